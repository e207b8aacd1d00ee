"""``fringekit config show``: the effective configuration with its defaults, units and help."""

from __future__ import annotations

import argparse
import sys

from fringekit.cli.options import (
    overrides,
)
from fringekit.config.files import to_toml

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    cf = sub.add_parser("config", help="configuration tools")
    cfs = cf.add_subparsers(dest="action", required=True)
    show = cfs.add_parser("show", help="print the effective config with defaults and units")
    show.add_argument("config", nargs="?", default=None)
    show.add_argument("--set", action="append", metavar="TABLE.KEY=VALUE")
    show.set_defaults(func=run, quiet=True)


def run(args: argparse.Namespace) -> int:
    cfg = overrides(args.config, args.set or [])
    sys.stdout.write(to_toml(cfg))
    return 0
