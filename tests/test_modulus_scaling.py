"""A stiffer or softer sheet relabels the loads: scaling the sheet's material constants by
k scales every stress and every load by k at the same deformed geometry, up to the
substrate's compliance (docs/theory.md, "Modulus scaling")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fringekit.fea import ContactSettings, Indenter, NeoHookean, solve
from fringekit.fea.materials import POLYCARBONATE_DEFAULT

K = 1.15  # +15 %: a PSM-4-class sheet from another batch, or a few degrees colder


def _solve(mesh, E: float, load: float, contact: ContactSettings, substrate):
    mats = {0: NeoHookean.from_E_nu(E, 0.49), 1: substrate}
    sols, _ = solve(mesh, [Indenter(normal_force=(load,))], materials=mats, contact=contact)
    return sols[-1]


def _compare(a, b) -> tuple[float, float]:
    """(relative depth difference, largest sheet-stress difference of b / K against a,
    relative to a's largest) of two states."""
    sheet = np.unique(a.mesh.cells[a.mesh.regions == 0])
    sa, sb = a.stress_nodes[sheet], b.stress_nodes[sheet] / K
    depth = abs(b.indenters[0].depth / a.indenters[0].depth - 1.0)
    return depth, float(np.abs(sb - sa).max() / np.abs(sa).max())


@pytest.mark.parametrize("friction", [0.0, pytest.param(math.inf, marks=pytest.mark.slow)])
def test_a_sheet_k_times_stiffer_carries_k_times_the_load_at_the_same_shape(small_meshes, friction):
    """2 N on the 4 MPa sheet against 2.3 N on a 4.6 MPa one (coarse block, 4 mm
    polycarbonate): the same depth and the same stresses divided by 1.15, to 5e-4, and
    to 1e-9 with a substrate scaled as well (then the relabelling is exact: the solver's
    penalties scale with the sheet's modulus and its tolerances with the load)."""
    mesh = small_meshes["quarter"]
    contact = ContactSettings(friction=friction)
    pc = POLYCARBONATE_DEFAULT
    a = _solve(mesh, 4e6, 2.0, contact, pc)
    b = _solve(mesh, 4e6 * K, 2.0 * K, contact, pc)
    depth, stress = _compare(a, b)
    assert depth < 5e-4 and stress < 5e-4, (depth, stress)
    assert depth > 1e-7  # the polycarbonate's own compliance: not exact
    stiffer_pc = NeoHookean(mu=pc.mu * K, K=pc.K * K)
    c = _solve(mesh, 4e6 * K, 2.0 * K, contact, stiffer_pc)
    depth, stress = _compare(a, c)
    assert depth < 1e-9 and stress < 1e-9, (depth, stress)
