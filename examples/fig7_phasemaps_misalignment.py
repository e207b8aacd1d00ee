"""Seed paper Fig. 7: six-step phasemaps under monochromatic light, isoclinic (eq. 2) and
isochromatic (eq. 3), with a small output quarter-wave plate misalignment (3 deg) and a
quarter-wave retardance error (4 deg), next to the same with perfect optics.

The paper saw an oval phasemap and zones where it was reversed. Reversed zones (delta
read as 2 pi - delta where sin delta < 0, with the isoclinic pi/2 off) come from eq. 2's
plain arctan and appear with perfect optics too; the oval comes from the optics errors,
whose phase error depends on the isoclinic, which turns with the azimuth about the
indenter. Both are measured: the reversed fraction, and the azimuthal variation of the
mean phase error on an annulus (its half peak-to-peak, in fringes).

    python examples/fig7_phasemaps_misalignment.py [--coarse] [--out DIR]
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
    maps,
    out_dir,
    parse_args,
    predict,
    six_images,
    write_json,  # noqa: E402
)

from analysis import exclude_circle, load_six_step, six_step, wrap  # noqa: E402

ERRORS = {"optics.qwp_out_error_deg": 3.0, "optics.qwp_error_deg": 4.0}


def phase_stats(res, truth, valid, x, y, r_band):
    err = wrap(res.delta_eq3 - truth)
    reversed_ = valid & (np.abs(err) > np.pi / 2)
    r = np.hypot(x, y)
    band = valid & ~reversed_ & (r >= r_band[0]) & (r <= r_band[1])
    phi = np.arctan2(y, x)
    sectors = np.floor((phi + np.pi) / (np.pi / 4)).astype(int) % 8
    means = [float(np.angle(np.mean(np.exp(1j * err[band & (sectors == k)])))) for k in range(8)]
    return {
        "reversed_fraction": float(reversed_[valid].mean()),
        "sector_mean_error_fringe": [m / (2 * np.pi) for m in means],
        "oval_amplitude_fringe": float((max(means) - min(means)) / 2 / (2 * np.pi)),
        "rms_error_fringe_not_reversed": float(
            np.sqrt(np.mean(err[valid & ~reversed_] ** 2)) / (2 * np.pi)
        ),
    }


def main(argv=None) -> dict:
    args = parse_args(__doc__.splitlines()[0], argv)
    out = out_dir(args, "fig7")
    res, panels = {}, {}
    for name, over in (("perfect", {}), ("misaligned", ERRORS)):
        cfg = config(over, args.coarse)
        summary, state = predict(cfg, out / name, args)
        m = maps(state)
        rc = centre_rc(m)
        a_px = summary["indenters"][0]["contact_radius_mm"] * 1e-3 / float(m["pixel_size_m"])
        mask = exclude_circle(np.isfinite(m["fringe_order"]), rc, a_px + 2)
        r6 = six_step(load_six_step(six_images(state)), mask=mask)
        truth = wrap(2 * np.pi * np.nan_to_num(m["fringe_order"])) % (2 * np.pi)
        x, y = m["x_m"] * 1e3, m["y_m"] * 1e3
        band = (2.0, 4.0)
        res[name] = phase_stats(r6, truth, r6.valid, x, y, band)
        res[name]["optics_errors_deg"] = {k.split(".")[1]: v for k, v in over.items()}
        panels[name] = (r6, m)
    fig, ax = plt.subplots(2, 2, figsize=(10, 9), dpi=100)
    for j, (name, (r6, m)) in enumerate(panels.items()):
        ext = (m["x_m"][0, 0] * 1e3, m["x_m"][0, -1] * 1e3, m["y_m"][-1, 0] * 1e3,
               m["y_m"][0, 0] * 1e3)  # fmt: skip
        iso = np.where(r6.valid, np.degrees(r6.isoclinic_eq2), np.nan)
        d3 = np.where(r6.valid, r6.delta_eq3, np.nan)
        ax[0, j].imshow(iso, cmap="gray", extent=ext)
        ax[0, j].set_title(f"isoclinic, eq. 2 ({name})")
        ax[1, j].imshow(d3, cmap="gray", extent=ext, vmin=0, vmax=2 * np.pi)
        s = res[name]
        ax[1, j].set_title(
            f"isochromatic, eq. 3 ({name})\nreversed {100 * s['reversed_fraction']:.0f} %, "
            f"oval amplitude {s['oval_amplitude_fringe']:.3f} fringe"
        )
    for a in ax.ravel():
        a.set_xlabel("x (mm)")
        a.set_ylabel("y (mm)")
    fig.tight_layout()
    fig.savefig(out / "fig7_phasemaps.png")
    plt.close(fig)
    write_json(out / "fig7.json", res)
    if not args.quiet:
        for name in panels:
            s = res[name]
            print(
                f"fig7 {name}: reversed {100 * s['reversed_fraction']:.1f} % of the valid pixels, "
                f"oval amplitude {s['oval_amplitude_fringe']:.4f} fringe"
            )
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
