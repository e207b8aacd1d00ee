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

__all__ = [
    "NO_DATA_RGB",
    "NO_DATA_IMAGE_LEVEL",
    "map_figure",
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


def _no_data(ax, fig, data, extent) -> None:
    """Paint pixels without data (NaN in a map; NaN in any channel of an RGB float image)
    in :data:`NO_DATA_RGB` and add the legend entry when there are any."""
    from matplotlib.patches import Patch

    bad = ~np.isfinite(np.asarray(data, float))
    if bad.ndim == 3:
        bad = bad.any(axis=-1)
    if not bad.any():
        return
    overlay = np.zeros((*bad.shape, 4))
    overlay[bad] = (*NO_DATA_RGB, 1.0)
    ax.imshow(overlay, extent=extent, interpolation="nearest")
    ax.legend(handles=[Patch(color=NO_DATA_RGB, label="no data")], loc="upper right",
              fontsize=7, framealpha=0.8)  # fmt: skip


def _figure(figsize, dpi=100, ncols: int = 1):
    from matplotlib.figure import Figure

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
) -> None:
    """PNG of a (rows, cols) map with a colour bar, or of an RGB image (no colour bar).

    ``extent`` (left, right, bottom, top) in the axis units; None plots in pixels. NaN
    pixels (for an RGB image: a float image with NaN) are drawn as "no data"
    (:data:`NO_DATA_RGB`).
    """
    fig, ax = _figure((5.2, 4.4), dpi=120)
    im = ax.imshow(data, cmap=cmap, extent=extent, vmin=vmin, vmax=vmax, interpolation="nearest")
    if np.ndim(data) == 2:
        fig.colorbar(im, ax=ax, label=label)
    _no_data(ax, fig, data, extent)
    ax.set_xlabel(axis_labels[0])
    ax.set_ylabel(axis_labels[1])
    ax.set_title(title)
    _save(fig, path)


def profile_figure(path, distance, values, *, xlabel: str, title: str) -> None:
    """PNG of the fringe order along a line: ``distance`` (k,) against ``values`` (k,)."""
    fig, ax = _figure((6, 3.4), dpi=120)
    ax.plot(distance, values, "-", lw=1.5)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fringe order")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    _save(fig, path)


def comparison_figure(comp, path, *, line=None, title: str = "") -> None:
    """PNG: measured, predicted, residual maps and an overlaid profile along ``line``.

    Parameters
    ----------
    comp : analysis.Comparison
    path : str or Path
    line : ((row, col), (row, col)), optional
        Default: the horizontal line through the registered centre.
    title : str
    """
    from analysis import line_profile

    if line is None:
        r = comp.centre_measured[0]
        line = ((r, 0.0), (r, comp.measured.shape[1] - 1.0))
    fig, ax = _figure((16, 4), ncols=4)
    vmax = np.nanmax([np.nanmax(comp.measured), np.nanmax(comp.predicted)])
    for a, data, name in (
        (ax[0], comp.measured, "measured N"),
        (ax[1], comp.predicted, "predicted N"),
    ):
        im = a.imshow(data, vmin=0, vmax=vmax, cmap="viridis")
        a.set_title(name)
        fig.colorbar(im, ax=a, shrink=0.8)
    lim = np.nanmax(np.abs(comp.residual)) or 1.0
    im = ax[2].imshow(comp.residual, cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax[2].set_title(f"residual, fringe (RMS {comp.rms:.3g}, 95th percentile of |r| {comp.p95:.3g})")
    fig.colorbar(im, ax=ax[2], shrink=0.8)
    for a in ax[:3]:
        a.plot([line[0][1], line[1][1]], [line[0][0], line[1][0]], "w--", lw=1)
    pm = line_profile(comp.measured, *line)
    pp = line_profile(comp.predicted, *line)
    ax[3].plot(pm.distance, pm.values, label="measured")
    ax[3].plot(pp.distance, pp.values, label="predicted")
    ax[3].set_xlabel("distance along line (px)")
    ax[3].set_ylabel("fringe order")
    ax[3].legend()
    if title:
        fig.suptitle(title)
    _save(fig, path)


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
    from matplotlib import colormaps

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
