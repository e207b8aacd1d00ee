"""The ``fringekit`` command.

The application layer's entry point. Subcommands:

- ``predict [CONFIG]``: config (a TOML file or a built-in case name; none = the reference
  case) -> mesh -> contact solution -> optics -> an output folder (fringekit.pipeline);
- ``config show [CONFIG]``: the effective configuration with defaults and units;
- ``mesh [CONFIG]``: the mesh ``predict`` would use for a config, summarised and exported.

- ``analyze IMAGES...``: fringe order maps, profiles and figures from six phase-stepped
  images or one RGB image (fringekit.analyze);
- ``compare PREDICTION MEASUREMENT``: registration, residual maps and statistics.

- ``calibrate [CONFIG]``: load-to-fringe relations over a load path, or ``--disc`` the
  fringe value from a disc; ``estimate MAPS --calibration FILE``: the load back.
- ``sweep SWEEP.toml``: a grid or list of cases on Dask, resumable (fringekit.sweep).
- ``library build [CONFIG]``: a sensor's response library (fringekit.library_build);
  ``invert IMAGE... --library DIR``: every indenter's position and load (fringekit.invert).
Exit status: 0 success, 2 a user error (bad config or input; one line, no traceback),
1 a run that failed (the solver did not reach a load; what converged is written).
"""

from __future__ import annotations

import argparse
import logging
import sys

from fringekit.cli.commands import (
    MESH_OPTIONS,
    cmd_analyze,
    cmd_calibrate,
    cmd_compare,
    cmd_config,
    cmd_estimate,
    cmd_mesh,
    cmd_predict,
    cmd_sweep,
    fringekit_version,
)
from fringekit.cli.library import add_invert, add_library
from fringekit.cli.options import (
    Parser,
    at_least_one,
    finite,
    fraction,
    nonnegative,
    pixel,
    positive,
)
from fringekit.errors import ComputeError, FringekitError, Interrupted

__all__ = ["main"]


def _run_options(p: argparse.ArgumentParser) -> None:
    """Options of the commands that mesh and solve a config (predict, calibrate)."""
    p.add_argument("--out", default=None, help="output folder (default fringekit-out/<case>)")
    p.add_argument(
        "--set", action="append", metavar="TABLE.KEY=VALUE",
        help="override one config value, e.g. --set optics.pixels=128 (repeatable)",
    )  # fmt: skip
    p.add_argument("--cache-dir", default=None, help="mesh and solution cache root")
    p.add_argument("--no-cache", action="store_true", help="re-mesh and re-solve")
    p.add_argument("--quiet", action="store_true", help="no progress output")


def _add_predict(sub) -> None:
    pr = sub.add_parser(
        "predict",
        help="mesh, solve and render fringes for a config (default: the reference case)",
    )
    pr.add_argument(
        "config", nargs="?", default=None,
        help="TOML config file or built-in case (reference, shear); default reference",
    )  # fmt: skip
    _run_options(pr)
    pr.add_argument("--library", default=None,
                    help="synthesise from a response library instead of solving (seconds; "
                    "final load state only)")  # fmt: skip
    pr.set_defaults(func=cmd_predict)


def _add_config(sub) -> None:
    cf = sub.add_parser("config", help="configuration tools")
    cfs = cf.add_subparsers(dest="action", required=True)
    show = cfs.add_parser("show", help="print the effective config with defaults and units")
    show.add_argument("config", nargs="?", default=None)
    show.add_argument("--set", action="append", metavar="TABLE.KEY=VALUE")
    show.set_defaults(func=cmd_config, quiet=True)


def _mono_options(g) -> None:
    g.add_argument(
        "--field",
        choices=("dark", "bright"),
        default="dark",
        help="(mono) polariscope field: whole orders are dark fringes in dark "
        "field, bright ones in bright field",
    )
    g.add_argument(
        "--flat",
        default=None,
        help="(mono) flat-field image: the light without the specimen's "
        "retardation (bright field, unloaded); default: the fringe envelope",
    )
    g.add_argument(
        "--smooth-px",
        type=nonnegative,
        default=0.5,
        help="(mono) Gaussian smoothing before normalising (px)",
    )


def _add_analyze(sub) -> None:
    an = sub.add_parser(
        "analyze", help="fringe order from six phase-stepped, one RGB or one monochrome image"
    )
    an.add_argument(
        "images",
        nargs="+",
        help="six step images (or a 6-page TIFF), one RGB or one monochrome image",
    )
    an.add_argument(
        "--method",
        choices=("phase", "rgb", "mono"),
        default=None,
        help="default: rgb for one colour PNG/JPEG, mono for one grey image, phase otherwise",
    )
    _mono_options(an.add_argument_group("mono: one monochrome photograph"))
    an.add_argument("--points", default=None, metavar="FILE.csv",
                    help="CSV with header row,col or x_mm,y_mm: writes points.csv with "
                    "row,col,x_mm,y_mm,order,order_sd,reliable")  # fmt: skip
    an.add_argument("--out", default=None, help="output folder (default fringekit-out/analysis)")
    an.add_argument("--dark", default=None, help="dark frame subtracted from every image")
    an.add_argument("--roi-circle", nargs=3, type=finite, metavar=("ROW", "COL", "R"))
    an.add_argument("--roi-rect", nargs=4, type=finite, metavar=("R0", "C0", "R1", "C1"),
                    help="rectangular region of interest (corners, px)")  # fmt: skip
    an.add_argument("--roi-polygon", nargs="+", type=pixel, metavar="ROW,COL",
                    help="polygonal region of interest (3 or more vertices, px)")  # fmt: skip
    an.add_argument("--exclude-polygon", nargs="+", type=pixel, action="append",
                    metavar="ROW,COL", help="masked polygon (crack, label, load point); "
                    "two vertices mask a line 3 px wide")  # fmt: skip
    an.add_argument(
        "--exclude-circle", nargs=3, type=finite, action="append", metavar=("ROW", "COL", "R"),
        help="masked circle, e.g. the indenter",
    )  # fmt: skip
    an.add_argument("--pixel-mm", type=positive, default=None, help="pixel pitch on the sheet (mm)")
    an.add_argument("--roi-disc", type=positive, default=None, metavar="DIAMETER_MM",
                    help="find the circular specimen of this diameter in the (first) image: "
                    "the region of interest, the pixel size and the origin")  # fmt: skip
    an.add_argument("--anchor-order", type=finite, default=0.0,
                    help="(phase, mono) fringe order of the image border ring")  # fmt: skip
    an.add_argument("--min-modulation", type=fraction, default=0.1)
    an.add_argument("--reference", nargs="+", default=None, metavar="IMAGE",
                    help="(phase) the six images (or a 6-page TIFF) of the unloaded specimen: "
                    "their residual retardation is subtracted vectorially")  # fmt: skip
    an.add_argument("--fold", choices=("count", "isoclinic"), default="count",
                    help="(phase) resolve the folded phase by counting fringes from the "
                    "anchor, or by the isoclinic's continuity; the other checks it")  # fmt: skip
    an.add_argument("--calibration", default=None, help="(rgb) table CSV: order,R,G,B")
    an.add_argument("--light", default="LED", help="(rgb) light of the synthetic chart")
    an.add_argument("--camera", default="CIE1931", help="(rgb) camera of the synthetic chart")
    an.add_argument("--max-order", type=positive, default=4.0, help="(rgb) chart range")
    an.add_argument("--exposure", type=positive, default=0.9,
                    help="(rgb) chart exposure, as in predict's optics.exposure")  # fmt: skip
    an.add_argument("--seed", nargs=3, type=finite, action="append", metavar=("ROW", "COL", "N"),
                    help="(rgb) pixel of known order: refined search from it")  # fmt: skip
    an.add_argument("--window", type=positive, default=0.25, help="(rgb) refined window (fringe)")
    an.add_argument("--line", nargs=4, type=finite, metavar=("R0", "C0", "R1", "C1"))
    an.add_argument(
        "--order-at",
        nargs=3,
        type=finite,
        action="append",
        metavar=("ROW", "COL", "N"),
        default=None,
        help="(phase, mono) a pixel of known fringe order N, the lowest order about it (it "
        "also fixes the sign), instead of the image border at --anchor-order; repeat it "
        "for every low point the count cannot reach by counting up (a disc's two ends)",
    )
    an.add_argument(
        "--origin-px",
        nargs=2,
        type=finite,
        metavar=("ROW", "COL"),
        default=None,
        help="pixel of the sensor origin: figures and profile.csv use x right, "
        "y up in mm about it (default: the image centre)",
    )
    an.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 when less than half of the region of interest is reliable",
    )
    an.add_argument("--f-sigma-N-per-m", type=positive, default=None)
    an.add_argument("--thickness-mm", type=positive, default=None)
    an.add_argument("--quiet", action="store_true")
    an.set_defaults(func=cmd_analyze)


def _add_compare(sub) -> None:
    co = sub.add_parser("compare", help="prediction vs measurement: residuals and figures")
    co.add_argument("prediction", help="predict output folder or maps.npz")
    co.add_argument("measurement", help="analyze output folder or maps.npz")
    co.add_argument("--out", default=None, help="output folder (default fringekit-out/compare)")
    co.add_argument("--predicted-pixel-mm", type=positive, default=None)
    co.add_argument("--measured-pixel-mm", type=positive, default=None)
    co.add_argument("--centre-measured", nargs=2, type=finite, metavar=("ROW", "COL"))
    co.add_argument("--rotation-deg", type=finite, default=0.0)
    co.add_argument("--quiet", action="store_true")
    co.set_defaults(func=cmd_compare)


def _add_calibrate(sub) -> None:
    ca = sub.add_parser(
        "calibrate",
        help="load-to-fringe relations from a load path, or the fringe value from a disc",
    )
    ca.add_argument(
        "config", nargs="?", default=None,
        help="config with a load path (default: the reference case at 1..10 N)",
    )  # fmt: skip
    _run_options(ca)
    ca.add_argument(
        "--disc", nargs="+", default=None, metavar="IMAGE_OR_MAPS",
        help="photographs of a disc in diametral compression (monochromatic light, circular "
        "polariscope, transmission), or one fringe-order map (maps.npz / analyze folder): "
        "fit f_sigma",
    )  # fmt: skip
    ca.add_argument("--load-N", nargs="+", type=positive, default=None,
                    help="(disc) diametral load of each photograph (N)")  # fmt: skip
    ca.add_argument("--diameter-mm", type=positive, default=None, help="(disc) diameter")
    ca.add_argument("--thickness-mm", type=positive, default=None, help="(disc) thickness")
    ca.add_argument("--wavelength-nm", type=positive, default=None,
                    help="(disc) wavelength of the light, recorded with f_sigma")  # fmt: skip
    ca.add_argument("--reference", default=None, metavar="IMAGE",
                    help="(disc) the unloaded disc, same light and exposure: fixes the "
                    "residual order")  # fmt: skip
    ca.add_argument("--field", choices=("dark", "bright"), default="dark",
                    help="(disc) polariscope field of the photographs")  # fmt: skip
    ca.add_argument("--dark", default=None, help="(disc) dark frame subtracted from every photo")
    ca.add_argument("--pixel-mm", type=positive, default=None)
    ca.add_argument("--centre", nargs=2, type=finite, metavar=("ROW", "COL"))
    ca.add_argument("--radius-px", type=positive, default=None,
                    help="(disc) disc radius in the photographs (px)")  # fmt: skip
    ca.set_defaults(func=cmd_calibrate)


def _add_estimate(sub) -> None:
    es = sub.add_parser("estimate", help="load (and shear) from a fringe-order map")
    es.add_argument("maps", help="maps.npz, or a fringekit analyze / predict output folder")
    es.add_argument("--calibration", required=True, help="calibration.json from calibrate")
    es.add_argument("--pixel-mm", type=positive, default=None)
    es.add_argument("--centre", nargs=2, type=finite, metavar=("ROW", "COL"),
                    help="indenter axis in pixels (default: stored in the maps)")  # fmt: skip
    es.add_argument("--out", default=None)
    es.add_argument("--quiet", action="store_true")
    es.set_defaults(func=cmd_estimate)


def _add_sweep(sub) -> None:
    sw = sub.add_parser("sweep", help="run a grid or list of cases in parallel (Dask)")
    sw.add_argument("sweep", help="sweep TOML file (base, [set], [grid] or [[case]])")
    sw.add_argument("--out", default=None, help="output folder (default fringekit-out/<name>)")
    sw.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    sw.add_argument("--workers", type=at_least_one, default=None, help="local worker processes")
    sw.add_argument("--cache-dir", default=None)
    sw.add_argument("--quiet", action="store_true")
    sw.set_defaults(func=cmd_sweep)


def _add_mesh(sub) -> None:
    m = sub.add_parser(
        "mesh", help="mesh a config (default: the reference case) as predict does; export VTU"
    )
    m.add_argument("config", nargs="?", default=None,
                   help="TOML config file or built-in case; default reference")  # fmt: skip
    m.add_argument("--set", action="append", metavar="TABLE.KEY=VALUE",
                   help="override one config value (repeatable)")  # fmt: skip
    m.add_argument("--symmetry", choices=("auto", "full", "half", "quarter"), default=None,
                   help="sets mesh.symmetry")  # fmt: skip
    for opt, keys in MESH_OPTIONS.items():
        if opt != "symmetry":
            flag = "--" + opt.replace("_", "-")
            m.add_argument(flag, type=finite, default=None, help="sets " + " and ".join(keys))
    m.add_argument("--out", default=None, help="output folder (default fringekit-out/<case>)")
    m.add_argument("--cache-dir", default=None, help="mesh cache root")
    m.add_argument("--no-cache", action="store_true", help="always regenerate the mesh")
    m.add_argument("--quiet", action="store_true")
    m.set_defaults(func=cmd_mesh)


def _parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="fringekit",
        description="Contact stress and photoelastic fringe prediction for photoelastic "
        "tactile sensors.",
    )
    p.add_argument("--version", action="version", version=f"fringekit {fringekit_version()}")
    sub = p.add_subparsers(dest="command")
    for add in (_add_predict, _add_config, _add_analyze, _add_compare, _add_calibrate,
                _add_estimate, _add_sweep, _add_mesh, add_library, add_invert):  # fmt: skip
        add(sub)
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
    except (FringekitError, ValueError, OSError) as exc:
        print(f"fringekit {args.command}: error: {exc}", file=sys.stderr)
        return 2

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
