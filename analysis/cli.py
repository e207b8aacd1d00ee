"""The ``fringekit`` command.

Subcommands available now:

- ``predict [CONFIG]``: config (a TOML file or a built-in case name; none = the reference
  case) -> mesh -> contact solution -> optics -> an output folder (analysis.predict);
- ``config show [CONFIG]``: the effective configuration with defaults and units;
- ``mesh``: generate, summarise and export the mesh of the reference sensor or a variant.

- ``analyze IMAGES...``: fringe order maps, profiles and figures from six phase-stepped
  images or one RGB image (analysis.analyze);
- ``compare PREDICTION MEASUREMENT``: registration, residual maps and statistics.

- ``calibrate [CONFIG]``: load-to-fringe relations over a load path, or ``--disc`` the
  fringe value from a disc; ``estimate MAPS --calibration FILE``: the load back.
- ``sweep SWEEP.toml``: a grid or list of cases on Dask, resumable (analysis.sweep).
Exit status: 0 success, 2 a user error (bad config or input; one line, no traceback),
1 a run that failed (the solver did not reach a load; what converged is written).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

__all__ = ["main"]


def _version() -> str:
    from .predict import _pkg_version

    return _pkg_version("fringekit", missing="0+unknown")


def _cmd_mesh(args: argparse.Namespace) -> int:
    from meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh, quality_report, write_vtu

    spec = MeshSpec(
        layers=Layers(
            sheet_thickness=args.thickness_mm * 1e-3,
            substrate_thickness=args.substrate_mm * 1e-3,
            width=args.width_mm * 1e-3,
            length=args.width_mm * 1e-3,
        ),
        indenters=(IndenterSite(0.0, 0.0, args.indenter_diameter_mm * 0.5e-3),),
        sizing=Sizing(
            h_contact=args.h_contact_mm * 1e-3,
            refine_radius=args.refine_radius_mm * 1e-3,
            h_far=args.h_far_mm * 1e-3,
            h_sheet=args.h_sheet_mm * 1e-3,
            growth=Sizing().growth,
        ),
        symmetry=args.symmetry,
    )
    t0 = time.perf_counter()
    mesh = build_mesh(spec, cache_dir=args.cache_dir, use_cache=not args.no_cache)
    elapsed = time.perf_counter() - t0
    rep = quality_report(mesh.points, mesh.cells, mesh.regions)
    out = Path(args.out)
    vtu = write_vtu(mesh, out / "mesh.vtu")
    summary = {
        "fringekit_version": _version(),
        "mesh_spec_SI": spec.to_dict(),
        "quality": rep.as_dict(),
        "facet_sets": {k: len(v) for k, v in mesh.facets.items()},
        "time_s": elapsed,
        "vtu": str(vtu),
    }
    (out / "mesh_summary.json").write_text(json.dumps(summary, indent=2))
    if not args.quiet:
        print(f"fringekit {_version()} - reference sensor mesh ({args.symmetry} model)")
        print(f"  {rep}")
        print("  facet sets: " + ", ".join(f"{k} {v}" for k, v in summary["facet_sets"].items()))
        print(f"  built or loaded in {elapsed:.1f} s; wrote {vtu} and {out / 'mesh_summary.json'}")
    return 0


def _overrides(cfg_source, sets: list[str], base: dict | None = None) -> dict:
    """Effective config from CONFIG (or ``base``) plus ``--set table.key=value`` overrides."""
    from .config import ConfigError, apply_overrides, load_config, tomllib

    base = load_config(cfg_source) if base is None or cfg_source is not None else base
    values = {}
    for item in sets:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {item!r} is not allowed; use --set table.key=value")
        try:
            values[key.strip()] = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            values[key.strip()] = text.strip()  # a bare word is a string
    return apply_overrides(base, values) if values else base


def _cmd_predict(args: argparse.Namespace) -> int:
    from .predict import run_predict

    cfg = _overrides(args.config, args.set or [])
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    t0 = time.perf_counter()
    summary = run_predict(
        cfg, out, cache_dir=args.cache_dir, use_cache=not args.no_cache, progress=not args.quiet
    )
    if not args.quiet:
        print(f"fringekit {_version()} - {cfg['case']}: done in {time.perf_counter() - t0:.1f} s")
        for j, ind in enumerate(summary["indenters"]):
            f = ", ".join(f"{v:.3g}" for v in ind["force_N"])
            print(
                f"  indenter {j}: force [{f}] N, depth {ind['depth_mm']:.4f} mm, "
                f"contact radius {ind['contact_radius_mm']:.3f} mm"
            )
        print(f"  max fringe order {summary['max_fringe_order']:.2f} (contact zone masked)")
        print(f"  results in {out}/ (summary.json, state_*/solution.vtu, images, figures)")
    return 0


def _cmd_config(args: argparse.Namespace) -> int:
    from .config import to_toml

    cfg = _overrides(args.config, args.set or [])
    sys.stdout.write(to_toml(cfg))
    return 0


def _cmd_analyze(args: argparse.Namespace) -> int:
    from .analyze import run_analyze

    if args.f_sigma_N_per_m is not None and not args.f_sigma_N_per_m > 0:
        raise ValueError(f"--f-sigma-N-per-m = {args.f_sigma_N_per_m} is not allowed; must be > 0")
    out = Path(args.out or "fringekit-out/analysis")
    summary = run_analyze(
        args.images,
        out,
        method=args.method,
        dark=args.dark,
        roi_circle=tuple(args.roi_circle) if args.roi_circle else None,
        exclude=[tuple(e) for e in args.exclude_circle or []],
        pixel_size=(args.pixel_mm or 0.0) * 1e-3,
        anchor_order=args.anchor_order,
        min_modulation=args.min_modulation,
        calibration=args.calibration,
        chart={
            "light": args.light,
            "camera": args.camera,
            "max_order": args.max_order,
            "exposure": args.exposure,
        },
        seeds=[tuple(s) for s in args.seed or []],
        window=args.window,
        line=tuple(args.line) if args.line else None,
        f_sigma=args.f_sigma_N_per_m,
        thickness=args.thickness_mm * 1e-3 if args.thickness_mm else None,
    )
    if not args.quiet:
        rng = summary["fringe_order_range"]
        print(
            f"fringekit analyze ({summary['method']}): {summary['valid_pixels']} valid, "
            f"{summary['reliable_pixels']} reliable pixels; fringe order "
            + (f"{rng[0]:.2f}..{rng[1]:.2f}" if rng else "none")
            + f"; results in {out}/"
        )
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from .analyze import run_compare

    out = Path(args.out or "fringekit-out/compare")
    s = run_compare(
        args.prediction,
        args.measurement,
        out,
        predicted_pixel_size=(args.predicted_pixel_mm or 0) * 1e-3 or None,
        measured_pixel_size=(args.measured_pixel_mm or 0) * 1e-3 or None,
        centre_measured=tuple(args.centre_measured) if args.centre_measured else None,
        rotation_deg=args.rotation_deg,
    )
    if not args.quiet:
        print(
            f"fringekit compare: residual RMS {s['rms_fringe']:.3f}, p95 {s['p95_fringe']:.3f} "
            f"fringe over {s['pixels']} pixels; results in {out}/"
        )
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from .calibration_run import default_calibration_config, run_calibrate, run_disc

    if args.disc:
        for name in ("load_N", "diameter_mm", "thickness_mm"):
            if getattr(args, name) is None:
                raise ValueError(f"--disc needs --{name.replace('_', '-')}")
        res = run_disc(
            args.disc, load_N=args.load_N, diameter_mm=args.diameter_mm,
            thickness_mm=args.thickness_mm, pixel_mm=args.pixel_mm,
            centre=tuple(args.centre) if args.centre else None,
        )  # fmt: skip
        if args.out:
            Path(args.out).mkdir(parents=True, exist_ok=True)
            (Path(args.out) / "fringe_value.json").write_text(json.dumps(res, indent=2))
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
        return 0
    base = default_calibration_config() if args.config is None else None
    cfg = _overrides(args.config, args.set or [], base=base)
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    cal = run_calibrate(
        cfg, out, cache_dir=args.cache_dir, use_cache=not args.no_cache, progress=not args.quiet
    )
    if not args.quiet:
        print(f"fringekit calibrate - {len(cal['loads_N'])} load states, results in {out}/")
        for n, fit in cal["normal_fits"].items():
            print(
                f"  F = {fit['a']:.4g} * {n}^{fit['b']:.3f}   (scatter "
                f"{100 * fit['sigma_logF']:.1f} % in F over {fit['n']} states)"
            )
        for n, fit in cal["shear_fits"].items():
            print(f"  {n} = {fit['c0']:.3g} + {fit['c1']:.4g} * {fit['feature']}")
    return 0


def _cmd_estimate(args: argparse.Namespace) -> int:
    from .calibration_run import run_estimate

    est = run_estimate(
        args.maps, args.calibration, pixel_mm=args.pixel_mm,
        centre=tuple(args.centre) if args.centre else None, out=args.out,
    )  # fmt: skip
    line = f"normal load {est['normal_N']:.3f} N (+- {est['normal_sigma_N']:.2g} N"
    line += f", {len(est['per_feature'])} features, spread {est['spread_N']:.2g} N)"
    if "shear_N" in est:
        line += f"; shear [{est['shear_N'][0]:.3f}, {est['shear_N'][1]:.3f}] N"
    print(line)
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .sweep import load_sweep, run_sweep

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers = {args.workers} is not allowed; must be >= 1")
    sweep = load_sweep(args.sweep)
    out = Path(args.out) if args.out else Path("fringekit-out") / sweep["name"]
    res = run_sweep(
        sweep, out, scheduler=args.scheduler, workers=args.workers, cache_dir=args.cache_dir,
        progress=not args.quiet,
    )  # fmt: skip
    if not args.quiet:
        print(
            f"fringekit sweep {sweep['name']}: {res['cases']} cases ({res['run']} run, "
            f"{res['skipped']} already finished, {res['failed']} failed) in {res['time_s']:.1f} s;"
            f" table {res['table']}"
        )
    return 1 if res["failed"] else 0


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


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fringekit",
        description="Contact stress and photoelastic fringe prediction for photoelastic "
        "tactile sensors.",
    )
    p.add_argument("--version", action="version", version=f"fringekit {_version()}")
    sub = p.add_subparsers(dest="command")
    pr = sub.add_parser(
        "predict",
        help="mesh, solve and render fringes for a config (default: the reference case)",
    )
    pr.add_argument(
        "config", nargs="?", default=None,
        help="TOML config file or built-in case (reference, shear); default reference",
    )  # fmt: skip
    _run_options(pr)
    pr.set_defaults(func=_cmd_predict)
    cf = sub.add_parser("config", help="configuration tools")
    cfs = cf.add_subparsers(dest="action", required=True)
    show = cfs.add_parser("show", help="print the effective config with defaults and units")
    show.add_argument("config", nargs="?", default=None)
    show.add_argument("--set", action="append", metavar="TABLE.KEY=VALUE")
    show.set_defaults(func=_cmd_config, quiet=True)
    an = sub.add_parser("analyze", help="fringe order from six phase-stepped or RGB images")
    an.add_argument("images", nargs="+", help="six step images (or a 6-page TIFF), or one RGB")
    an.add_argument("--method", choices=("phase", "rgb"), default=None,
                    help="default: rgb for one PNG/JPEG, phase otherwise")  # fmt: skip
    an.add_argument("--out", default=None, help="output folder (default fringekit-out/analysis)")
    an.add_argument("--dark", default=None, help="dark frame subtracted from every image")
    an.add_argument("--roi-circle", nargs=3, type=float, metavar=("ROW", "COL", "R"))
    an.add_argument(
        "--exclude-circle", nargs=3, type=float, action="append", metavar=("ROW", "COL", "R"),
        help="masked circle, e.g. the indenter",
    )  # fmt: skip
    an.add_argument("--pixel-mm", type=float, default=None, help="pixel pitch on the sheet (mm)")
    an.add_argument("--anchor-order", type=float, default=0.0,
                    help="(phase) fringe order of the image border ring")  # fmt: skip
    an.add_argument("--min-modulation", type=float, default=0.1)
    an.add_argument("--calibration", default=None, help="(rgb) table CSV: order,R,G,B")
    an.add_argument("--light", default="LED", help="(rgb) light of the synthetic chart")
    an.add_argument("--camera", default="CIE1931", help="(rgb) camera of the synthetic chart")
    an.add_argument("--max-order", type=float, default=4.0, help="(rgb) chart range")
    an.add_argument("--exposure", type=float, default=0.9,
                    help="(rgb) chart exposure, as in predict's optics.exposure")  # fmt: skip
    an.add_argument("--seed", nargs=3, type=float, action="append", metavar=("ROW", "COL", "N"),
                    help="(rgb) pixel of known order: refined search from it")  # fmt: skip
    an.add_argument("--window", type=float, default=0.25, help="(rgb) refined window (fringe)")
    an.add_argument("--line", nargs=4, type=float, metavar=("R0", "C0", "R1", "C1"))
    an.add_argument("--f-sigma-N-per-m", type=float, default=None)
    an.add_argument("--thickness-mm", type=float, default=None)
    an.add_argument("--quiet", action="store_true")
    an.set_defaults(func=_cmd_analyze)
    co = sub.add_parser("compare", help="prediction vs measurement: residuals and figures")
    co.add_argument("prediction", help="predict output folder or maps.npz")
    co.add_argument("measurement", help="analyze output folder or maps.npz")
    co.add_argument("--out", default=None, help="output folder (default fringekit-out/compare)")
    co.add_argument("--predicted-pixel-mm", type=float, default=None)
    co.add_argument("--measured-pixel-mm", type=float, default=None)
    co.add_argument("--centre-measured", nargs=2, type=float, metavar=("ROW", "COL"))
    co.add_argument("--rotation-deg", type=float, default=0.0)
    co.add_argument("--quiet", action="store_true")
    co.set_defaults(func=_cmd_compare)
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
        "--disc", default=None, metavar="MAPS",
        help="fringe-order map of a diametral disc (transmission): fit f_sigma",
    )  # fmt: skip
    ca.add_argument("--load-N", type=float, default=None, help="(disc) diametral load")
    ca.add_argument("--diameter-mm", type=float, default=None, help="(disc) diameter")
    ca.add_argument("--thickness-mm", type=float, default=None, help="(disc) thickness")
    ca.add_argument("--pixel-mm", type=float, default=None)
    ca.add_argument("--centre", nargs=2, type=float, metavar=("ROW", "COL"))
    ca.set_defaults(func=_cmd_calibrate)
    es = sub.add_parser("estimate", help="load (and shear) from a fringe-order map")
    es.add_argument("maps", help="maps.npz, or a fringekit analyze / predict output folder")
    es.add_argument("--calibration", required=True, help="calibration.json from calibrate")
    es.add_argument("--pixel-mm", type=float, default=None)
    es.add_argument("--centre", nargs=2, type=float, metavar=("ROW", "COL"),
                    help="indenter axis in pixels (default: stored in the maps)")  # fmt: skip
    es.add_argument("--out", default=None)
    es.add_argument("--quiet", action="store_true")
    es.set_defaults(func=_cmd_estimate)
    sw = sub.add_parser("sweep", help="run a grid or list of cases in parallel (Dask)")
    sw.add_argument("sweep", help="sweep TOML file (base, [set], [grid] or [[case]])")
    sw.add_argument("--out", default=None, help="output folder (default fringekit-out/<name>)")
    sw.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    sw.add_argument("--workers", type=int, default=None, help="local worker processes")
    sw.add_argument("--cache-dir", default=None)
    sw.add_argument("--quiet", action="store_true")
    sw.set_defaults(func=_cmd_sweep)
    m = sub.add_parser("mesh", help="mesh the reference sensor (or a variant) and export VTU")
    m.add_argument("--symmetry", choices=("full", "half", "quarter"), default="quarter")
    m.add_argument("--thickness-mm", type=float, default=3.0, help="sheet thickness (mm)")
    m.add_argument("--substrate-mm", type=float, default=15.0, help="PC thickness (mm)")
    m.add_argument("--width-mm", type=float, default=40.0, help="lateral size (mm)")
    m.add_argument("--indenter-diameter-mm", type=float, default=3.5)
    m.add_argument("--h-contact-mm", type=float, default=0.3)
    m.add_argument("--refine-radius-mm", type=float, default=2.0)
    m.add_argument("--h-sheet-mm", type=float, default=1.0)
    m.add_argument("--h-far-mm", type=float, default=4.0)
    m.add_argument("--out", default="fringekit-out/reference", help="output folder")
    m.add_argument("--cache-dir", default=None, help="mesh cache root")
    m.add_argument("--no-cache", action="store_true", help="always regenerate the mesh")
    m.add_argument("--quiet", action="store_true")
    m.set_defaults(func=_cmd_mesh)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fringekit`` console script; returns the exit status."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    logging.basicConfig(
        level=logging.WARNING if getattr(args, "quiet", False) else logging.INFO,
        format="%(name)s: %(message)s",
    )
    for noisy in ("distributed", "tornado", "bokeh"):  # Dask's cluster chatter
        logging.getLogger(noisy).setLevel(logging.WARNING)
    from .predict import PredictError

    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f"fringekit {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except PredictError as exc:
        print(f"fringekit {args.command}: failed: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
