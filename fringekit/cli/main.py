"""The ``fringekit`` command.

The application layer's entry point. Subcommands:

- ``predict [CONFIG]``: config (a TOML file or a built-in case name; none = the reference
  case) -> mesh -> contact solution -> optics -> an output folder (:mod:`fringekit.cli.predict`);
- ``config show [CONFIG]``: the effective configuration with defaults and units;
- ``mesh [CONFIG]``: the mesh ``predict`` would use for a config, summarised and exported.

- ``analyze IMAGES...``: fringe order maps, profiles and figures from six phase-stepped
  images, one RGB or one monochrome image;
- ``compare PREDICTION MEASUREMENT``: registration, residual maps and statistics.

- ``calibrate [CONFIG]``: load-to-fringe relations over a load path, or ``--disc`` the
  fringe value from a disc; ``estimate MAPS --calibration FILE``: the load back.
- ``sweep SWEEP.toml``: a grid or list of cases on Dask, resumable.
- ``library build [CONFIG]``: a sensor's response library;
  ``invert IMAGE... --library DIR``: every indenter's position and load;
  ``track SOURCE --library DIR``: every contact's load through a video or camera stream;
  ``sensor calibrate --library DIR --reference REST --known KNOWN.csv``: the library
  calibrated to a physical sensor (``--sensor`` of invert and track).

One module per subcommand (``fringekit.cli.<name>``) holds its parser and its handler;
each handler reads its inputs, runs the computation (the API, or a run function beside it
that writes as it goes: sweep, calibrate, compare, estimate, mesh, predict --library) and
prints a summary.
Exit status: 0 success, 2 a user error (bad config or input; one line, no traceback),
1 a run that failed (the solver did not reach a load; what converged is written).
"""

from __future__ import annotations

import logging
import sys

from fringekit import __version__
from fringekit.cli import (
    analyze,
    calibrate,
    compare,
    config,
    estimate,
    invert,
    library,
    mesh,
    predict,
    sensor,
    sweep,
    track,
)
from fringekit.cli.options import Parser
from fringekit.errors import ComputeError, FringekitError, Interrupted
from fringekit.output.folders import os_error_message

__all__ = ["main"]

#: The subcommands in the order ``fringekit --help`` lists them; each module holds its
#: parser (``add_parser``) and its handler (``run``).
SUBCOMMANDS = (
    predict,
    config,
    analyze,
    compare,
    calibrate,
    estimate,
    sweep,
    mesh,
    library,
    invert,
    track,
    sensor,
)


def _parser() -> Parser:
    p = Parser(
        prog="fringekit",
        description="Contact stress and photoelastic fringe prediction for photoelastic "
        "tactile sensors.",
    )
    p.add_argument("--version", action="version", version=f"fringekit {__version__}")
    sub = p.add_subparsers(dest="command")
    for command in SUBCOMMANDS:
        command.add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fringekit`` console script; returns the exit status."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a bad option (one line, exit 2)
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help()
        return 0
    logging.basicConfig(
        level=logging.WARNING if getattr(args, "quiet", False) else logging.INFO,
        format="%(name)s: %(message)s",
    )
    for noisy in ("distributed", "tornado", "bokeh"):  # Dask's cluster chatter
        logging.getLogger(noisy).setLevel(logging.WARNING)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print(f"fringekit {args.command}: interrupted by the user", file=sys.stderr)
        return 130
    except Interrupted as exc:
        print(f"fringekit {args.command}: {exc}", file=sys.stderr)
        return 130
    except ComputeError as exc:
        print(f"fringekit {args.command}: failed: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # a disk or a permission: said without errno or hidden paths
        print(f"fringekit {args.command}: error: {os_error_message(exc)}", file=sys.stderr)
        return 2
    except (FringekitError, ValueError) as exc:
        print(f"fringekit {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
