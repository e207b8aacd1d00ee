"""``fringekit estimate``: the load (and shear) of one indenter from a fringe-order map and a
calibration.
"""

from __future__ import annotations

import argparse
import sys

from fringekit.calibrate.estimate import run_estimate
from fringekit.cli.options import (
    PIXEL_MM,
    finite,
    in_range,
)

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    es = sub.add_parser("estimate", help="load (and shear) from a fringe-order map")
    es.add_argument("maps", help="maps.npz, or a fringekit analyze / predict output folder")
    es.add_argument("--calibration", required=True, help="calibration.json from calibrate")
    es.add_argument("--pixel-mm", type=in_range(PIXEL_MM), default=None)
    es.add_argument(
        "--centre",
        nargs=2,
        type=finite,
        metavar=("ROW", "COL"),
        help="indenter axis in pixels (default: stored in the maps)",
    )
    es.add_argument("--out", default=None)
    es.add_argument("--quiet", action="store_true")
    es.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    est = run_estimate(
        args.maps,
        args.calibration,
        pixel_mm=args.pixel_mm,
        centre=tuple(args.centre) if args.centre else None,
        out=args.out,
    )
    line = (
        f"normal load {est['normal_N']:.3f} N (standard uncertainty {est['normal_sigma_N']:.2g} N"
        f" from the calibration scatter; {len(est['per_feature'])} features, whose estimates "
        f"span {est['spread_N']:.2g} N)"
    )
    if "shear_N" in est:
        line += f"; shear [{est['shear_N'][0]:.3f}, {est['shear_N'][1]:.3f}] N"
    print(line)
    if "warning" in est:
        print(f"fringekit estimate: warning: {est['warning']}", file=sys.stderr)
    return 0
