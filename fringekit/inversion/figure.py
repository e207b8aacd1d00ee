"""``fit.png`` of ``fringekit invert``: measured, fitted and residual images.

The residual panel is in fringe amplitudes (the fitted gains' mean), the unit of each
indenter's ``residual_rms``, which the panel names beside it."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from fringekit.inversion.model import unpack
from fringekit.output.figures import sensor_extent

__all__ = ["fit_figure"]


def _shown(model, values: np.ndarray) -> np.ndarray:
    """(rows, cols[, 3]) of (P, C) values: RGB as is, six steps as step 2 (dark field)."""
    rows, cols = model.grid.shape
    v = values.reshape(rows, cols, -1)
    if model.method == "rgb":
        return v
    return v[..., 1] if model.method == "phase" else v[..., 0]


def fit_figure(path, model, res) -> None:
    """Three panels in sensor mm, indenters marked, tangential loads as arrows; the
    residual in fringe amplitudes with each indenter's ``residual_rms``."""
    known = bool(len(res.params)) and bool(np.all(np.isfinite(res.params)))
    if known:
        fitted, _, _, outside = model.fitted(unpack(res.params.ravel(), list(res.diameters)))
    else:  # no indenter, or positions only (a time budget spent at detection)
        fitted = np.full_like(model.measured, np.median(model.measured))
        outside = np.ones(len(model.measured), bool)
    resid = np.where((model.usable & outside)[:, None], model.misfit(fitted), np.nan)
    origin = tuple(float(v) for v in model.grid.xy_to_pixel(0.0, 0.0))
    ext = sensor_extent(model.grid.shape, model.grid.pixel_size, origin)
    fig = Figure(figsize=(13, 4.6), dpi=100)
    axes = fig.subplots(1, 3)
    top = float(np.nanmax(model.measured)) or 1.0
    amp = float(np.mean(np.abs(res.gains))) if len(res.gains) else 0.0
    panels = (
        ("measured", model.measured / top),
        ("fitted (library)", fitted / top),
        ("residual", resid / (amp or top)),
    )
    scale = max(float(np.max(np.abs(res.params[:, 2]))) if known else 1.0, 1e-9)
    for ax, (title, v) in zip(axes, panels, strict=True):
        img = _shown(model, v)
        if title == "residual":
            if img.ndim == 3:  # the channels' mean; all-NaN pixels (no data) stay NaN
                n = np.isfinite(img).sum(-1)
                img = np.where(n > 0, np.nansum(img, -1) / np.maximum(n, 1), np.nan)
            im = ax.imshow(img, extent=ext, cmap="coolwarm", vmin=-0.3, vmax=0.3)
            label = "of the fringe amplitude" if amp else "of full scale"
            fig.colorbar(im, ax=ax, fraction=0.046, label=label)
        else:
            ax.imshow(np.clip(img, 0, 1), extent=ext, cmap="gray", vmin=0, vmax=1)
        for v_ in res.params:
            ax.plot(v_[0], v_[1], "+", color="yellow", ms=8)
            if not known:
                continue
            ax.arrow(
                v_[0],
                v_[1],
                3.0 * v_[3] / scale,
                3.0 * v_[4] / scale,
                color="yellow",
                width=0.05,
                length_includes_head=True,
            )
        ax.set_title(title)
        ax.set_xlabel("x (mm)")
    axes[0].set_ylabel("y (mm)")
    for i, r in enumerate(res.residual_rms):
        axes[2].annotate(
            f"{i + 1}: residual_rms {r:.3f}",
            (0.02, 0.96 - 0.06 * i),
            xycoords="axes fraction",
            fontsize=7,
            va="top",
        )
    for i, v_ in enumerate(res.params):
        axes[1].annotate(
            f"{i + 1}: Fz {v_[2]:.2f} N, Ft ({v_[3]:.2f}, {v_[4]:.2f}) N",
            (0.02, 0.96 - 0.06 * i),
            xycoords="axes fraction",
            color="yellow",
            fontsize=7,
            va="top",
        )
    fig.tight_layout()
    fig.savefig(path)
