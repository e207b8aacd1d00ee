"""The figure ``fringekit sensor calibrate`` writes beside the sensor file: the rest-frame
maps, and every known frame measured, fitted and its residual."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from fringekit.config.inputs import optics_setup
from fringekit.inversion.rest import residual_fringes

__all__ = ["calibration_figure"]


def _grey(v: np.ndarray) -> np.ndarray:
    """A (rows, cols[, C]) image as one channel: the colour channels' mean, or the second
    of the six phase steps (a dark field, 1 - cos d; their mean is even)."""
    if v.ndim == 3 and v.shape[-1] == 6:
        return v[..., 1]
    return v.mean(-1) if v.ndim == 3 else v


def _rest(s):
    """(map, title, colour-bar label) of the sheet at rest: the rest frame's light, or the
    phase method's residual retarder in fringes."""
    if s.residual is None:
        return _grey(s.rest), "rest frame (residual birefringence)", "linear intensity"
    law = s.optics(optics_setup(s.config)).law
    fringes = residual_fringes(s.residual.reshape(-1, 2), law).reshape(s.residual.shape[:2])
    return fringes, "residual retarder (rest steps)", "retardation (fringe)"


def calibration_figure(path, cal) -> None:
    """First row: the illumination (relative) and the rest frame's linear intensity (phase:
    the residual retarder), with the fitted scales; one row per known frame: the measured
    frame less the rest frame (phase: its second step), the fit, and the residual of the
    mean gain (its ``residual_rms`` in the title)."""
    s, fit = cal.sensor, cal.fit
    n = len(fit.fitted)
    fig = Figure(figsize=(12, 3.6 * (n + 1)), dpi=90)
    axes = np.atleast_2d(fig.subplots(n + 1, 3))
    im = axes[0, 0].imshow(s.illumination, cmap="viridis")
    fig.colorbar(im, ax=axes[0, 0], fraction=0.046, label="relative illumination")
    axes[0, 0].set_title("illumination")
    rest, title, label = _rest(s)
    im = axes[0, 1].imshow(rest, cmap="magma")
    fig.colorbar(im, ax=axes[0, 1], fraction=0.046, label=label)
    axes[0, 1].set_title(title)
    axes[0, 2].axis("off")
    text = [
        f"modulus x {s.modulus_scale:.4f}",
        f"fringe value x {s.fringe_scale:.4f}",
        f"gamma {s.gamma:.3f}",
        f"black {', '.join(f'{b:.4f}' for b in s.black)}",
        f"pitch {s.pixel_mm:.5g} mm",
        f"origin ({s.origin_px[0]:.2f}, {s.origin_px[1]:.2f}) px",
        f"rotation {s.rotation_deg:.2f} deg",
    ]
    axes[0, 2].text(0.0, 0.95, "\n".join(text), va="top", family="monospace")
    shape = fit.grid_shape
    gain = float(np.abs(fit.coefficients[0]).mean()) or 1.0
    for i, (name, d, f, r) in enumerate(
        zip(cal.images, fit.measured, fit.fitted, fit.residual_rms, strict=True), start=1
    ):
        top = float(np.max(d)) or 1.0
        seen = "measured (step 2)" if s.method == "phase" else "measured - rest"
        for ax, v, title in ((axes[i, 0], d, seen), (axes[i, 1], f, "fitted")):
            ax.imshow(np.clip(_grey(v.reshape(*shape, -1)) / top, 0, 1), cmap="gray")
            ax.set_title(f"{title}: {name.rsplit('/', 1)[-1]}")
        im = axes[i, 2].imshow(
            _grey(((d - f) / gain).reshape(*shape, -1)), cmap="coolwarm", vmin=-0.3, vmax=0.3
        )
        fig.colorbar(im, ax=axes[i, 2], fraction=0.046, label="of the fringe amplitude")
        axes[i, 2].set_title(f"residual (rms {r:.3f} near the contacts)")
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path)
