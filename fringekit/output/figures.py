"""Every figure fringekit writes: maps, profiles, comparisons, calibrations, sweeps.

Figures are built on :class:`matplotlib.figure.Figure` objects and saved directly, never
through ``pyplot`` state or :func:`matplotlib.use`: writing a PNG does not switch the
backend of a notebook or an application that imports fringekit.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from fringekit.analysis import line_profile

__all__ = [
    "NO_DATA_RGB",
    "NO_DATA_IMAGE_LEVEL",
    "map_figure",
    "sensor_extent",
    "profile_figure",
    "comparison_figure",
    "calibration_figure",
    "sweep_plots",
]


#: How pixels without data (the contact zone, masked or unreliable pixels, pixels off the
#: sheet) look in every figure: flat light grey, with a legend entry "no data". In every
#: map (maps.npz, analysis.npz) they are NaN.
NO_DATA_RGB = (0.82, 0.82, 0.82)
#: ... and in every image fringekit writes as a camera would (six-step PNGs, white light):
#: this fraction of full scale in every channel, with mask.png (255 = data) beside them.
NO_DATA_IMAGE_LEVEL = 0.5


def _legend(ax, handles) -> None:
    """The small legend of the "no data" and hatched markings, when there are any."""
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.8)


def _no_data(ax, data, extent) -> list:
    """Paint pixels without data (NaN in a map; NaN in any channel of an RGB float image)
    in :data:`NO_DATA_RGB`; returns the legend entry when there are any."""
    bad = ~np.isfinite(np.asarray(data, float))
    if bad.ndim == 3:
        bad = bad.any(axis=-1)
    if not bad.any():
        return []
    overlay = np.zeros((*bad.shape, 4))
    overlay[bad] = (*NO_DATA_RGB, 1.0)
    ax.imshow(overlay, extent=extent, interpolation="nearest")
    return [Patch(color=NO_DATA_RGB, label="no data")]


def sensor_extent(shape, pixel_size: float, origin_rc) -> tuple[float, float, float, float]:
    """imshow extent (left, right, bottom, top) in mm of an image in the sensor frame:
    x to the right and y up from the sensor origin at pixel ``origin_rc`` (row, col)."""
    rows, cols = shape[:2]
    p = pixel_size * 1e3
    r0, c0 = origin_rc
    return ((-0.5 - c0) * p, (cols - 0.5 - c0) * p, (r0 - rows + 0.5) * p, (r0 + 0.5) * p)


def _figure(figsize, dpi=100, ncols: int = 1):
    fig = Figure(figsize=figsize, dpi=dpi)
    axes = fig.subplots(1, ncols)
    return fig, axes


def _save(fig, path) -> None:
    fig.tight_layout()
    fig.savefig(path)


def map_figure(
    path,
    data,
    title: str,
    label: str,
    cmap="turbo",
    *,
    extent=None,
    axis_labels=("column (px)", "row (px)"),
    vmin=None,
    vmax=None,
    hatch=None,
    hatch_label: str = "",
) -> Figure:
    """PNG of a (rows, cols) map with a colour bar, or of an RGB image (no colour bar).

    ``extent`` (left, right, bottom, top) in the axis units; None plots in pixels. NaN
    pixels (for an RGB image: a float image with NaN) are drawn as "no data"
    (:data:`NO_DATA_RGB`). ``hatch`` (rows, cols) bool marks pixels whose value is one of
    several (hatched, with ``hatch_label`` in the legend).
    """
    fig, ax = _figure((5.2, 4.4), dpi=120)
    im = ax.imshow(data, cmap=cmap, extent=extent, vmin=vmin, vmax=vmax, interpolation="nearest")
    if np.ndim(data) == 2:
        fig.colorbar(im, ax=ax, label=label)
    handles = _no_data(ax, data, extent)
    if hatch is not None and np.any(hatch):
        ax.contourf(
            np.asarray(hatch, float),
            levels=[0.5, 1.5],
            colors="none",
            hatches=["////"],
            extent=extent,
            origin="upper",
        )
        handles.append(Patch(facecolor="none", edgecolor="k", hatch="////", label=hatch_label))
    _legend(ax, handles)
    ax.set_xlabel(axis_labels[0])
    ax.set_ylabel(axis_labels[1])
    ax.set_title(title)
    _save(fig, path)
    return fig


def profile_figure(path, distance, values, *, xlabel: str, title: str) -> None:
    """PNG of the fringe order along a line: ``distance`` (k,) against ``values`` (k,)."""
    fig, ax = _figure((6, 3.4), dpi=120)
    ax.plot(distance, values, "-", lw=1.5)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fringe order")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    _save(fig, path)


def comparison_figure(
    comp, path, *, line=None, title: str = "", pixel_size: float = 0.0, centre_xy_mm=(0.0, 0.0)
) -> Figure:
    """PNG: measured, predicted, residual maps and an overlaid profile along ``line``.

    Parameters
    ----------
    comp : analysis.Comparison
    path : str or Path
    line : ((row, col), (row, col)), optional
        Default: the horizontal line through the registered centre.
    title : str
    pixel_size : float
        Measured pixel pitch (m); with it the maps are drawn in the sensor frame (x right,
        y up, mm), else in pixels.
    centre_xy_mm : (x, y)
        Sensor coordinates (mm) of the registered centre (the prediction's indenter axis).
    """
    if line is None:
        r = comp.centre_measured[0]
        line = ((r, 0.0), (r, comp.measured.shape[1] - 1.0))
    p = pixel_size * 1e3
    if p:
        rc, cc = comp.centre_measured
        origin = (rc + centre_xy_mm[1] / p, cc - centre_xy_mm[0] / p)
        extent = sensor_extent(comp.measured.shape, pixel_size, origin)

        def to_axes(r, c):
            return (c - origin[1]) * p, (origin[0] - r) * p

        labels, unit = ("x (mm)", "y (mm)"), "mm"
    else:
        extent, labels, unit = None, ("column (px)", "row (px)"), "px"

        def to_axes(r, c):
            return c, r

    fig, ax = _figure((16, 4), ncols=4)
    vmax = np.nanmax([np.nanmax(comp.measured), np.nanmax(comp.predicted)])
    lim = np.nanmax(np.abs(comp.residual)) or 1.0
    panels = (
        (comp.measured, "measured fringe order", "viridis", 0, vmax),
        (comp.predicted, "predicted fringe order", "viridis", 0, vmax),
        (
            comp.residual,
            f"residual, fringe (RMS {comp.rms:.3g}, 95th percentile of |r| {comp.p95:.3g})",
            "RdBu_r",
            -lim,
            lim,
        ),
    )
    (x0, y0), (x1, y1) = to_axes(*line[0]), to_axes(*line[1])
    for a, (data, name, cmap, lo, hi) in zip(ax[:3], panels, strict=True):
        im = a.imshow(data, vmin=lo, vmax=hi, cmap=cmap, extent=extent, interpolation="nearest")
        a.set_title(name, fontsize=9)
        a.set_xlabel(labels[0])
        a.set_ylabel(labels[1])
        fig.colorbar(im, ax=a, shrink=0.8)
        _legend(a, _no_data(a, data, extent))
        a.plot([x0, x1], [y0, y1], "w--", lw=1)
    pm = line_profile(comp.measured, *line, pixel_size=pixel_size or None)
    pp = line_profile(comp.predicted, *line, pixel_size=pixel_size or None)
    scale = 1e3 if p else 1.0
    ax[3].plot(pm.distance * scale, pm.values, label="measured")
    ax[3].plot(pp.distance * scale, pp.values, label="predicted")
    ax[3].set_xlabel(f"distance along the dashed line ({unit})")
    ax[3].set_ylabel("fringe order")
    ax[3].legend()
    if title:
        fig.suptitle(title)
    _save(fig, path)
    return fig


def calibration_figure(path, cal: dict, profiles) -> None:
    """PNG of a load-to-fringe calibration: radial order profiles and the fitted F = a v^b.

    Parameters
    ----------
    cal : dict
        From :func:`analysis.calibrate_from_maps` (``loads_N``, ``features``,
        ``normal_fits``).
    profiles : sequence of (r_mm (k,), order (k,))
        The azimuthal mean order of each load state.
    """
    fits = cal["normal_fits"]
    names = [n for n in fits if not n.startswith("centroid")]
    fig, ax = _figure((12, 4.4), dpi=110, ncols=2)
    cmap = colormaps["viridis"]
    loads = cal["loads_N"]
    for k, (r, prof) in enumerate(profiles):
        ax[0].plot(r, prof, color=cmap(k / max(len(profiles) - 1, 1)), label=f"{loads[k]:.3g} N")
    ax[0].set_xlabel("radius (mm)")
    ax[0].set_ylabel("fringe order (azimuthal mean)")
    ax[0].set_title("fringe order along the radius")
    ax[0].legend(fontsize=7, ncol=2)
    ax[0].grid(alpha=0.3)
    for n in names:
        v = np.asarray(cal["features"][n], float)
        fit = fits[n]
        vv = np.linspace(*fit["range"], 50)
        (line,) = ax[1].plot(v, loads, "o", ms=4, label=f"{n}: b = {fit['b']:.2f}")
        ax[1].plot(vv, fit["a"] * vv ** fit["b"], "-", color=line.get_color(), lw=1)
    ax[1].set_xscale("log")
    ax[1].set_yscale("log")
    ax[1].set_xlabel("feature value (fringe, mm or fringe mm^2)")
    ax[1].set_ylabel("normal load (N)")
    ax[1].set_title("fitted relations F = a v^b")
    ax[1].legend(fontsize=7)
    ax[1].grid(alpha=0.3, which="both")
    _save(fig, path)


def _swept_value(v):
    v = json.loads(v) if isinstance(v, str) and v.startswith("[") else v
    return v[-1] if isinstance(v, list) else v  # a load path: its last (largest) state


def sweep_plots(rows: list[dict], keys: list[str], folder: Path) -> None:
    """One PNG per numeric swept key: max fringe order, depth and contact radius against it,
    one line per combination of the other keys (``rows`` from the sweep's result table)."""
    ok = [r for r in rows if r["status"] == "ok"]
    if not ok:
        return
    folder.mkdir(parents=True, exist_ok=True)
    for key in keys:
        xs = [_swept_value(r[key]) for r in ok]
        if not all(isinstance(x, (int, float)) for x in xs):
            continue
        fig, ax = _figure((13, 3.6), ncols=3)
        others = [k for k in keys if k != key]
        groups: dict = {}
        for x, r in zip(xs, ok, strict=True):
            groups.setdefault(tuple(r[k] for k in others), []).append((x, r))
        for label, pts in groups.items():
            pts.sort(key=lambda p: p[0])
            lab = ", ".join(f"{k}={v}" for k, v in zip(others, label, strict=True)) or None
            for a, m in zip(ax, ("max_fringe_order", "depth_mm", "contact_radius_mm"), strict=True):
                a.plot([p[0] for p in pts], [p[1][m] for p in pts], "o-", label=lab)
                a.set_ylabel(m)
        for a in ax:
            a.set_xlabel(key)
            a.grid(alpha=0.3)
        if len(groups) > 1:
            ax[0].legend(fontsize=7)
        _save(fig, folder / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', key)}.png")


def disc_fit_figure(path, photos, orders, titles) -> None:
    """One panel per photograph of a disc: the photo in grey with the fitted fringe
    centres drawn over it - whole orders (cyan) and half orders (orange) of the fitted
    order map (NaN outside the disc).

    photos : list of (rows, cols) float; orders : list of (rows, cols) float (fringe);
    titles : list of str.
    """
    n = len(photos)
    fig, axes = _figure((3.2 * n, 3.4), dpi=110, ncols=n)
    for ax, img, N, title in zip(np.atleast_1d(axes), photos, orders, titles, strict=True):
        ax.imshow(img, cmap="gray", vmin=0, vmax=max(float(np.nanmax(img)), 1e-6))
        top = float(np.nanmax(N)) if np.isfinite(N).any() else 0.0
        whole = np.arange(np.ceil(np.nanmin(N)), top + 1e-9) if top > 0 else []
        halves = np.arange(np.ceil(np.nanmin(N) - 0.5) + 0.5, top + 1e-9) if top > 0 else []
        if len(whole):
            ax.contour(N, levels=whole, colors="cyan", linewidths=0.7)
        if len(halves):
            ax.contour(N, levels=halves, colors="orange", linewidths=0.7)
        ax.set_title(title, fontsize=8)
        ax.set_axis_off()
    _save(fig, path)
