"""What a solve costs: one body tangent per Newton iteration, and a mixed-precision
factorization that gives double-precision answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp

from fea import Indenter, LinearSolver, SolverSettings, available_backends, solve
from fea.linsolve import REFINE_RTOL

PARDISO = "pardiso" in available_backends()


def _trials(log) -> int:
    """Residual-only line-search trials of a Newton log: alpha = 2^-k took k of them."""
    return sum(round(-math.log2(row["alpha"])) for row in log if "alpha" in row)


def test_body_is_assembled_once_per_newton_iteration(small_meshes):
    """Increment starts, multiplier updates and stress recovery reuse the last iterate's
    body evaluation: the only tangents beyond one per iteration are the very first and
    those of backtracked steps, and the only residual evaluations are backtracking
    trials."""
    sols, stats = solve(small_meshes["quarter"], [Indenter(normal_force=(1.0, 2.0, 4.0))])
    rows = [row for s in sols for row in s.log]
    backtracked = sum(1 for row in rows if row.get("alpha", 1.0) < 1.0)
    assert stats.al_updates > 0 and len(sols) == 3  # there was something to reuse
    assert stats.tangent_assemblies <= stats.newton_iterations + 1 + backtracked
    assert stats.residual_evaluations == _trials(rows)
    print(stats.tangent_assemblies, stats.newton_iterations, stats.residual_evaluations)


@pytest.mark.skipif(not PARDISO, reason="PARDISO (pypardiso) is not available here")
def test_mixed_precision_gives_the_double_precision_solution(small_meshes):
    mesh = small_meshes["quarter"]
    ind = [Indenter(normal_force=(3.0,))]
    mixed, sm = solve(mesh, ind, settings=SolverSettings(precision="mixed"))
    double, sd = solve(mesh, ind, settings=SolverSettings(precision="double"))
    a, b = mixed[-1].indenters[0], double[-1].indenters[0]
    # both converge to the force tolerance: the same state to far below the mesh error
    assert a.depth == pytest.approx(b.depth, rel=1e-6)
    assert a.contact_radius == pytest.approx(b.contact_radius, rel=1e-6)
    np.testing.assert_allclose(
        mixed[-1].stress_qp, double[-1].stress_qp, atol=1e-6 * np.abs(double[-1].stress_qp).max()
    )


def _laplacian(n: int) -> sp.csr_matrix:
    """Upper triangle of the 1D Laplacian: condition about 4 (n + 1)^2 / pi^2."""
    return sp.diags([np.full(n, 2.0), -np.ones(n - 1)], [0, 1], format="csr")


@pytest.mark.skipif(not PARDISO, reason="PARDISO (pypardiso) is not available here")
@pytest.mark.parametrize(("n", "fallback"), [(3000, False), (60000, True)])
def test_refinement_reaches_double_accuracy_or_falls_back(n, fallback):
    """A system of condition 3.6e6 is refined to REFINE_RTOL on its single-precision
    factor (measured: 2 steps); one of condition 1.5e9 does not get there in MAX_REFINE
    steps and is refactorised in double precision."""
    A = _laplacian(n)
    full = A + sp.triu(A, 1).T
    x_true = np.sin(np.linspace(0, 3, n))
    b = full @ x_true
    lin = LinearSolver("pardiso", "mixed")
    x = lin.solve(A, b, symmetric=True, pattern_id=1)
    assert np.linalg.norm(full @ x - b) <= REFINE_RTOL * np.linalg.norm(b)
    assert (lin.n_fallbacks == 1) is fallback
    assert lin.n_refinements >= 1
    lin.release()


def test_bad_precision_is_named():
    with pytest.raises(ValueError, match="precision = 'half'"):
        SolverSettings(precision="half")
    with pytest.raises(ValueError, match="precision = 'half'"):
        LinearSolver("scipy", "half")
