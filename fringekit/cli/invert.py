"""``fringekit invert``: every indenter's position and load vector from an image
(:func:`fringekit.invert`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fringekit.cli.options import (
    PIXEL_MM,
    in_range,
    nonnegative,
    origin_px_option,
    residual_steps_option,
)
from fringekit.inversion.budget import DEFAULT_MAX_SECONDS
from fringekit.inversion.run import run_invert

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    iv = sub.add_parser("invert", help="every indenter's position and load from an image")
    iv.add_argument("images", nargs="+", help="one colour or grey image, or six phase steps")
    iv.add_argument("--library", required=True, help="library folder (fringekit library build)")
    iv.add_argument("--out", required=True, help="output folder")
    iv.add_argument(
        "--method",
        choices=("rgb", "mono", "phase"),
        default=None,
        help="default: rgb for a colour image, mono for grey, phase for six",
    )
    iv.add_argument(
        "--pixel-mm",
        type=in_range(PIXEL_MM),
        default=None,
        help="pixel pitch on the sheet (mm); required without --sensor",
    )
    origin_px_option(iv)
    iv.add_argument(
        "--sensor",
        default=None,
        help="the image's sensor file: SENSOR.json of fringekit sensor calibrate (or of "
        "sensor init, a config with nothing fitted); default: config.toml of the predict "
        "folder holding the image, else the library's",
    )
    iv.add_argument(
        "--reference",
        nargs="+",
        default=None,
        metavar="FRAME",
        help="frames of the sensor at rest in the image's light: rgb/mono, their light "
        "(glare, ghosts, stray light) is taken off the image; phase, the six steps of the "
        "rest (or 6n) give the sheet's residual retarder, put into the model",
    )
    residual_steps_option(iv)
    iv.add_argument(
        "--refine",
        choices=("fem",),
        default=None,
        help="fem: after the library fit, full-FEM defect correction rounds until the loads "
        "move by less than their 1-sigma (one FEM solve each, minutes)",
    )
    iv.add_argument(
        "--max-seconds",
        type=nonnegative,
        default=DEFAULT_MAX_SECONDS,
        help="time budget (s): the fit stops at the end of the stage that spends it and "
        "writes that stage's answer, every indenter flagged, exit status 1 "
        f"(default {DEFAULT_MAX_SECONDS:g})",
    )
    iv.add_argument("--quiet", action="store_true", help="no stage lines")
    iv.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    s = run_invert(
        args.images,
        args.library,
        Path(args.out),
        method=args.method,
        pixel_mm=args.pixel_mm,
        origin_px=args.origin_px,
        sensor=args.sensor,
        reference=args.reference,
        residual_steps=args.residual_steps,
        refine=args.refine,
        max_seconds=args.max_seconds,
        progress=not args.quiet,
    )
    for w in s["warnings"]:
        print(f"fringekit invert: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"fringekit invert: {s['n_indenters']} indenter(s) -> {args.out}/loads.csv")
    return 1 if s["stopped_after"] else 0  # cut short: the computation did not finish
