"""``fringekit calibrate``: load-to-fringe relations over a load path, or (``--disc``) the
material fringe value from disc photographs or a fringe-order map.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from fringekit.calibrate.disc import is_photo, run_disc_photos
from fringekit.calibrate.estimate import run_disc
from fringekit.calibrate.load import default_calibration_config, run_calibrate
from fringekit.cli.options import (
    DISC_DIAMETER_MM,
    PIXEL_MM,
    RADIUS_PX,
    finite,
    in_range,
    overrides,
    run_options,
)
from fringekit.errors import InputError
from fringekit.output.folders import claim_output

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    ca = sub.add_parser(
        "calibrate",
        help="load-to-fringe relations from a load path, or the fringe value from a disc",
    )
    ca.add_argument(
        "config",
        nargs="?",
        default=None,
        help="config with a load path (default: the reference case at 1..10 N)",
    )
    run_options(ca)
    ca.add_argument(
        "--disc",
        nargs="+",
        default=None,
        metavar="IMAGE_OR_MAPS",
        help="photographs of a disc in diametral compression (monochromatic light, circular "
        "polariscope, transmission), or one fringe-order map (maps.npz / analyze folder): "
        "fit f_sigma",
    )
    ca.add_argument(
        "--load-N",
        nargs="+",
        type=in_range("indenter.load_N", positive=True),
        default=None,
        help="(disc) diametral load of each photograph (N)",
    )
    ca.add_argument(
        "--diameter-mm", type=in_range(DISC_DIAMETER_MM), default=None, help="(disc) diameter"
    )
    ca.add_argument(
        "--thickness-mm",
        type=in_range("sheet.thickness_mm"),
        default=None,
        help="(disc) thickness",
    )
    ca.add_argument(
        "--wavelength-nm",
        type=in_range("optics.wavelength_nm"),
        default=None,
        help="(disc) wavelength of the light, recorded with f_sigma",
    )
    ca.add_argument(
        "--reference",
        default=None,
        metavar="IMAGE",
        help="(disc) the unloaded disc, same light and exposure: fixes the residual order",
    )
    ca.add_argument(
        "--field",
        choices=("dark", "bright"),
        default="dark",
        help="(disc) polariscope field of the photographs",
    )
    ca.add_argument(
        "--residual-field",
        choices=("auto", "uniform", "series"),
        default="auto",
        help="(disc) frozen stress: uniform (one residual order), series (any smooth "
        "field, by load stepping; at least 4 photos at distinct loads), auto (uniform, "
        "then series when that leaves over 4 %% of the fringe amplitude)",
    )
    ca.add_argument("--dark", default=None, help="(disc) dark frame subtracted from every photo")
    ca.add_argument("--pixel-mm", type=in_range(PIXEL_MM), default=None)
    ca.add_argument("--centre", nargs=2, type=finite, metavar=("ROW", "COL"))
    ca.add_argument(
        "--radius-px",
        type=in_range(RADIUS_PX),
        default=None,
        help="(disc) disc radius in the photographs (px)",
    )
    ca.set_defaults(func=run)


def _disc_photos(args: argparse.Namespace) -> int:
    out = Path(args.out or "fringekit-out/disc")
    res = run_disc_photos(
        args.disc,
        args.load_N,
        diameter_mm=args.diameter_mm,
        thickness_mm=args.thickness_mm,
        out=out,
        wavelength_nm=args.wavelength_nm,
        reference=args.reference,
        field=args.field,
        centre=tuple(args.centre) if args.centre else None,
        radius_px=args.radius_px,
        pixel_mm=args.pixel_mm,
        dark=args.dark,
        echo=(lambda s: None) if args.quiet else print,
        residual_field=args.residual_field,
    )
    print(
        f"fringe value f_sigma = {res['f_sigma_N_per_m']:.5g} +- {res['f_sigma_sd_N_per_m']:.2g} "
        f"N/m per fringe from {len(args.disc)} photograph(s), offset "
        f"{res['offset_order']:.3f} fringe; results in {out}/"
    )
    for w in res["summary"]["warnings"]:
        print(f"fringekit calibrate: warning: {w}", file=sys.stderr)
    return 0


def _disc_map(args: argparse.Namespace) -> int:
    if len(args.disc) != 1 or len(args.load_N) != 1:
        raise InputError("--disc with a fringe-order map takes one map and one --load-N")
    res = run_disc(
        args.disc[0],
        load_N=args.load_N[0],
        diameter_mm=args.diameter_mm,
        thickness_mm=args.thickness_mm,
        pixel_mm=args.pixel_mm,
        centre=tuple(args.centre) if args.centre else None,
    )
    if args.out:
        with claim_output(args.out, command="calibrate", inputs=args.disc) as work:
            (work / "fringe_value.json").write_text(json.dumps(res, indent=2))
    print(
        f"fringe value f_sigma = {res['f_sigma_N_per_m']:.4g} N/m per fringe (whole-field "
        f"fit over {res['pixels']} pixels, residual {res['rms_residual_fringe']:.3f} fringe"
        + (
            f"; centre only {res['f_sigma_centre_N_per_m']:.4g}"
            if res["f_sigma_centre_N_per_m"]
            else ""
        )
        + ")"
    )
    if "warning" in res:
        print(f"fringekit calibrate: warning: {res['warning']}", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    if args.disc:
        for name in ("load_N", "diameter_mm", "thickness_mm"):
            if getattr(args, name) is None:
                raise InputError(f"--disc needs --{name.replace('_', '-')}")
        return _disc_photos(args) if is_photo(args.disc[0]) else _disc_map(args)
    disc_only = (
        "load_N",
        "diameter_mm",
        "thickness_mm",
        "wavelength_nm",
        "reference",
        "dark",
        "pixel_mm",
        "centre",
        "radius_px",
    )
    given = [n for n in disc_only if getattr(args, n) is not None]
    if given:
        flag = "--" + given[0].replace("_", "-")
        raise InputError(
            f"{flag} is an option of calibrate --disc; give --disc IMAGE... with it, or leave "
            "it out for the load-path calibration"
        )
    base = default_calibration_config() if args.config is None else None
    cfg = overrides(args.config, args.set or [], base=base)
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    cal = run_calibrate(
        cfg,
        out,
        cache_dir=args.cache_dir,
        use_cache=not args.no_cache,
        progress=not args.quiet,
        inputs=[args.config],
    )
    if not args.quiet:
        print(
            f"fringekit calibrate - {len(cal['loads_N'])} load states, results in {out}/ "
            "(F in N; each feature in the unit its name ends with, order in fringes)"
        )
        for n, fit in cal["normal_fits"].items():
            print(
                f"  F = {fit['a']:.4g} * {n}^{fit['b']:.3f}   (scatter "
                f"{100 * fit['sigma_logF']:.1f} % in F over {fit['n']} states)"
            )
        for n, fit in cal["shear_fits"].items():
            print(f"  {n} = {fit['c0']:.3g} N + {fit['c1']:.4g} N/mm * {fit['feature']}")
    return 0
