"""Seed paper Fig. 8: the axis-insensitive isochromatic
====================================================

The axis-insensitive isochromatic (the seed paper's second eq. 4) under monochromatic
light: the phasemap, and the fractional fringe order along a-b, which eq. 4 folds into
[0, 0.5] (the paper: "fringe order can only range between 0 to 0.5").

.. code-block:: bash

    python examples/fig8_axis_insensitive.py [--coarse] [--out DIR]

Writes ``fig8_axis_insensitive.png`` and ``fig8.json`` (RMS difference between the eq. 4
fractional order and the folded predicted order, over the image and along a-b).
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from common import (  # noqa: E402
    centre_rc,
    config,
    contact_mask,
    extent_mm,
    maps,
    out_dir,
    parse_args,
    predict,
    six_step_of,
    write_json,
)

from fringekit.analysis import line_profile  # noqa: E402


def folded(order):
    """N folded into [0, 0.5]: what eq. 4 (positive root) can show."""
    f = np.mod(order, 1.0)
    return np.minimum(f, 1.0 - f)


def main(argv=None) -> dict:
    args = parse_args(__doc__.splitlines()[0], argv)
    out = out_dir(args, "fig8")
    summary, state = predict(config({}, args.coarse, edge=True), out / "vertical", args)
    m = maps(state)
    rc = centre_rc(m)
    r6 = six_step_of(state, contact_mask(summary, m))
    frac = np.where(r6.valid, r6.delta_axis_insensitive / (2 * np.pi), np.nan)
    pred = np.where(r6.valid, folded(m["fringe_order"]), np.nan)
    row = rc[0]
    cols = frac.shape[1]
    ab = ((row, 0.0), (row, cols - 1.0))
    x = (np.arange(cols) - rc[1]) * float(m["pixel_size_m"]) * 1e3
    p_meas = line_profile(frac, *ab, n=cols).values
    p_pred = line_profile(pred, *ab, n=cols).values
    d = frac - pred
    res = {
        "rms_fringe": float(np.sqrt(np.nanmean(d**2))),
        "rms_fringe_along_ab": float(np.sqrt(np.nanmean((p_meas - p_pred) ** 2))),
        "range": [float(np.nanmin(frac)), float(np.nanmax(frac))],
    }
    fig, ax = plt.subplots(1, 2, figsize=(11.5, 4.6), dpi=110)
    ext = extent_mm(m)
    im = ax[0].imshow(frac, cmap="gray", extent=ext, vmin=0, vmax=0.5)
    fig.colorbar(im, ax=ax[0], label="fractional fringe order")
    ax[0].plot([x[0], x[-1]], [0, 0], "r--", lw=1)
    ax[0].set_title("(a) phasemap, eq. 4 (axis insensitive)")
    ax[0].set_xlabel("x (mm)")
    ax[0].set_ylabel("y (mm)")
    ax[1].plot(x, p_pred, "k-", lw=2, label="prediction, folded to [0, 0.5]")
    ax[1].plot(x, p_meas, "r.", ms=4, label="six-step, eq. 4")
    ax[1].set_xlabel("position along a-b (mm)")
    ax[1].set_ylabel("fractional fringe order")
    ax[1].set_title(f"(b) along a-b (RMS {res['rms_fringe_along_ab']:.3f})")
    ax[1].legend(fontsize=8)
    ax[1].grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "fig8_axis_insensitive.png")
    plt.close(fig)
    write_json(out / "fig8.json", res)
    if not args.quiet:
        print(
            f"fig8: eq. 4 fractional order in [{res['range'][0]:.3f}, {res['range'][1]:.3f}], "
            f"RMS vs folded prediction {res['rms_fringe']:.4f} fringe"
        )
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
