"""``fringekit sensor calibrate``: a library calibrated to one physical sensor
(:func:`fringekit.calibrate_sensor`); ``fringekit sensor init``: the sensor file of a
config with nothing fitted. ``invert``, ``track`` and ``predict --library`` take either
file as ``--sensor``."""

from __future__ import annotations

import argparse
import sys

from fringekit.cli.options import PIXEL_MM, in_range, origin_px_option, overrides
from fringekit.errors import ConfigError
from fringekit.library.calibrated import CalibratedSensor
from fringekit.library.store import check_sensor, load_library
from fringekit.sensor.calibrate import calibrate_sensor, check_out

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    se = sub.add_parser("sensor", help="calibrate a library to a physical sensor")
    acts = se.add_subparsers(dest="action", required=True)
    c = acts.add_parser(
        "calibrate",
        help="modulus and fringe-value scales, camera response, light, rest frame (phase: "
        "residual retarder) and geometry from rest frames and frames of known loads",
    )
    c.add_argument("--library", required=True, help="library folder (fringekit library build)")
    c.add_argument(
        "--reference",
        nargs="+",
        default=None,
        help="frame(s) of the sensor at rest, same light (phase: the six steps, or sets of six)",
    )
    c.add_argument(
        "--residual-steps",
        nargs="+",
        default=None,
        help="(mono, instead of --reference) the six phase steps of the sensor at rest: the "
        "sheet's residual retarder, modelled instead of a rest frame subtracted",
    )
    c.add_argument(
        "--known",
        required=True,
        help="KNOWN.csv: image,x_mm,y_mm,Fx_N,Fy_N,Fz_N per contact (blank x_mm,y_mm: fitted; "
        "phase: image is the six steps' files joined by ';')",
    )
    c.add_argument("--out", required=True, help="the sensor file to write (.json; a .png beside)")
    c.add_argument(
        "--pixel-mm",
        type=in_range(PIXEL_MM),
        required=True,
        help="nominal pixel pitch on the sheet (mm); fitted when two or more positions are known",
    )
    origin_px_option(
        c,
        "nominal image pixel of the sheet's origin (default: the image centre)",
    )
    c.add_argument("--dark", nargs="+", default=None, help="frame(s) with the light off")
    c.add_argument(
        "--method",
        choices=("rgb", "mono", "phase"),
        default=None,
        help="default: rgb for colour frames, mono for grey ones (phase: six-step frames)",
    )
    c.add_argument("--quiet", action="store_true", help="no step lines")
    c.set_defaults(func=run)
    i = acts.add_parser("init", help="a sensor file of a config with nothing fitted (for --sensor)")
    i.add_argument("config", help="TOML config or built-in case: the sensor")
    i.add_argument("--library", required=True, help="library folder the file is used with")
    i.add_argument(
        "--shape",
        nargs=2,
        type=int,
        metavar=("ROWS", "COLS"),
        required=True,
        help="image size (px)",
    )
    i.add_argument(
        "--pixel-mm", type=in_range(PIXEL_MM), required=True, help="pixel pitch on the sheet (mm)"
    )
    origin_px_option(
        i,
        "image pixel of the sheet's origin (default: the image centre)",
    )
    i.add_argument(
        "--method",
        choices=("rgb", "mono", "phase"),
        default="rgb",
        help="the images' method (default rgb)",
    )
    i.add_argument("--out", required=True, help="the sensor file to write (.json)")
    i.set_defaults(func=run_init)


def run_init(args: argparse.Namespace) -> int:
    out = check_out(args.out)
    lib = load_library(args.library)
    cfg = overrides(args.config, [])
    check_sensor(lib, cfg, args.config)
    if min(args.shape) < 2:
        raise ConfigError(f"--shape {args.shape[0]} {args.shape[1]}: give at least 2 x 2 px")
    s = CalibratedSensor.uncalibrated(
        cfg, lib, args.shape, args.method, args.pixel_mm, args.origin_px
    )
    s.check(lib)
    s.grid_options(None, None)
    print(f"fringekit sensor init: wrote {s.save(out)}")
    return 0


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
        residual_steps=args.residual_steps,
        progress=not args.quiet,
    )
    path = cal.write(out)
    for w in cal.sensor.report["warnings"]:
        print(f"fringekit sensor calibrate: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"fringekit sensor calibrate: wrote {path} and {path.with_suffix('.png').name}")
    return 1 if cal.sensor.report["warnings"] else 0
