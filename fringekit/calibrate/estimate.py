"""``fringekit estimate`` and ``fringekit calibrate --disc``: a stored map against a
calibration.

``run_estimate`` computes the features of :func:`analysis.fringe_features` from a
fringe-order map (``fringekit analyze`` or ``predict`` output) and inverts a calibration
(:func:`analysis.estimate_load`); ``run_disc`` fits the fringe value to a diametral-disc
map (:func:`fringekit.calibrate.disc_map.fringe_value_from_disc`).
"""

from __future__ import annotations

import json

import numpy as np

from fringekit.analysis import estimate_load, fringe_features, load_calibration
from fringekit.calibrate.disc_map import disc_outline, fringe_value_from_disc
from fringekit.errors import InputError
from fringekit.measurement.compare import read_order_map
from fringekit.output.folders import claim_output

__all__ = ["run_estimate", "run_disc"]


def _read_map(maps, pixel_mm, centre):
    m = read_order_map(maps, pixel_size=pixel_mm * 1e-3 if pixel_mm else None)
    rc = centre if centre is not None else m.indenter_rc
    if rc is None:
        raise InputError(f"{m.path} stores no indenter position; give --centre ROW COL (pixels)")
    rows, cols = m.order.shape
    if not (0 <= rc[0] <= rows - 1 and 0 <= rc[1] <= cols - 1):
        raise InputError(
            f"--centre {rc[0]:g} {rc[1]:g} is outside the map; allowed rows 0..{rows - 1}, "
            f"columns 0..{cols - 1}"
        )
    return m.path, m.order, m.pixel_size, (float(rc[0]), float(rc[1]))


def run_estimate(maps, calibration, *, pixel_mm=None, centre=None, out=None) -> dict:
    """Normal load (and shear) from a fringe-order map and a calibration file."""
    cal = load_calibration(calibration)
    f, order, px, rc = _read_map(maps, pixel_mm, centre)
    feats = fringe_features(order, px, rc)
    est = estimate_load(cal, feats)
    est.update(maps=str(f), calibration=str(calibration), features=feats, centre_rc=list(rc))
    if out is not None:
        with claim_output(out, command="estimate", inputs=[maps, calibration]) as work:
            (work / "estimate.json").write_text(json.dumps(est, indent=2, default=float))
    return est


def run_disc(maps, *, load_N, diameter_mm, thickness_mm, pixel_mm=None, centre=None) -> dict:
    """Fringe value from a diametral-disc fringe-order map at a known load."""
    m = read_order_map(maps, pixel_size=pixel_mm * 1e-3 if pixel_mm else None)
    f, order, px = m.path, m.order, m.pixel_size
    if m.reliable is not None:  # analyze's reliable mask: fit only what it vouches for
        order = np.where(m.reliable, order, np.nan)
    D = diameter_mm * 1e-3
    rc = centre if centre is not None else disc_outline(np.isfinite(m.order), px, D)
    res = fringe_value_from_disc(
        order, px, rc, load_N=load_N, diameter=D, thickness=thickness_mm * 1e-3
    )
    return {
        **res,
        "maps": str(f),
        "centre_rc": list(rc),
        "centre_from": "--centre" if centre is not None else "the outline of the map's data",
        "reliable_mask_used": m.reliable is not None,
    }
