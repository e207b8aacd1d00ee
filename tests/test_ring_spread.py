"""Faceted rings: the spread over the polar angle of the rendered fringe order on circles
about a centred indenter (an axisymmetric load, so every circle should carry one order).

The small built-in case (8 N, 3.5 mm sphere, quarter model) rendered at 128 px over
12 mm; the order is read bilinearly at 720 angles on each circle. The mesh is made by the
deterministic layered mesher, so each figure is one number on every run, and the bounds
below are the measured spreads with about 10 % room: a change that facets the rings
more fails. The target of 0.03 fringe (``docs/validation.md``) is not met yet.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fringekit.analysis import circle_profile
from fringekit.config import as_config
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import fringe_order_map

RADII_MM = (2.0, 2.5, 3.0, 4.0)


def _small_order(cache_dir, mesh: dict):
    """The small case with the ``mesh`` keys, rendered at 128 px over 12 mm: (the last
    solution, the solve's stats, fringe order (128, 128), the axis (row, col), the pixel
    (mm))."""
    cfg = as_config("small").replace({**mesh, "optics.pixels": 128})
    _, sols, stats, failure = solve_config(cfg.data, cache_dir=cache_dir, progress=False)
    assert failure is None
    order, _, centres = fringe_order_map(sols[-1], cfg.data)
    pixel_mm = cfg.data["optics"]["field_of_view_mm"] / order.shape[1]
    return sols[-1], stats, order, centres[0], pixel_mm


def _rings(cache_dir, h_contact_mm: float, h_layer_mm: float):
    """(DOF, contact radius (mm), mean order (4,), spread over angle (4,)) on RADII_MM."""
    mesh = {"mesh.h_contact_mm": h_contact_mm, "mesh.h_layer_mm": h_layer_mm}
    sol, stats, order, axis, pixel_mm = _small_order(cache_dir, mesh)
    vals = np.array([circle_profile(order, axis, r, pixel_size=pixel_mm)[1] for r in RADII_MM])
    assert np.all(np.isfinite(vals))  # every circle lies outside the contact, in the view
    radius_mm = sol.indenters[0].contact_radius * 1e3
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


def _order_annulus(cache_dir, scale: float) -> np.ndarray:
    """The small case's fringe order (128 px over 12 mm) with every mesh size scaled by
    ``scale`` (0.6 mm under the indenter, 1.5 mm in the sheet, 4 mm far, layers as thick
    as the contact's elements), on pixels 1.55-5.5 mm from the axis (1.3 contact radii
    out to the view's edge)."""
    mesh = {
        "mesh.h_contact_mm": 0.6 * scale,
        "mesh.h_sheet_mm": 1.5 * scale,
        "mesh.h_far_mm": 4.0 * scale,
        "mesh.h_layer_mm": 0.0,
    }
    _, _, order, axis, pixel_mm = _small_order(cache_dir, mesh)
    rows, cols = np.indices(order.shape)
    r_mm = np.hypot(rows - axis[0], cols - axis[1]) * pixel_mm
    return order[(r_mm > 1.55) & (r_mm < 5.5)]


@pytest.mark.slow
def test_the_fringe_order_converges_with_refinement_at_a_fitted_rate(cache_dir):
    """Three meshes, every size scaled by sqrt(2) each time (4.5k, 9.5k and 29k DOF):
    the RMS change of the order beyond 1.3 contact radii falls from 0.115 to 0.059
    fringe, an observed rate p = ln(e1 / e2) / ln(sqrt 2) of 1.9 in the element size.
    A fourth mesh (69k DOF, not run here) gives 0.043 and a rate of 0.9 between the two
    finest: the faceting near the contact (the spread above) converges more slowly than
    the field (docs/validation.md)."""
    orders = [_order_annulus(cache_dir, s) for s in (math.sqrt(2.0), 1.0, math.sqrt(0.5))]
    assert all(np.all(np.isfinite(o)) for o in orders)
    e1 = float(np.sqrt(np.mean((orders[0] - orders[1]) ** 2)))
    e2 = float(np.sqrt(np.mean((orders[1] - orders[2]) ** 2)))
    rate = math.log(e1 / e2) / math.log(math.sqrt(2.0))
    assert 0.10 < e1 < 0.13 and 0.05 < e2 < 0.07, (e1, e2)
    assert 1.5 < rate < 2.3, rate
