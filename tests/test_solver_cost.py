"""What a solve costs: one body tangent per Newton iteration, and a mixed-precision
factorization that gives double-precision answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp

from fringekit.fea import (
    SHEET_DEFAULT,
    ContactSettings,
    Indenter,
    LinearSolver,
    SolverSettings,
    available_backends,
    estimate_solve,
    solve,
)
from fringekit.fea.linsolve import REFINE_RTOL

PARDISO = "pardiso" in available_backends()


def _expected_evaluations(log) -> tuple[int, int]:
    """(tangents, residual evaluations) the Newton log implies when the body is
    evaluated once per line-search trial and never again for multiplier updates,
    increment starts or recovery, and a tangent is formed once per linear solve, on
    the accepted iterate's kinematics.

    A step of length 2^-k took k + 1 trials; every step (row with ``alpha``) is one
    linear solve on one tangent. The unloaded start is one residual evaluation.
    """
    steps = [row for row in log if "alpha" in row]
    residuals = 1 + sum(round(-math.log2(row["alpha"])) + 1 for row in steps)
    return len(steps), residuals


def test_body_is_assembled_once_per_newton_iteration(small_meshes):
    """One tangent per Newton iteration, whatever the line search does: trials evaluate
    the residual only, and increment starts, multiplier updates and stress recovery
    reuse the last iterate's evaluation. The counts are exactly those the Newton log
    implies, and some step was shortened (so a rejected trial cost no tangent)."""
    sols, stats = solve(small_meshes["quarter"], [Indenter(normal_force=(1.0, 2.0, 4.0))])
    rows = [row for s in sols for row in s.log]
    assert stats.al_updates > 0 and len(sols) == 3 and stats.cutbacks == 0
    assert any(row.get("alpha", 1.0) < 1.0 for row in rows)
    assert stats.tangent_assemblies == stats.newton_iterations
    assert (stats.tangent_assemblies, stats.residual_evaluations) == _expected_evaluations(rows)


@pytest.mark.parametrize("kernel", ["neo-hookean", "mooney-rivlin"])
def test_a_tangent_formed_later_matches_finite_differences(small_meshes, kernel):
    """body_tangent on a residual-only evaluation (what an accepted line-search trial
    gets) is the derivative of the internal force, for both element kernels (the
    neo-Hookean outer products and the general 4th-order contraction), on a mesh of two
    materials; it is the same as evaluating both at once."""
    from fringekit.fea import MooneyRivlin
    from fringekit.fea.assembly import Pattern, body_state, body_tangent, cell_dofs
    from fringekit.fea.element import reference_gradients

    mesh = small_meshes["quarter"]
    grads = reference_gradients(mesh.points, mesh.cells)
    mat = SHEET_DEFAULT if kernel == "neo-hookean" else MooneyRivlin(0.4e6, 0.2e6, 60e6)
    half = mesh.n_cells // 2
    groups = [(np.arange(half), mat), (np.arange(half, mesh.n_cells), SHEET_DEFAULT)]
    u = 1e-4 * np.sin(500 * mesh.points[:, [1, 2, 0]])
    res = body_state(u, mesh.cells, grads, groups, tangent=False)
    assert res.Ke is None
    later = body_tangent(res, grads, groups)
    dofs = cell_dofs(mesh.cells)
    pat = Pattern(3 * mesh.n_points, [dofs], symmetric=True)
    U = pat.matrix([(*pat.scatter(dofs), later.Ke.ravel())])
    K = U + sp.triu(U, k=1).T
    v = np.random.default_rng(5).standard_normal(u.shape)
    h = 1e-9
    fp = body_state(u + h * v, mesh.cells, grads, groups, tangent=False).force
    fm = body_state(u - h * v, mesh.cells, grads, groups, tangent=False).force
    an = K @ v.ravel()
    assert np.linalg.norm(((fp - fm) / (2 * h)).ravel() - an) <= 1e-6 * np.linalg.norm(an)
    both = body_state(u, mesh.cells, grads, groups, tangent=True)
    np.testing.assert_array_equal(later.Ke, both.Ke)


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


@pytest.mark.skipif(not PARDISO, reason="PARDISO (pypardiso) is not available here")
@pytest.mark.parametrize(("change", "reused"), [(1e-7, True), (1e-3, False)])
def test_an_earlier_factor_solves_a_nearby_matrix_exactly(change, reused):
    """A Newton step near convergence is solved on the previous tangent's factor, refined
    against the new tangent to REFINE_RTOL: no factorization, the same answer. A matrix
    that changed too much is factorised anew (smallest eigenvalue 4e-5: a change of 1e-7
    contracts the refinement by ~3e-3 per step, one of 1e-3 not at all)."""
    n = 500
    A1 = _laplacian(n)
    A2 = A1 + sp.diags(change * np.linspace(1.0, 2.0, n), format="csr")
    full2 = A2 + sp.triu(A2, 1).T
    b = np.cos(np.linspace(0, 5, n))
    lin = LinearSolver("pardiso", "mixed")
    lin.solve(A1, b, symmetric=True, pattern_id=1)
    x = lin.solve(A2.tocsr(), b, symmetric=True, pattern_id=1, reuse=True)
    assert np.linalg.norm(full2 @ x - b) <= REFINE_RTOL * np.linalg.norm(b)
    assert lin.n_reuses == int(reused) and lin.n_factorizations == 2 - int(reused)
    lin.release()


@pytest.mark.slow
def test_increments_on_the_way_skip_multiplier_updates_when_frictionless(small_meshes, monkeypatch):
    """Frictionless contact is path-independent: an increment on the way to a load state
    needs equilibrium, not the penetration tolerance. 8 N in one state (several increments)
    with and without that rule: the same state to within the multiplier loop's stopping
    tolerance (1 % of the depth in penetration), in fewer multiplier updates and Newton
    iterations. With friction every increment is solved in full."""
    import fringekit.fea.solver
    from fringekit.fea import ContactSettings

    mesh = small_meshes["quarter"]
    fast, fs = solve(mesh, [Indenter(normal_force=(8.0,))])
    full_increment = fringekit.fea.solver.solve_increment

    def always_final(run, st, s_new, iter_log, final=True):
        return full_increment(run, st, s_new, iter_log, True)

    monkeypatch.setattr(fringekit.fea.solver, "solve_increment", always_final)
    slow, ss = solve(mesh, [Indenter(normal_force=(8.0,))])
    assert fs.al_updates < ss.al_updates and fs.newton_iterations < ss.newton_iterations
    a, b = fast[-1].indenters[0], slow[-1].indenters[0]
    assert a.depth == pytest.approx(b.depth, rel=2e-3)
    assert a.force[2] == pytest.approx(-8.0, rel=1e-6)
    # with friction the rule is off: the same counts either way
    mu = ContactSettings(friction=0.3)
    _, s_mu_full = solve(mesh, [Indenter(normal_force=(8.0,))], contact=mu)
    monkeypatch.setattr(fringekit.fea.solver, "solve_increment", full_increment)
    _, s_mu = solve(mesh, [Indenter(normal_force=(8.0,))], contact=mu)
    assert s_mu.al_updates == s_mu_full.al_updates
    assert s_mu.newton_iterations == s_mu_full.newton_iterations


@pytest.mark.parametrize("friction", [0.0, math.inf])
def test_the_estimate_knows_the_increments_the_solver_takes(small_meshes, friction):
    """The cost estimate steps the load as the solver does (first increment, doubling,
    and with friction no normal load rising more than 1.25x per increment): the same
    increments per state, frictionless and under full stick, on a path of two states."""
    mesh = small_meshes["quarter"]
    ind = [Indenter(normal_force=(1.0, 2.5))]
    contact = ContactSettings(friction=friction)
    _, stats = solve(mesh, ind, contact=contact)
    est = estimate_solve(mesh.n_dofs, ind, E=SHEET_DEFAULT.E, h=3e-3, contact=contact)
    assert stats.cutbacks == 0
    assert sum(est.increments) == stats.increments
    assert est.increments[1] == (5 if friction else 1)  # 1 -> 2.5 N: 1.25^4 < 2.5 < 1.25^5
    assert est.seconds > 0 and f"{stats.increments} increment(s)" in est.text()
