"""What ``fringekit analyze`` writes for an :class:`~fringekit.measurement.order.Analysis`:

- ``maps.npz`` - ``fringe_order`` (NaN where unknown), ``reliable`` (bool), and for the
  phase method ``isoclinic_rad``, ``delta_eq3_rad``, ``delta_axis_insensitive_rad``,
  ``modulation``; for RGB ``colour_error``; for mono ``order_sd``,
  ``normalised_intensity``, ``fringe_centres``; ``stress_difference_Pa`` when a fringe value
  and thickness are given; ``pixel_size_m`` (0 when not given);
- ``fringe_order.png`` and the method's other maps as PNG figures;
- ``profile.csv`` / ``profile.png`` - the order along a line (the seed paper's a-b line);
- ``summary.json`` - method, inputs, counts of valid and reliable pixels, order range;
- ``points.csv`` - with ``points``: the order at the given points.

Stored maps are read back by :mod:`fringekit.measurement.compare` (``compare``, ``estimate``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fringekit.analysis import line_profile
from fringekit.errors import InputError
from fringekit.measurement.mono import read_points, write_points
from fringekit.output.figures import map_figure, profile_figure, sensor_extent
from fringekit.output.folders import atomic_write

__all__ = ["write_analysis"]


def _figure(
    path,
    data,
    title,
    label,
    cmap="turbo",
    pixel_size=0.0,
    vmin=None,
    vmax=None,
    origin_rc=(0.0, 0.0),
):
    """:func:`map_figure` in the sensor frame (mm, y up) when the pixel size is known,
    else in pixels (the coordinates the options take)."""
    if pixel_size:
        ext = sensor_extent(data.shape, pixel_size, origin_rc)
        map_figure(
            path,
            data,
            title,
            label,
            cmap,
            extent=ext,
            axis_labels=("x (mm)", "y (mm)"),
            vmin=vmin,
            vmax=vmax,
        )
    else:
        map_figure(path, data, title, label, cmap, vmin=vmin, vmax=vmax)


def _write_figures(out: Path, method: str, maps: dict, pixel_size: float, origin_rc) -> None:
    """One PNG per map of ``maps`` (fringe order, the method's maps, stress)."""
    two_pi = 2 * np.pi
    figures = [
        (
            "fringe_order",
            maps["fringe_order"],
            f"fringe order ({method})",
            "fringe order",
            "turbo",
            None,
            None,
        )
    ]
    if method == "phase":
        figures += [
            (
                "isoclinic",
                np.degrees(maps["isoclinic_rad"]),
                "isoclinic",
                "deg",
                "twilight",
                None,
                None,
            ),
            (
                "phasemap_eq3",
                maps["delta_eq3_rad"],
                "isochromatic phase (eq. 3)",
                "rad",
                "gray",
                0,
                two_pi,
            ),
            (
                "phasemap_axis_insensitive",
                maps["delta_axis_insensitive_rad"],
                "axis-insensitive phase (eq. 4)",
                "rad",
                "gray",
                0,
                np.pi,
            ),
            ("modulation", maps["modulation"], "modulation", "", "viridis", 0, 1),
        ]
    elif method == "mono":
        figures += [
            (
                "order_sd",
                maps["order_sd"],
                "fringe order uncertainty (1 sd)",
                "fringe",
                "magma",
                0,
                None,
            ),
            (
                "normalised_intensity",
                np.where(maps["fringe_centres"], np.nan, maps["normalised_intensity"]),
                "sin^2(pi N), fringe centres blank",
                "",
                "gray",
                0,
                1,
            ),
        ]
    else:
        figures.append(
            (
                "colour_error",
                maps["colour_error"],
                "colour distance to table",
                "",
                "magma",
                None,
                None,
            )
        )
    if "stress_difference_Pa" in maps:
        figures.append(
            (
                "stress_difference",
                maps["stress_difference_Pa"] * 1e-6,
                "principal stress difference",
                "MPa",
                "viridis",
                None,
                None,
            )
        )
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
    np.savetxt(
        out / "profile.csv",
        table,
        delimiter=",",
        header=head + ",fringe_order",
        comments="",
        fmt="%.6g",
    )
    title = f"profile ({line[0]:.0f}, {line[1]:.0f}) -> ({line[2]:.0f}, {line[3]:.0f}) px"
    profile_figure(
        out / "profile.png",
        dist,
        prof.values,
        xlabel=f"distance along the line ({unit})",
        title=title,
    )


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
    the row through the first excluded circle's centre in the image (the indenter), else
    through the middle of the region of interest, across the region's columns."""
    rows, cols = roi.shape
    if line is None:
        rr, cc = np.nonzero(roi)
        inside = [e for e in exclude if 0 <= e[0] <= rows - 1]  # an indenter in the image
        r = inside[0][0] if inside else float(np.round(rr.mean()))
        line = (r, float(cc.min()), r, float(cc.max()))
    for name, (r, c) in (("start", line[:2]), ("end", line[2:])):
        if not (0 <= r <= rows - 1 and 0 <= c <= cols - 1):
            raise InputError(
                f"--line {name} ({r:g}, {c:g}) is outside the image; allowed rows 0..{rows - 1}, "
                f"columns 0..{cols - 1}"
            )
    return line


def write_analysis(an, out: Path, *, line=None, points=None) -> Path:
    """Write an :class:`~fringekit.measurement.order.Analysis` into ``out``: ``maps.npz``, the
    figures, the profile along ``line`` (r0, c0, r1, c1 px; default across the region),
    ``points.csv`` for a CSV of points, and ``summary.json``."""
    pixel_size = an.pixel_mm * 1e-3
    line = _profile_line(line, an.region.exclude_circles, an.roi_mask)
    pts = (
        None
        if points is None
        else read_points(points, an.fringe_order.shape, pixel_size, an.origin_px)
    )
    _write_outputs(out, an.method, an.maps, pixel_size, an.origin_px, line, pts)
    summary = dict(an.summary, line_px=[float(v) for v in line])
    if pts is not None:
        summary["points"] = str(points)
    atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=float))
    return out
