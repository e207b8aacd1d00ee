"""``fringekit sensor calibrate``: a library calibrated to one physical sensor
(:func:`fringekit.calibrate_sensor`); ``invert`` and ``track`` take the file it writes
as ``--sensor``."""

from __future__ import annotations

import argparse
import sys

from fringekit.cli.options import PIXEL_MM, finite, in_range
from fringekit.sensor.calibrate import calibrate_sensor, check_out

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    se = sub.add_parser("sensor", help="calibrate a library to a physical sensor")
    acts = se.add_subparsers(dest="action", required=True)
    c = acts.add_parser(
        "calibrate",
        help="modulus and fringe-value scales, camera response, light, rest frame and "
        "geometry from rest frames and frames of known loads",
    )
    c.add_argument("--library", required=True, help="library folder (fringekit library build)")
    c.add_argument(
        "--reference", nargs="+", required=True, help="frame(s) of the sensor at rest, same light"
    )
    c.add_argument(
        "--known",
        required=True,
        help="KNOWN.csv: image,x_mm,y_mm,Fx_N,Fy_N,Fz_N per contact (blank x_mm,y_mm: fitted)",
    )
    c.add_argument("--out", required=True, help="the sensor file to write (.json; a .png beside)")
    c.add_argument(
        "--pixel-mm",
        type=in_range(PIXEL_MM),
        required=True,
        help="nominal pixel pitch on the sheet (mm); fitted when two or more positions are known",
    )
    c.add_argument(
        "--origin-px",
        nargs=2,
        type=finite,
        metavar=("ROW", "COL"),
        default=None,
        help="nominal image pixel of the sheet's origin (default: the image centre)",
    )
    c.add_argument("--dark", nargs="+", default=None, help="frame(s) with the light off")
    c.add_argument(
        "--method",
        choices=("rgb", "mono"),
        default=None,
        help="default: rgb for colour frames, mono for grey ones",
    )
    c.add_argument("--quiet", action="store_true", help="no step lines")
    c.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = check_out(args.out)
    cal = calibrate_sensor(
        args.library,
        args.reference,
        args.known,
        pixel_mm=args.pixel_mm,
        origin_px=args.origin_px,
        dark=args.dark,
        method=args.method,
        progress=not args.quiet,
    )
    path = cal.write(out)
    for w in cal.sensor.report["warnings"]:
        print(f"fringekit sensor calibrate: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"fringekit sensor calibrate: wrote {path} and {path.with_suffix('.png').name}")
    return 1 if cal.sensor.report["warnings"] else 0
