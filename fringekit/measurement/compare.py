"""Stored fringe-order maps read back, and ``fringekit compare``.

:func:`read_order_map` reads the ``maps.npz`` of ``fringekit predict`` or ``analyze``
(``compare``, ``estimate`` and ``calibrate --disc`` use it). ``run_compare`` registers a
predicted fringe-order map onto a measured one and writes ``comparison.png``,
``residual.npz`` and ``summary.json`` (RMS and 95th percentile of the residual in fringe
orders). Kept apart from :mod:`fringekit.measurement.order` so that these commands do not import
the optics and colour-science at start-up.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fringekit.analysis import compare_maps
from fringekit.errors import InputError
from fringekit.output.figures import comparison_figure
from fringekit.output.folders import claim_output

__all__ = ["find_maps", "OrderMap", "read_order_map", "run_compare"]


def find_maps(path: str | os.PathLike) -> Path:
    """``maps.npz`` of a predict or analyze output: the file itself, the folder's, or the
    last rendered state's of a predict case folder."""
    p = Path(path)
    if p.is_file():
        return p
    if (p / "maps.npz").is_file():
        return p / "maps.npz"
    states = sorted(p.glob("state_*/maps.npz"))
    if states:
        return states[-1]
    raise FileNotFoundError(f"{p}: no maps.npz here (give a predict or analyze output folder)")


@dataclass(frozen=True)
class OrderMap:
    """A stored fringe-order map (``maps.npz`` of ``predict`` or ``analyze``).

    Attributes
    ----------
    path : the file read
    order : (rows, cols) fringe order, NaN where unknown
    pixel_size : float (m), the given one, else the stored one
    indenter_rc : (row, col) of the first indenter's axis, or None when not stored
    reliable : (rows, cols) bool, or None when not stored
    indenter_xy_mm : (x, y) of that axis in the sensor frame (mm), or None when the map
        stores no sensor coordinates (an analyze map)
    """

    path: Path
    order: np.ndarray
    pixel_size: float
    indenter_rc: tuple[float, float] | None
    reliable: np.ndarray | None
    indenter_xy_mm: tuple[float, float] | None = None


def read_order_map(path, *, pixel_size: float | None = None, hint: str = "--pixel-mm"):
    """Read a :class:`OrderMap` (see :func:`find_maps`); a pixel size is required, from
    the file or ``pixel_size`` (m); the error names ``hint``, the option that gives it."""
    f = find_maps(path)
    try:
        z = np.load(f, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:100]
        raise InputError(f"{f}: not a maps.npz of fringekit predict or analyze ({first})") from None
    with z:
        if "fringe_order" not in z:
            raise InputError(
                f"{f}: holds no fringe_order map (arrays: {sorted(z.files)}); give the "
                "maps.npz of fringekit predict or analyze"
            )
        order = np.array(z["fringe_order"], float)
        px = float(z["pixel_size_m"]) if "pixel_size_m" in z else 0.0
        rc = z["indenter_rc"][0] if "indenter_rc" in z and len(z["indenter_rc"]) else None
        rel = np.array(z["reliable"], bool) if "reliable" in z else None
        xy = None
        if rc is not None and "x_m" in z and "y_m" in z:
            r, c = (
                int(np.clip(round(float(v)), 0, n - 1))
                for v, n in zip(rc, order.shape, strict=True)
            )
            x0, y0 = float(z["x_m"][r, c]), float(z["y_m"][r, c])
            xy = (
                x0 * 1e3 + (float(rc[1]) - c) * px * 1e3,
                y0 * 1e3 - (float(rc[0]) - r) * px * 1e3,
            )
    px = pixel_size or px
    if not px:
        raise InputError(f"{f} stores no pixel size; give {hint}")
    rc = (float(rc[0]), float(rc[1])) if rc is not None else None
    return OrderMap(f, order, px, rc, rel, xy)


def run_compare(
    prediction: str | os.PathLike,
    measurement: str | os.PathLike,
    out: str | os.PathLike,
    *,
    predicted_pixel_size: float | None = None,
    measured_pixel_size: float | None = None,
    centre_measured: tuple[float, float] | None = None,
    rotation_deg: float = 0.0,
) -> dict:
    """Register a prediction onto a measurement and write residuals, figure and summary.

    Pixel sizes (m) default to those stored in the maps; the prediction's centre is its
    first indenter's axis when stored; the measurement's centre is fitted by phase
    correlation unless given as (row, col).
    """
    p = read_order_map(
        prediction,
        pixel_size=predicted_pixel_size,
        hint="--predicted-pixel-mm (the predicted pixel pitch)",
    )
    m = read_order_map(
        measurement,
        pixel_size=measured_pixel_size,
        hint="--measured-pixel-mm (the measured pixel pitch)",
    )
    pf, mf, pred, meas = p.path, m.path, p.order, m.order
    pp, mp, cp, rel = p.pixel_size, m.pixel_size, p.indenter_rc, m.reliable
    with claim_output(out, command="compare", inputs=[prediction, measurement]) as work:
        comp = compare_maps(
            pred,
            meas,
            predicted_pixel_size=pp,
            measured_pixel_size=mp,
            centre_predicted=cp,
            centre_measured=centre_measured,
            rotation_deg=rotation_deg,
            mask=rel,
        )
        comparison_figure(
            comp,
            work / "comparison.png",
            title=f"{pf.parent.name} vs {mf.parent.name}",
            pixel_size=mp,
            centre_xy_mm=p.indenter_xy_mm or (0.0, 0.0),
        )
        np.savez_compressed(
            work / "residual.npz", residual=comp.residual, predicted=comp.predicted, measured=meas
        )
        summary = {
            "prediction": str(pf),
            "measurement": str(mf),
            "rms_fringe": comp.rms,
            "p95_fringe": comp.p95,
            "centre_measured_px": list(comp.centre_measured),
            "scale": comp.scale,
            "rotation_deg": comp.rotation_deg,
            **comp.info,
        }
        (work / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
