"""First contact of force-controlled indenters: the contact tangent stays definite.

A force-controlled indenter is first placed at the depth the bonded-layer formula gives
(fea.solver._predict is internal: the tests go through ``solve``). Against the undeformed
sheet that placement penetrates deeply, and the penalty pressures are ~100 times the
physical ones. The curvature term of the contact tangent, -(p / r)(I - n n), is a negative
tangential stiffness that then outweighs the sheet: before the cap, Newton threw surface
nodes 0.9-4.9 mm sideways on the reference mesh (1 N, 0.17 mm depth), inverted elements
and crawled with steps of 1/32 (27 Newton iterations for the first state, 8 now).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_spec

from fringekit.fea import Indenter, solve
from fringekit.fea.contact import sphere_contact
from fringekit.meshes import MeshSpec, build_mesh


def _deep_points(rng, R=1.75e-3, depth=2e-4):
    """Quadrature points inside the sphere near its south pole (penetration up to depth)."""
    dirs = np.array([0, 0, -1.0]) + 0.3 * rng.standard_normal((5, 7, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    c = np.array([0, 0, R])
    return c, c + dirs * (R - depth * rng.random((5, 7)))[..., None]


def test_curvature_cap_keeps_the_contact_tangent_definite_and_the_force_exact():
    rng = np.random.default_rng(7)
    R, eps, E = 1.75e-3, 6.7e11, 4e6
    c, xq = _deep_points(rng, R)
    w = 1e-8 * (1 + rng.random((5, 7)))
    lam = np.zeros((5, 7))
    free = sphere_contact(xq, w, c, R, lam, eps)
    capped = sphere_contact(xq, w, c, R, lam, eps, p_curvature_cap=E)
    assert free.p.max() > 20 * E  # the penalty pressures of a first placement
    np.testing.assert_array_equal(capped.force, free.force)  # the residual is untouched
    assert capped.energy == free.energy

    def smallest_eigenvalue(res):
        """Most negative eigenvalue over the facets' 21 x 21 contact tangents (N/m)."""
        K = 0.5 * (res.K + res.K.swapaxes(1, 2))
        return np.linalg.eigvalsh(K).min()

    # uncapped: a tangential stiffness of -w p / r per point; capped: at most -w E / r
    # per point, summed over a facet's 7 points with shape-function weights below 2
    bound = 2 * w.sum(axis=1).max() * E / (R - 2e-4)
    assert smallest_eigenvalue(free) < -5 * bound
    assert smallest_eigenvalue(capped) > -bound
    # below the cap the tangent is the exact one
    mild = sphere_contact(xq, w, c, R, lam, 1e9)
    mild_capped = sphere_contact(xq, w, c, R, lam, 1e9, p_curvature_cap=E)
    assert mild.p.max() < E
    np.testing.assert_array_equal(mild.K, mild_capped.K)


@pytest.mark.slow
def test_first_contact_on_the_reference_mesh_takes_whole_newton_steps(tmp_path):
    """1 N on the reference quarter model: full steps only (27 iterations with steps down
    to 1/32 before the cap; 8 with it)."""
    mesh = build_mesh(MeshSpec(symmetry="quarter"), cache_dir=tmp_path)
    sols, stats = solve(mesh, [Indenter(normal_force=(1.0,))])
    alphas = [row["alpha"] for row in sols[0].log if "alpha" in row]
    assert stats.cutbacks == 0 and min(alphas) == 1.0
    assert stats.iterations_per_state[0] <= 10


@pytest.mark.parametrize("force", [8.0])
def test_a_deep_first_placement_needs_few_shortened_steps(small_meshes, force):
    """8 N in one state on the small block: 36 Newton iterations with 14 shortened
    line-search steps before the cap, 26 and 3 with it."""
    sols, stats = solve(small_meshes["quarter"], [Indenter(normal_force=(force,))])
    alphas = [row["alpha"] for row in sols[0].log if "alpha" in row]
    assert stats.cutbacks == 0
    assert sum(a < 1 for a in alphas) <= 6 and stats.iterations_per_state[0] <= 30
    assert small_meshes["quarter"].spec == small_spec("quarter")


def test_a_long_increment_says_so_with_its_loads(small_meshes, monkeypatch, caplog):
    """An increment that runs past the watchdog's limit is reported once, naming the loads
    it is trying and what to change (the limit is 60 s; 0 here)."""
    import fringekit.fea.watchdog

    monkeypatch.setattr(fringekit.fea.watchdog, "STALL_WARN_S", 0.0)
    with caplog.at_level("WARNING", logger="fringekit.fea"):
        solve(small_meshes["quarter"], [Indenter(normal_force=(1.0, 2.0))])
    said = [r.getMessage() for r in caplog.records if "has run" in r.getMessage()]
    assert len(said) == 2  # once per increment
    assert "indenter loads 1 N" in said[0] and "indenter loads 2 N" in said[1]
    assert "indenter.load_N" in said[0]


def test_a_two_value_cycle_of_the_residual_is_recognised():
    """The shear case's Newton run bounced between residuals of 0.0528 and 0.0355 N for
    16 iterations (a contact point flipping in and out), was cut back twice and took 59
    iterations for its shear state; a multiplier update on the cycle takes it to 24."""
    from fringekit.fea.newton import is_cycling

    assert is_cycling([0.58, 0.0528, 0.0355, 0.0528, 0.0355])
    assert not is_cycling([0.0528, 0.0355, 0.0528])  # too short to tell
    assert not is_cycling([4.0, 2.9, 2.5, 1.2])  # converging
    assert not is_cycling([0.1, 0.1, 0.1, 0.1])  # stalled, not alternating


def test_two_indenters_at_different_loads_on_a_thin_sheet(tmp_path):
    """A coarse twin of the two-indenter case that stalled (2 mm sheet, 3.5 mm heads at
    (-4, 0) mm with 6 N and (4, 2) mm with 3 N; here a 16 x 10 mm sheet on a rigid base,
    1 mm elements, 4.5k DOF). Before the cap: a cut-back, 24 shortened line-search steps,
    68 Newton iterations; with it: none, 1 and 31."""
    from fringekit.meshes import IndenterSite, Layers, Sizing

    spec = MeshSpec(
        layers=Layers(2e-3, 0.0, 16e-3, 10e-3),
        indenters=(IndenterSite(-4e-3, 0.0), IndenterSite(4e-3, 2e-3)),
        sizing=Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_sheet=1.5e-3, h_far=4e-3, growth=0.5),
    )
    mesh = build_mesh(spec, cache_dir=tmp_path)
    inds = [
        Indenter(x=-4e-3, y=0.0, normal_force=(6.0,)),
        Indenter(x=4e-3, y=2e-3, normal_force=(3.0,)),
    ]
    sols, stats = solve(mesh, inds)
    alphas = [row["alpha"] for row in sols[0].log if "alpha" in row]
    assert stats.cutbacks == 0 and sum(a < 1 for a in alphas) <= 3
    assert stats.iterations_per_state[0] <= 40
    forces = [ind.force[2] for ind in sols[0].indenters]
    assert forces == pytest.approx([-6.0, -3.0], rel=1e-6)
