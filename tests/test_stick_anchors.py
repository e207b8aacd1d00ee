"""Full stick: a point that comes into contact during an increment, and the failed line
search that its stale anchor can cause."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fringekit.fea.newton
from fringekit.fea import ContactSettings, Indenter, solve
from fringekit.fea.contact import sphere_contact

R, EPS = 1.75e-3, 1e11


def _energy(gap: float, anchor_shift: float) -> float:
    """Stick energy of one point on the sphere's axis side at normal gap ``gap``, its
    anchor displaced tangentially by ``anchor_shift`` from its projection."""
    n = np.array([0.3, 0.0, -1.0]) / math.hypot(0.3, 1.0)
    x = (R + gap) * n
    t = np.array([1.0, 0.0, 0.3]) / math.hypot(1.0, 0.3)  # tangent to the sphere at n
    a = R * n + anchor_shift * t
    a = R * a / np.linalg.norm(a)
    res = sphere_contact(
        x[None, None],
        np.full((1, 1), 1e-8),
        np.zeros(3),
        R,
        np.zeros((1, 1)),
        EPS,
        mu=math.inf,
        anchor=a[None, None],
        eps_t=EPS,
        tangent=False,
    )
    return res.energy


def test_a_stale_anchor_makes_the_stick_energy_jump_at_first_contact():
    """Just outside the sphere the point carries no energy; just inside, with an anchor
    5 um away, it carries w eps_T |s|^2 / 2 however small the penetration: the energy
    (and the force) of the increment jump there, so no line-search step length need
    decrease them. Anchored at its own projection the jump is gone."""
    h = 1e-13
    jump = _energy(-h, 5e-6) - _energy(h, 5e-6)
    assert jump == pytest.approx(0.5 * 1e-8 * EPS * (5e-6) ** 2, rel=1e-3)
    assert abs(_energy(-h, 0.0) - _energy(h, 0.0)) < 1e-12 * jump


@pytest.mark.parametrize(
    "stall", [pytest.param("fails", marks=pytest.mark.slow), "crawls", "cycles"]
)
def test_a_stalled_line_search_with_stick_anchors_the_new_points_and_goes_on(
    small_meshes, monkeypatch, stall
):
    """A line search that fails, or accepts a step of 1/16 or less near equilibrium, or
    iterates that cycle between two residuals (each forced here, once), in a stick solve
    re-anchors the points that came into contact during the increment and Newton goes
    on: no cut-back, and the state is the one the solve without the stall reaches (the
    re-anchored points are at the contact's edge, where the converged anchors differ by
    the sheet's motion within one Newton step). Frictionless contact has no anchors: the
    same failure cuts the increment back, and a short step is just a short step."""
    mesh = small_meshes["quarter"]
    ind = [Indenter(normal_force=(2.0,))]
    stick = ContactSettings(friction=math.inf)
    ref, ref_stats = solve(mesh, ind, contact=stick)
    assert ref_stats.reanchors == 0
    real = fringekit.fea.newton.line_search
    calls = {"n": 0}

    def stall_once(run, st, f_ind, dx, energy, rnorm):
        calls["n"] += 1
        if calls["n"] != 7:  # iteration 7 of the log: residual 9e-4 N, near equilibrium
            return real(run, st, f_ind, dx, energy, rnorm)
        if stall == "fails":
            return None, 2.0**-8
        trial, _ = real(run, st, f_ind, dx, energy, rnorm)
        return trial, 2.0**-5  # reported as a crawl; the step itself is the real one

    real_cycling = fringekit.fea.newton.is_cycling
    seen = {"n": 0}

    def cycles_once(history):
        seen["n"] += 1
        return seen["n"] == 7 or real_cycling(history)

    if stall == "cycles":
        monkeypatch.setattr(fringekit.fea.newton, "is_cycling", cycles_once)
    else:
        monkeypatch.setattr(fringekit.fea.newton, "line_search", stall_once)
    sols, stats = solve(mesh, ind, contact=stick)
    assert stats.reanchors == 1 and stats.cutbacks == 0
    a, b = sols[-1].indenters[0], ref[-1].indenters[0]
    assert a.force[2] == pytest.approx(-2.0, rel=1e-6)
    assert a.depth == pytest.approx(b.depth, rel=1e-3)
    calls["n"] = seen["n"] = 0
    _, free = solve(mesh, ind)
    assert free.reanchors == 0 and free.cutbacks == (1 if stall == "fails" else 0)
