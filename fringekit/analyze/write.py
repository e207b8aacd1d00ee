"""``fringekit analyze``: image files -> maps, profiles, figures.

``run_analyze`` reads a six-step set (phase), one colour image (RGB) or one monochrome
image (mono, :mod:`fringekit.analyze_mono`), builds the masks, runs the method of
:mod:`analysis`, and writes to an output folder:

- ``maps.npz`` - ``fringe_order`` (NaN where unknown), ``reliable`` (bool), and for the
  phase method ``isoclinic_rad``, ``delta_eq3_rad``, ``delta_axis_insensitive_rad``,
  ``modulation``; for RGB ``colour_error``; for mono ``order_sd``,
  ``normalised_intensity``, ``fringe_centres``; ``stress_difference_Pa`` when a fringe value
  and thickness are given; ``pixel_size_m`` (0 when not given);
- ``fringe_order.png`` and the method's other maps as PNG figures;
- ``profile.csv`` / ``profile.png`` - the order along a line (the seed paper's a-b line);
- ``summary.json`` - method, inputs, counts of valid and reliable pixels, order range;
- ``points.csv`` - with ``points``: the order at the given points.

Stored maps are read back by :mod:`fringekit.maps` (``compare``, ``estimate``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fringekit.analysis import (
    line_profile,
    load_image,
    principal_stress_difference,
)
from fringekit.analyze.methods import analyse_phase, analyse_rgb
from fringekit.analyze.mono import analyse_mono, read_points, write_points
from fringekit.analyze.regions import disc_region
from fringekit.output.figures import map_figure, profile_figure, sensor_extent

__all__ = ["run_analyze"]


def _figure(path, data, title, label, cmap="turbo", pixel_size=0.0, vmin=None, vmax=None,
            origin_rc=(0.0, 0.0)):  # fmt: skip
    """:func:`map_figure` in the sensor frame (mm, y up) when the pixel size is known,
    else in pixels (the coordinates the options take)."""
    if pixel_size:
        ext = sensor_extent(data.shape, pixel_size, origin_rc)
        map_figure(path, data, title, label, cmap, extent=ext, axis_labels=("x (mm)", "y (mm)"),
                   vmin=vmin, vmax=vmax)  # fmt: skip
    else:
        map_figure(path, data, title, label, cmap, vmin=vmin, vmax=vmax)


#: Share of the region of interest that must be reliable before analyze stops warning
#: (and, with ``--strict``, exits 1).
MIN_RELIABLE_SHARE = 0.5


def _write_figures(out: Path, method: str, maps: dict, pixel_size: float, origin_rc) -> None:
    """One PNG per map of ``maps`` (fringe order, the method's maps, stress)."""
    two_pi = 2 * np.pi
    figures = [("fringe_order", maps["fringe_order"], f"fringe order ({method})",
                "fringe order", "turbo", None, None)]  # fmt: skip
    if method == "phase":
        figures += [
            ("isoclinic", np.degrees(maps["isoclinic_rad"]), "isoclinic", "deg", "twilight",
             None, None),
            ("phasemap_eq3", maps["delta_eq3_rad"], "isochromatic phase (eq. 3)", "rad",
             "gray", 0, two_pi),
            ("phasemap_axis_insensitive", maps["delta_axis_insensitive_rad"],
             "axis-insensitive phase (eq. 4)", "rad", "gray", 0, np.pi),
            ("modulation", maps["modulation"], "modulation", "", "viridis", 0, 1),
        ]  # fmt: skip
    elif method == "mono":
        figures += [
            ("order_sd", maps["order_sd"], "fringe order uncertainty (1 sd)", "fringe",
             "magma", 0, None),
            ("normalised_intensity", np.where(maps["fringe_centres"], np.nan,
             maps["normalised_intensity"]), "sin^2(pi N), fringe centres blank", "", "gray",
             0, 1),
        ]  # fmt: skip
    else:
        figures.append(("colour_error", maps["colour_error"], "colour distance to table", "",
                        "magma", None, None))  # fmt: skip
    if "stress_difference_Pa" in maps:
        figures.append(("stress_difference", maps["stress_difference_Pa"] * 1e-6,
                        "principal stress difference", "MPa", "viridis", None, None))  # fmt: skip
    for name, data, title, label, cmap, vmin, vmax in figures:
        _figure(out / f"{name}.png", data, title, label, cmap, pixel_size, vmin, vmax, origin_rc)


def _write_profile(out: Path, order, line, pixel_size: float, origin_rc) -> None:
    """``profile.csv`` and ``profile.png`` along ``line`` (r0, c0, r1, c1) px; with a pixel
    size the table also gives each sample's x, y in the sensor frame (mm)."""
    prof = line_profile(order, line[:2], line[2:], pixel_size=pixel_size or None)
    t = np.linspace(0.0, 1.0, len(prof.values))
    rows = line[0] + t * (line[2] - line[0])
    cols = line[1] + t * (line[3] - line[1])
    if pixel_size:
        dist = prof.distance * 1e3
        x = (cols - origin_rc[1]) * pixel_size * 1e3
        y = (origin_rc[0] - rows) * pixel_size * 1e3
        table, head, unit = (
            np.column_stack([dist, x, y, prof.values]),
            "distance_mm,x_mm,y_mm",
            "mm",
        )
    else:
        dist = prof.distance
        table, head, unit = (
            np.column_stack([dist, rows, cols, prof.values]),
            "distance_px,row,col",
            "px",
        )
    np.savetxt(out / "profile.csv", table, delimiter=",", header=head + ",fringe_order",
               comments="", fmt="%.6g")  # fmt: skip
    title = f"profile ({line[0]:.0f}, {line[1]:.0f}) -> ({line[2]:.0f}, {line[3]:.0f}) px"
    profile_figure(out / "profile.png", dist, prof.values,
                   xlabel=f"distance along the line ({unit})", title=title)  # fmt: skip


def _write_outputs(out: Path, method, maps, pixel_size, origin_rc, line, pts) -> None:
    """maps.npz, the figures, the profile and (with points) points.csv."""
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "maps.npz", **maps)
    _write_figures(out, method, maps, pixel_size, origin_rc)
    _write_profile(out, maps["fringe_order"], line, pixel_size, origin_rc)
    if pts is not None:
        write_points(out, pts, maps, pixel_size, origin_rc)


def _profile_line(line, exclude, roi: np.ndarray) -> tuple[float, float, float, float]:
    """The profile line (r0, c0, r1, c1) px: the given one, checked against the image, or
    the row through the first excluded circle's centre (the indenter), else through the
    middle of the region of interest, across the region's columns."""
    rows, cols = roi.shape
    if line is None:
        rr, cc = np.nonzero(roi)
        r = exclude[0][0] if exclude else float(np.round(rr.mean()))
        line = (r, float(cc.min()), r, float(cc.max()))
    for name, (r, c) in (("start", line[:2]), ("end", line[2:])):
        if not (0 <= r <= rows - 1 and 0 <= c <= cols - 1):
            raise ValueError(
                f"--line {name} ({r:g}, {c:g}) is outside the image; allowed rows 0..{rows - 1}, "
                f"columns 0..{cols - 1}"
            )
    return line


def _counts(order, reliable, mask, part: dict) -> dict:
    """Pixel counts, the order range and the reliability warning of an analysis."""
    finite = np.isfinite(order)
    roi = int(mask.sum())
    share = float(np.sum(reliable & mask)) / roi if roi else 0.0
    out = {
        "shape": list(order.shape),
        "valid_pixels": int(finite.sum()),
        "reliable_pixels": int(np.sum(reliable)),
        "masked_pixels": int((~mask).sum()),
        "fringe_order_range": [float(np.nanmin(order)), float(np.nanmax(order))]
        if finite.any()
        else None,
        "reliable_fraction_of_roi": share,
    }
    warnings = []
    if share < MIN_RELIABLE_SHARE:
        why = part.get("unreliable_reason", "the order map is mostly a guess")
        warnings.append(
            f"only {100 * share:.0f} % of the region of interest is reliable (fewer than "
            f"{100 * MIN_RELIABLE_SHARE:.0f} %): {why}"
        )
    if "extra_warning" in part:
        warnings.append(part["extra_warning"])
    if warnings:
        out["warning"] = "; ".join(warnings)
    return out


def _method(method, paths) -> str:
    """The method asked for, or the default for the images given (checked)."""
    if method is None:
        single = len(paths) == 1 and not paths[0].lower().endswith((".tif", ".tiff"))
        method = ("rgb" if load_image(paths[0]).data.ndim == 3 else "mono") if single else "phase"
    if method not in ("phase", "rgb", "mono"):
        raise ValueError(f"--method {method!r} is not allowed; use phase, rgb or mono")
    return method


def run_analyze(
    images: Sequence[str | os.PathLike],
    out: str | os.PathLike,
    *,
    method: str | None = None,
    dark=None,
    roi_circle: tuple[float, float, float] | None = None,
    exclude: Sequence[tuple[float, float, float]] = (),
    roi_polygon=None,
    exclude_polygons=(),
    pixel_size: float = 0.0,
    origin_px: tuple[float, float] | None = None,
    anchor_order: float = 0.0,
    order_at: Sequence[tuple[float, float, float]] = (),
    line: tuple[float, float, float, float] | None = None,
    f_sigma: float | None = None,
    thickness: float | None = None,
    points=None,
    phase: dict | None = None,
    rgb: dict | None = None,
    mono: dict | None = None,
    roi_disc: float | None = None,
) -> dict:
    """Analyse fringe images; write maps, figures and a summary to ``out``.

    Parameters
    ----------
    images : paths - ``phase``: six files in :data:`analysis.SIX_STEP_ORDER` or one
        6-page TIFF; ``rgb``: one colour image; ``mono``: one image.
    method : {"phase", "rgb", "mono"}, optional - default ``rgb`` for one colour image,
        ``mono`` for one grey image, ``phase`` otherwise.
    roi_circle : (row, col, radius) px; exclude : (row, col, radius) px circles;
    roi_polygon, exclude_polygons : (k, 2) (row, col) px - the region of interest.
    pixel_size : float (m) - for axes in mm, 0 = pixels; origin_px : (row, col) - the
        pixel of the sensor origin (default the image centre) for the sensor frame.
    anchor_order : float - order of the image border ring (far field); order_at : (row,
        col, order) ... - pixels of known order instead (each the lowest about it).
    line : (r0, c0, r1, c1) px - profile line (default across the region).
    f_sigma, thickness : float (N/m, m) - both for the stress difference (seed eq. 4).
    points : path - CSV (``row,col`` or ``x_mm,y_mm``) for ``points.csv``.
    phase : dict - ``min_modulation``, ``fold`` ("count"/"isoclinic": how the folded
        phase is resolved; the other checks it), ``reference`` (six zero-load images).
    rgb : dict - ``calibration`` (table CSV), ``chart`` (light, camera, max_order,
        exposure of the synthetic chart), ``seeds`` ((row, col, order) ...), ``window``.
    mono : dict - ``field`` ("dark"/"bright"), ``flat`` (image path), ``smooth_px``.
    roi_disc : float (m) - the diameter of a circular specimen to find in the first image:
        it sets the region, the pixel size and the origin (:func:`regions.disc_region`).
    """
    paths = [str(p) for p in images]
    if not paths:
        raise ValueError("analyze needs at least one image")
    method = _method(method, paths)
    phase, rgb = phase or {}, rgb or {}
    disc = None if roi_disc is None else disc_region(paths[0], roi_disc, dark)
    if disc is not None:
        roi_circle, pixel_size = disc["roi_circle"], pixel_size or disc["pixel_size"]
        origin_px = origin_px if origin_px is not None else disc["origin_px"]
    if phase.get("reference") and method != "phase":
        raise ValueError(
            f"--reference is for --method phase (six zero-load images); the {method} method "
            "has none (calibrate --disc takes a zero-load photo)"
        )
    if (f_sigma is None) != (thickness is None):
        raise ValueError("give both the fringe value and the thickness for stress, or neither")
    out = Path(out)
    mask_args = (roi_circle, exclude, roi_polygon, exclude_polygons)
    runs = {
        "phase": lambda: analyse_phase(paths, dark, mask_args, anchor_order, order_at, **phase),
        "mono": lambda: analyse_mono(paths, dark, mask_args, anchor_order, order_at, mono or {}),
        "rgb": lambda: analyse_rgb(paths, dark, mask_args, **rgb),
    }  # fmt: skip
    order, reliable, maps, part, mask = runs[method]()
    summary: dict = {"method": method, "images": paths}
    if disc is not None:
        summary["disc_found"] = disc["info"]
    summary.update((k, v) for k, v in part.items() if k != "extra_warning")
    rows, cols = order.shape
    origin_rc = tuple(origin_px) if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    line = _profile_line(line, exclude, mask)
    pts = None if points is None else read_points(points, order.shape, pixel_size, origin_rc)
    maps.update(fringe_order=order, reliable=reliable, pixel_size_m=np.array(pixel_size))
    if f_sigma is not None:
        maps["stress_difference_Pa"] = principal_stress_difference(order, f_sigma, thickness)
    _write_outputs(out, method, maps, pixel_size, origin_rc, line, pts)
    if pts is not None:
        summary["points"] = str(points)
    summary.update(_counts(order, reliable, mask, part))
    summary.update(
        pixel_size_mm=pixel_size * 1e3,
        origin_px=[float(v) for v in origin_rc],
        line_px=[float(v) for v in line],
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary
