"""Full stick: a point sticks where it first touches, so the stick energy is continuous
at first touch and the converged state of a monotone load path does not depend on how
it is cut into load states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fringekit.fea import ContactSettings, Indenter, solve
from fringekit.fea.contact import sphere_contact

R, EPS = 1.75e-3, 1e11
N_TOUCH = np.array([0.3, 0.0, -1.0]) / math.hypot(0.3, 1.0)  # a point on the sphere
T_TOUCH = np.array([1.0, 0.0, 0.3]) / math.hypot(1.0, 0.3)  # tangent to it there


def _energy(gap: float, *, first_touch: bool) -> float:
    """Stick energy of one point that moved from 5 um outside the sphere, 5 um to the
    side, to normal gap ``gap`` at ``N_TOUCH``: anchored where it was (the old rule) or
    where its path crossed the sphere (``first_touch``)."""
    x = (R + gap) * N_TOUCH
    y0 = (R + 5e-6) * N_TOUCH - 5e-6 * T_TOUCH
    stale = R * y0 / np.linalg.norm(y0)
    res = sphere_contact(
        x[None, None],
        np.full((1, 1), 1e-8),
        np.zeros(3),
        R,
        np.zeros((1, 1)),
        EPS,
        mu=math.inf,
        anchor=stale[None, None],
        anchored=np.array([[not first_touch]]),
        y_from=y0[None, None],
        eps_t=EPS,
        tangent=False,
    )
    return res.energy


def test_a_first_touch_anchor_makes_the_stick_energy_continuous():
    """Anchored where it was at the step's start, a point that just touches carries
    w eps_T |s|^2 / 2 however small its penetration: the energy (and force) jump there,
    so no line-search step length need decrease them. Anchored where its path crossed
    the sphere, it carries nothing at first touch, and its energy grows with the square
    of the penetration."""
    h = 1e-13
    jump = _energy(-h, first_touch=False) - _energy(h, first_touch=False)
    assert jump == pytest.approx(0.5 * 1e-8 * EPS * (5e-6) ** 2, rel=1e-2)
    assert abs(_energy(-h, first_touch=True) - _energy(h, first_touch=True)) < 1e-9 * jump
    deeper = [_energy(-g, first_touch=True) for g in (1e-8, 2e-8)]
    # the normal penalty w eps_N g^2 / 2 plus the stick part, both ~ g^2
    assert deeper[1] / deeper[0] == pytest.approx(4.0, rel=0.05)


def _states(F: float, n: int, shear: float = 0.0, n_shear: int = 0):
    """n normal load states up to F, then n_shear tangential ones up to ``shear``."""
    normal = [F * (k + 1) / n for k in range(n)] + [F] * n_shear
    tang = [(0.0, 0.0)] * n + [(shear * (k + 1) / n_shear, 0.0) for k in range(n_shear)]
    return Indenter(normal_force=tuple(normal), shear_force=tuple(tang) if n_shear else None)


def _surface_difference(a, b) -> float:
    """Largest difference of the nodal stress (Pa) of two solutions, relative to the
    largest nodal stress."""
    return float(np.abs(a.stress_nodes - b.stress_nodes).max() / np.abs(b.stress_nodes).max())


@pytest.mark.slow
def test_stick_does_not_depend_on_the_load_states(small_meshes):
    """2 N under full stick in one load state and in eight: the same depth and contact
    radius (0.3 %; measured 0.03 % and 0.02 %), force and stresses. Before first-touch
    anchoring one state gave a depth 2 % larger than sixteen on this block (0.3952
    against 0.3874 mm at 3 N)."""
    mesh = small_meshes["quarter"]
    stick = ContactSettings(friction=math.inf)
    one, _ = solve(mesh, [_states(2.0, 1)], contact=stick)
    eight, _ = solve(mesh, [_states(2.0, 8)], contact=stick)
    a, b = one[-1].indenters[0], eight[-1].indenters[0]
    assert a.force[2] == pytest.approx(b.force[2], rel=1e-9)
    assert a.depth == pytest.approx(b.depth, rel=3e-3)
    assert a.contact_radius == pytest.approx(b.contact_radius, rel=3e-3)
    assert _surface_difference(one[-1], eight[-1]) < 0.03


@pytest.mark.slow
def test_stick_with_shear_does_not_depend_on_the_load_states(small_meshes):
    """2 N, then 0.6 N tangential under full stick: one normal and one tangential state
    against four of each give the same depth, contact radius (0.3 %; measured 0.1 % and
    0.06 %) and tangential displacement (0.5 %; measured 0.06 %)."""
    mesh = small_meshes["half"]
    stick = ContactSettings(friction=math.inf)
    one, _ = solve(mesh, [_states(2.0, 1, 0.6, 1)], contact=stick)
    four, _ = solve(mesh, [_states(2.0, 4, 0.6, 4)], contact=stick)
    a, b = one[-1].indenters[0], four[-1].indenters[0]
    assert a.force[0] == pytest.approx(b.force[0], rel=1e-9)
    assert a.depth == pytest.approx(b.depth, rel=3e-3)
    assert a.contact_radius == pytest.approx(b.contact_radius, rel=3e-3)
    assert a.centre[0] == pytest.approx(b.centre[0], rel=5e-3)
    assert _surface_difference(one[-1], four[-1]) < 0.03
