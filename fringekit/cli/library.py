"""The ``library`` and ``invert`` subcommands of ``fringekit`` (parsers and runs)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fringekit.cli.options import at_least_one, at_least_zero, finite, nonnegative, positive

__all__ = ["add_invert", "add_library", "cmd_invert", "cmd_library"]


def add_library(sub) -> None:
    lb = sub.add_parser("library", help="response libraries for invert and fast predictions")
    acts = lb.add_subparsers(dest="action", required=True)
    b = acts.add_parser("build", help="FEM solutions over a grid of loads for a sensor")
    b.add_argument("config", nargs="?", default=None,
                   help="TOML config or built-in case: the sensor (default reference)")  # fmt: skip
    b.add_argument("--out", required=True, help="library folder (resumed when it exists)")
    b.add_argument("--set", action="append", metavar="TABLE.KEY=VALUE",
                   help="override one config value (repeatable)")  # fmt: skip
    b.add_argument("--diameter-mm", nargs="+", type=positive, default=None,
                   help="indenter diameters (default: the config's)")  # fmt: skip
    b.add_argument("--load-N", nargs="+", type=positive, default=None,
                   help="normal loads of the grid (default 0.25..12 N, 14 values)")  # fmt: skip
    b.add_argument("--shear-ratio", nargs="+", type=nonnegative, default=None,
                   help="tangential/normal ratios from 0 (default 0 0.2 0.4 0.6 0.8)")  # fmt: skip
    b.add_argument("--slabs", type=at_least_one, default=16, help="slabs per stored ray")
    b.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    b.add_argument("--workers", type=at_least_zero, default=None,
                   help="local single-threaded worker processes, one diameter's chain "
                        "each (default: one diameter is solved in this process on every "
                        "core; 0: always in this process)")  # fmt: skip
    b.add_argument("--cache-dir", default=None, help="mesh and solution cache root")
    b.add_argument("--quiet", action="store_true")
    b.set_defaults(func=cmd_library)


def add_invert(sub) -> None:
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
    iv.add_argument("--pixel-mm", type=positive, default=None,
                    help="pixel pitch on the sheet (mm), required")  # fmt: skip
    iv.add_argument(
        "--origin-px",
        nargs=2,
        type=finite,
        metavar=("ROW", "COL"),
        default=None,
        help="image pixel of the sensor origin (default: the image centre)",
    )
    iv.add_argument("--sensor", default=None,
                    help="the image's sensor: a config file or a predict output folder "
                    "(default: config.toml of the predict folder holding the image)")  # fmt: skip
    iv.add_argument("--quiet", action="store_true")
    iv.set_defaults(func=cmd_invert)


def cmd_library(args: argparse.Namespace) -> int:
    from fringekit.cli.commands import fringekit_version, overrides
    from fringekit.library.build import DEFAULT_LOADS_N, DEFAULT_RATIOS, build_library

    cfg = overrides(args.config, args.set or [])
    m = build_library(
        cfg, Path(args.out), diameters=args.diameter_mm, loads=args.load_N or DEFAULT_LOADS_N,
        ratios=args.shear_ratio if args.shear_ratio is not None else DEFAULT_RATIOS,
        n_slabs=int(args.slabs), scheduler=args.scheduler, workers=args.workers,
        cache_dir=args.cache_dir, progress=not args.quiet, inputs=[args.config],
    ).manifest  # fmt: skip
    if not args.quiet:
        g = m["grid"]
        print(f"fringekit {fringekit_version()} - library {args.out}: "
              f"{len(g['diameters_mm'])} diameter(s) x {len(g['load_N'])} loads x "
              f"{len(g['shear_ratio'])} ratios, solved in {m['build_s']:.1f} s")  # fmt: skip
    return 0


def cmd_invert(args: argparse.Namespace) -> int:
    from fringekit.invert.run import run_invert

    s = run_invert(args.images, args.library, Path(args.out), method=args.method,
                   pixel_mm=args.pixel_mm, origin_px=args.origin_px, sensor=args.sensor,
                   progress=not args.quiet)  # fmt: skip
    for w in s["warnings"]:
        print(f"fringekit invert: warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(f"fringekit invert: {s['n_indenters']} indenter(s) -> {args.out}/loads.csv")
    return 0
