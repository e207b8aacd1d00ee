"""Load-to-fringe calibration of the reference indenter, 1-10 N
============================================================

The fringe order along the radius at every load from one continuation run, and the
fitted relations F = a v^b for the order at fixed radii and the radii of the first
fringes (``fringekit calibrate``). The fit is checked by estimating a load that was not
calibrated (5 N, solved separately) from its predicted fringe map.

.. code-block:: bash

    python examples/calibration_load_to_fringe.py [--coarse] [--out DIR]

Writes ``calibration/`` (the folder of ``fringekit calibrate``: ``calibration.png``,
``calibration.json``), ``check_5N/`` and ``check.json`` (the 5 N estimate).
"""

from __future__ import annotations

import sys

from common import config, out_dir, parse_args, predict, write_json

from fringekit.analysis import estimate_load, fringe_features
from fringekit.calibrate.load import run_calibrate


def main(argv=None) -> dict:
    args = parse_args(__doc__.splitlines()[0], argv)
    out = out_dir(args, "calibration")
    loads = [2.0, 4.0, 6.0, 8.0] if args.coarse else [float(k) for k in range(1, 11)]
    cfg = config({"indenter.load_N": loads, "case": "calibration"}, args.coarse)
    # calibrate writes a folder of its own; the 5 N check goes beside it
    cal = run_calibrate(cfg, out / "calibration", cache_dir=args.cache_dir, progress=not args.quiet)
    check_cfg = config({"indenter.load_N": [5.0], "case": "check_5N"}, args.coarse)
    _, state = predict(check_cfg, out / "check_5N", args)
    import numpy as np

    with np.load(state / "maps.npz") as z:
        order, px, rc = z["fringe_order"], float(z["pixel_size_m"]), tuple(z["indenter_rc"][0])
    est = estimate_load(cal, fringe_features(order, px, rc))
    check = {
        "true_N": 5.0,
        "estimate_N": est["normal_N"],
        "sigma_N": est["normal_sigma_N"],
        "spread_N": est["spread_N"],
        "per_feature_N": {k: v["load_N"] for k, v in est["per_feature"].items()},
    }
    write_json(out / "check.json", check)
    if not args.quiet:
        fit = cal["normal_fits"].get("order_at_3mm") or next(iter(cal["normal_fits"].values()))
        print(
            f"calibration: {len(loads)} loads; order at 3 mm: F = {fit['a']:.3g} v^{fit['b']:.3f}"
            f" (scatter {100 * fit['sigma_logF']:.1f} %); 5 N estimated as "
            f"{check['estimate_N']:.3f} N (features spread {check['spread_N']:.2f} N)"
        )
    return {"calibration": cal["normal_fits"], "check": check}


if __name__ == "__main__":
    main(sys.argv[1:])
