"""Faceted rings: the spread over the polar angle of the rendered fringe order on circles
about a centred indenter (an axisymmetric load, so every circle should carry one order).

The small built-in case (8 N, 3.5 mm sphere, quarter model) rendered at 128 px over
12 mm; the order is read bilinearly at 720 angles on each circle. The mesh is made by the
deterministic layered mesher, so each figure is one number on every run, and the bounds
below are the measured spreads with about 10 % room: a change that facets the rings
more fails. The target of 0.03 fringe (``docs/validation.md``) is not met yet.
"""

from __future__ import annotations

import numpy as np
import pytest

from fringekit.analysis import circle_profile
from fringekit.config import as_config
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import fringe_order_map

RADII_MM = (2.0, 2.5, 3.0, 4.0)


def _rings(cache_dir, h_contact_mm: float, h_layer_mm: float):
    """(DOF, contact radius (mm), mean order (4,), spread over angle (4,)) on RADII_MM."""
    cfg = as_config("small").replace(
        {
            "mesh.h_contact_mm": h_contact_mm,
            "mesh.h_layer_mm": h_layer_mm,
            "optics.pixels": 128,
        }
    )
    _, sols, stats, failure = solve_config(cfg.data, cache_dir=cache_dir, progress=False)
    assert failure is None
    order, _, centres = fringe_order_map(sols[-1], cfg.data)
    pixel_mm = cfg.data["optics"]["field_of_view_mm"] / order.shape[1]
    vals = np.array(
        [circle_profile(order, centres[0], r, pixel_size=pixel_mm)[1] for r in RADII_MM]
    )
    assert np.all(np.isfinite(vals))  # every circle lies outside the contact, in the view
    radius_mm = sols[-1].indenters[0].contact_radius * 1e3
    return stats.dofs, radius_mm, vals.mean(axis=1), vals.max(axis=1) - vals.min(axis=1)


@pytest.mark.slow
def test_a_finer_lateral_mesh_on_thick_layers_rounds_the_rings(cache_dir):
    """0.3 mm under the indenter on 0.6 mm layers (h_layer; the reference case's default
    mesh since 2026-11-27) against 0.6 mm (its default before): rounder rings (spread
    0.20 / 0.20 / 0.12 / 0.08 fringe at 2 / 2.5 / 3 / 4 mm against 0.29 / 0.27 / 0.29 /
    0.09), the same orders and contact radius as 0.3 mm through the
    whole thickness (10 layers, three times the solve) to 0.01 fringe and 0.5 %, where
    the 0.6 mm mesh is 0.05-0.09 fringe and 3.7 % off (contact radius 1.144 against
    1.189 mm: on 0.6 mm facets the edge fit's sd exceeds 0.5 % and the contact area's
    circle is given; 0.3 mm on 0.6 mm layers is fitted, 1.187 mm)."""
    _, a6, mean6, spread6 = _rings(cache_dir, 0.6, 0.0)
    dofs3, a3, mean3, spread3 = _rings(cache_dir, 0.3, 0.6)
    dofs_fine, a_fine, mean_fine, _ = _rings(cache_dir, 0.3, 0.0)
    assert dofs3 < 0.6 * dofs_fine  # 15k against 27k: five layers, not ten
    assert np.all(spread3 <= np.array([0.22, 0.22, 0.13, 0.085])), spread3
    assert np.all(spread6[:3] > 0.25), spread6  # the default's facets, as measured
    assert np.max(np.abs(mean3 - mean_fine)) < 0.012, (mean3, mean_fine)
    assert abs(a3 / a_fine - 1) < 0.005, (a3, a_fine)
    assert np.max(np.abs(mean6 - mean_fine)[:2]) > 0.04 and a6 / a_fine < 0.97
