"""``fringekit predict``: a config -> mesh, contact solution, fringe maps and images in a
folder (or, with ``--library``, synthesised from a response library).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from fringekit import __version__
from fringekit.cli.options import (
    overrides,
    run_options,
)
from fringekit.errors import ConfigError
from fringekit.prediction.from_library import run_library_predict
from fringekit.prediction.pipeline import run_predict

__all__ = ["UNRESOLVED_EDGE", "add_parser", "run"]

#: Said after a contact radius the edge fit could not give (the contact area's circle).
UNRESOLVED_EDGE = (
    "(from the contact area: this mesh does not resolve the contact's edge, expect it a few "
    "% small; lower mesh.h_contact_mm)"
)


def add_parser(sub) -> None:
    pr = sub.add_parser(
        "predict",
        help="mesh, solve and render fringes for a config (default: the reference case)",
    )
    pr.add_argument(
        "config",
        nargs="?",
        default=None,
        help="TOML config file or built-in case (reference, shear, small); default reference",
    )
    run_options(pr)
    pr.add_argument(
        "--library",
        default=None,
        help="synthesise from a response library instead of solving (seconds; "
        "final load state only)",
    )
    pr.add_argument(
        "--sensor",
        default=None,
        help="(with --library) a calibrated sensor file (fringekit sensor calibrate): the "
        "library read as its sheet, and state_01/camera.png the frame its camera records "
        "(a phase sensor's six steps: camera_step1.png to camera_step6.png)",
    )
    pr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cfg = overrides(args.config, args.set or [])
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    t0 = time.perf_counter()
    if args.library:
        run_library_predict(
            cfg,
            args.library,
            out,
            sensor=args.sensor,
            progress=not args.quiet,
            inputs=[args.config],
        )
        return 0
    if args.sensor is not None:
        raise ConfigError(
            f"--sensor {args.sensor}: a calibrated sensor is used with --library only"
        )
    summary = run_predict(
        cfg,
        out,
        cache_dir=args.cache_dir,
        use_cache=not args.no_cache,
        progress=not args.quiet,
        inputs=[args.config],
    )
    if not args.quiet:
        took = time.perf_counter() - t0
        print(f"fringekit {__version__} - {cfg['case']}: done in {took:.1f} s")
        for j, ind in enumerate(summary["indenters"]):
            f = ", ".join(f"{v:.3g}" for v in ind["force_N"])
            sd = ind.get("contact_radius_sd_mm")
            # no sd: the edge fit failed and the contact area's circle is given, 3-5 %
            # small on the 0.6 mm facets measured (docs/validation.md): flagged
            pm = f" +- {sd:.4f} mm" if sd is not None else f" mm {UNRESOLVED_EDGE}"
            print(
                f"  indenter {j}: force [{f}] N, depth {ind['depth_mm']:.4f} mm, "
                f"contact radius {ind['contact_radius_mm']:.4f}{pm}"
            )
        print(f"  max fringe order {summary['max_fringe_order']:.2f} (contact zone masked)")
        print(f"  results in {out}/ (summary.json, state_*/solution.vtu, images, figures)")
    return 0
