"""``fringekit library build``: a sensor's response library (:func:`fringekit.build_library`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from fringekit import __version__
from fringekit.cli.options import (
    SHEAR_RATIO,
    at_least_one,
    at_least_zero,
    in_range,
    overrides,
)
from fringekit.library.build import DEFAULT_LOADS_N, DEFAULT_RATIOS, build_library

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    lb = sub.add_parser("library", help="response libraries for invert and fast predictions")
    acts = lb.add_subparsers(dest="action", required=True)
    b = acts.add_parser("build", help="FEM solutions over a grid of loads for a sensor")
    b.add_argument(
        "config",
        nargs="?",
        default=None,
        help="TOML config or built-in case: the sensor (default reference)",
    )
    b.add_argument("--out", required=True, help="library folder (resumed when it exists)")
    b.add_argument(
        "--set",
        action="append",
        metavar="TABLE.KEY=VALUE",
        help="override one config value (repeatable)",
    )
    b.add_argument(
        "--diameter-mm",
        nargs="+",
        type=in_range("indenter.diameter_mm"),
        default=None,
        help="indenter diameters (default: the config's)",
    )
    b.add_argument(
        "--load-N",
        nargs="+",
        type=in_range("indenter.load_N", positive=True),
        default=None,
        help="normal loads of the grid (default 0.25..12 N, 14 values)",
    )
    b.add_argument(
        "--shear-ratio",
        nargs="+",
        type=in_range(SHEAR_RATIO),
        default=None,
        help="tangential/normal ratios from 0 (default 0 0.2 0.4 0.6 0.8)",
    )
    b.add_argument("--slabs", type=at_least_one, default=16, help="slabs per stored ray")
    b.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    b.add_argument(
        "--workers",
        type=at_least_zero,
        default=None,
        help="local single-threaded worker processes, one diameter's chain "
        "each (default: one diameter is solved in this process on every "
        "core; 0: always in this process)",
    )
    b.add_argument("--cache-dir", default=None, help="mesh and solution cache root")
    b.add_argument(
        "--no-cache", action="store_true", help="solve every branch (none from the cache)"
    )
    b.add_argument("--quiet", action="store_true")
    b.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = overrides(args.config, args.set or [])
    m = build_library(
        cfg,
        Path(args.out),
        diameters=args.diameter_mm,
        loads=args.load_N or DEFAULT_LOADS_N,
        ratios=args.shear_ratio if args.shear_ratio is not None else DEFAULT_RATIOS,
        n_slabs=int(args.slabs),
        scheduler=args.scheduler,
        workers=args.workers,
        cache_dir=args.cache_dir,
        use_cache=not args.no_cache,
        progress=not args.quiet,
        inputs=[args.config],
    ).manifest
    if not args.quiet:
        g = m["grid"]
        print(
            f"fringekit {__version__} - library {args.out}: "
            f"{len(g['diameters_mm'])} diameter(s) x {len(g['load_N'])} loads x "
            f"{len(g['shear_ratio'])} ratios, solved in {m['build_s']:.1f} s"
        )
    return 0
