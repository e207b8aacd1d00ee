"""Seed paper Fig. 3: white-light fringes under vertical and shear load
====================================================================

White-light fringes under the 3.5 mm indenter, (a) 8 N vertical and (b) 8 N vertical +
6.4 N shear with stick (the built-in shear case; the paper's 8 N of shear folds an
element at the stuck contact's trailing edge, ``docs/validation.md``), side by side on
the same camera settings; the shift of the pattern in the shear direction is measured
and reported.

.. code-block:: bash

    python examples/fig3_white_light.py [--coarse] [--out DIR]

Writes ``fig3_white_light.png`` and ``fig3.json`` (max fringe order of each case, the
order-weighted centroid of each pattern about the undeformed indenter axis, the pattern
shift and the indenter's own displacement).
"""

from __future__ import annotations

import sys

import imageio.v3 as iio
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from common import config, extent_mm, maps, out_dir, parse_args, predict, write_json  # noqa: E402


def centroid_mm(m: dict, r_max_mm: float) -> tuple[float, float]:
    """Order-weighted centroid (x, y) in mm of the valid pixels within r_max of the axis."""
    x, y, n = m["x_m"] * 1e3, m["y_m"] * 1e3, m["fringe_order"]
    use = np.isfinite(n) & (np.hypot(x, y) <= r_max_mm)
    w = np.where(use, n, 0.0)
    return float((w * x).sum() / w.sum()), float((w * y).sum() / w.sum())


def main(argv=None) -> dict:
    args = parse_args(__doc__.splitlines()[0], argv)
    out = out_dir(args, "fig3")
    cases = {
        "vertical": config({}, args.coarse),
        "shear": config({}, args.coarse, base="shear"),
    }
    r_max = 4.0 if args.coarse else 8.0
    res, images = {}, {}
    for name, cfg in cases.items():
        summary, state = predict(cfg, out / name, args)
        m = maps(state)
        cx, cy = centroid_mm(m, r_max)
        ind = summary["indenters"][0]
        res[name] = {
            "max_fringe_order": summary["max_fringe_order"],
            "force_N": ind["force_N"],
            "depth_mm": ind["depth_mm"],
            "contact_radius_mm": ind["contact_radius_mm"],
            "indenter_x_mm": ind["centre_mm"][0],
            "centroid_mm": [cx, cy],
        }
        images[name] = (iio.imread(state / "white_light.png"), m)
    res["pattern_shift_x_mm"] = res["shear"]["centroid_mm"][0] - res["vertical"]["centroid_mm"][0]
    res["indenter_shift_x_mm"] = res["shear"]["indenter_x_mm"] - res["vertical"]["indenter_x_mm"]

    fig, ax = plt.subplots(1, 2, figsize=(10.5, 5), dpi=110)
    for a, (name, (img, m)) in zip(ax, images.items(), strict=True):
        a.imshow(img, extent=extent_mm(m))
        cx, cy = res[name]["centroid_mm"]
        a.plot([0], [0], "w+", ms=12, label="undeformed axis")
        a.plot([cx], [cy], "wx", ms=10, label="pattern centroid")
        f = res[name]["force_N"]
        a.set_title(
            f"({'ab'[list(images).index(name)]}) {name}: F = "
            f"[{f[0]:.0f}, {f[1]:.0f}, {-f[2]:.0f}] N"
        )
        a.set_xlabel("x (mm)")
        a.set_ylabel("y (mm)")
    ax[1].legend(loc="lower left", fontsize=8)
    fig.suptitle(
        f"white light, dark-field circular; pattern shift in x {res['pattern_shift_x_mm']:.2f} mm"
    )
    fig.tight_layout()
    fig.savefig(out / "fig3_white_light.png")
    plt.close(fig)
    write_json(out / "fig3.json", res)
    if not args.quiet:
        v, s = res["vertical"]["max_fringe_order"], res["shear"]["max_fringe_order"]
        print(
            f"fig3: pattern shift {res['pattern_shift_x_mm']:.3f} mm in x (indenter moved "
            f"{res['indenter_shift_x_mm']:.3f} mm); max order vertical {v:.2f}, shear {s:.2f}"
        )
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
