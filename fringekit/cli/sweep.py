"""``fringekit sweep``: a grid or list of cases, in parallel on Dask and resumable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fringekit.cli.options import (
    at_least_one,
)
from fringekit.sweep.run import load_sweep, run_sweep

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    sw = sub.add_parser("sweep", help="run a grid or list of cases in parallel (Dask)")
    sw.add_argument("sweep", help="sweep TOML file (base, [set], [grid] or [[case]])")
    sw.add_argument("--out", default=None, help="output folder (default fringekit-out/<name>)")
    sw.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    sw.add_argument("--workers", type=at_least_one, default=None, help="local worker processes")
    sw.add_argument("--cache-dir", default=None)
    sw.add_argument("--quiet", action="store_true")
    sw.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    sweep = load_sweep(args.sweep)
    out = Path(args.out) if args.out else Path("fringekit-out") / sweep["name"]
    res = run_sweep(
        sweep,
        out,
        scheduler=args.scheduler,
        workers=args.workers,
        cache_dir=args.cache_dir,
        progress=not args.quiet,
        inputs=[args.sweep],
    )
    if not args.quiet:
        print(
            f"fringekit sweep {sweep['name']}: {res['cases']} cases ({res['run']} run, "
            f"{res['skipped']} already finished, {res['failed']} failed) in {res['time_s']:.1f} s;"
            f" table {res['table']}"
        )
    if res["failed"]:  # said even with --quiet: the exit status alone does not say why
        sys.stderr.write(
            f"fringekit sweep {sweep['name']}: {res['failed']} of {res['cases']} cases failed; "
            f"each one's error is in the error column of {res['table']}\n"
        )
    return 1 if res["failed"] else 0
