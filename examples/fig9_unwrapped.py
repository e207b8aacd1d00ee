"""Seed paper Fig. 9: the unwrapped phasemap and the complete fringe order
=======================================================================

The unwrapped phasemap and the complete fringe order along c-d, against the prediction.
The paper could not unwrap near the centre ("fractional fringe order ... unreliable and
erroneous in this zone"); fringekit resolves the isoclinic ambiguity, unwraps, anchors
the far field, and reports where the result is unreliable (fringes closer than the pixel
pitch resolves, contradicted neighbour relations).

.. code-block:: bash

    python examples/fig9_unwrapped.py [--coarse] [--out DIR]

Writes ``fig9_unwrapped.png`` (phasemap, order along c-d, difference map around the contact)
and ``fig9.json`` (RMS and worst error against the prediction over reliable pixels, the
reliable pixels off by more than 0.1 fringe and how many of them are mirror images
k +- delta of the prediction, unreliable pixels within 1 mm of the masked contact and
elsewhere).
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

from fringekit.analysis import (  # noqa: E402
    line_profile,
    unwrap_fringe_order,
)


def main(argv=None) -> dict:
    args = parse_args(__doc__.splitlines()[0], argv)
    out = out_dir(args, "fig9")
    summary, state = predict(config({}, args.coarse, edge=True), out / "vertical", args)
    m = maps(state)
    rc = centre_rc(m)
    px_mm = float(m["pixel_size_m"]) * 1e3
    a_mm = summary["indenters"][0]["contact_radius_mm"]
    r6 = six_step_of(state, contact_mask(summary, m))
    pred = m["fringe_order"]
    border = np.concatenate(
        [pred[:3].ravel(), pred[-3:].ravel(), pred[:, :3].ravel(), pred[:, -3:].ravel()]
    )
    anchor = float(np.nanmedian(border))  # the far field's order, as a calibration gives it
    fo = unwrap_fringe_order(r6, anchor_order=anchor)
    r = np.hypot(m["x_m"], m["y_m"]) * 1e3
    near = r6.valid & (r <= a_mm + 1.0)
    far = r6.valid & ~near
    err = fo.order - pred
    off = fo.reliable & (np.abs(err) > 0.1)
    mid = 0.5 * (fo.order + pred)
    res = {
        "anchor_order": anchor,
        "info": fo.info,
        "rms_fringe_reliable": float(np.sqrt(np.nanmean(err[fo.reliable] ** 2))),
        "max_abs_error_fringe": float(np.nanmax(np.abs(err[r6.valid]))),
        "max_abs_error_reliable_fringe": float(np.nanmax(np.abs(err[fo.reliable]))),
        "reliable_pixels_off_by_0.1": int(off.sum()),
        # of which the reading and the prediction are mirror images about a whole or half
        # order (k + delta against k - delta: the characteristic order's two branches where
        # the axes turn through the thickness; not a fringe-count error)
        "off_by_0.1_mirror_images": int(
            (off & (np.abs(mid - np.round(2 * mid) / 2) < 0.025)).sum()
        ),
        "unreliable_near_contact": int((near & ~fo.reliable).sum()),
        "pixels_near_contact": int(near.sum()),
        "unreliable_elsewhere": int((far & ~fo.reliable).sum()),
        "pixels_elsewhere": int(far.sum()),
    }
    cols = pred.shape[0]
    cd = ((0.0, rc[1]), (cols - 1.0, rc[1]))
    y = -(np.arange(cols) - rc[0]) * px_mm
    p_meas = line_profile(fo.order, *cd, n=cols).values
    p_pred = line_profile(pred, *cd, n=cols).values
    unrel = line_profile(np.where(fo.reliable, np.nan, fo.order), *cd, n=cols).values
    fig, ax = plt.subplots(1, 3, figsize=(16.5, 4.6), dpi=110)
    ext = extent_mm(m)
    im = ax[0].imshow(fo.order, cmap="viridis", extent=ext)
    fig.colorbar(im, ax=ax[0], label="fringe order")
    ax[0].contour(
        np.where(fo.reliable, 0.0, 1.0),
        levels=[0.5],
        colors="r",
        linewidths=0.8,
        extent=(ext[0], ext[1], ext[3], ext[2]),
        origin="upper",
    )
    ax[0].plot([0, 0], [y[0], y[-1]], "w--", lw=1)
    ax[0].set_title("(a) unwrapped phasemap (red: unreliable)")
    ax[0].set_xlabel("x (mm)")
    ax[0].set_ylabel("y (mm)")
    ax[1].plot(y, p_pred, "k-", lw=2, label="prediction")
    ax[1].plot(y, p_meas, "b.", ms=4, label="six-step, unwrapped")
    ax[1].plot(y, unrel, "rx", ms=5, label="flagged unreliable")
    ax[1].set_xlabel("position along c-d (mm)")
    ax[1].set_ylabel("complete fringe order")
    ax[1].set_title(f"(b) along c-d (RMS {res['rms_fringe_reliable']:.3f} on reliable pixels)")
    ax[1].legend(fontsize=8)
    ax[1].grid(alpha=0.3)
    # where they differ: mostly mirror images k +- delta about a whole or half order, the
    # characteristic order's two branches where the axes turn through the thickness
    zoom = 3.0 * a_mm
    im = ax[2].imshow(
        np.where(r6.valid, err, np.nan), cmap="RdBu_r", vmin=-0.3, vmax=0.3, extent=ext
    )
    fig.colorbar(im, ax=ax[2], label="six-step - prediction (fringe)")
    ax[2].set_xlim(-zoom, zoom)
    ax[2].set_ylim(-zoom, zoom)
    ax[2].set_title(
        f"(c) difference; {res['reliable_pixels_off_by_0.1']} reliable pixels off by > 0.1,\n"
        f"{res['off_by_0.1_mirror_images']} of them mirror images about a whole or half order",
        fontsize=9,
    )
    ax[2].set_xlabel("x (mm)")
    fig.tight_layout()
    fig.savefig(out / "fig9_unwrapped.png")
    plt.close(fig)
    write_json(out / "fig9.json", res)
    if not args.quiet:
        print(
            f"fig9: RMS {res['rms_fringe_reliable']:.4f} fringe on reliable pixels; unreliable "
            f"{res['unreliable_near_contact']}/{res['pixels_near_contact']} within 1 mm of "
            f"the contact, {res['unreliable_elsewhere']}/{res['pixels_elsewhere']} elsewhere"
        )
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
