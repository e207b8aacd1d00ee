"""The ``fringekit`` subcommands: parsed options -> a run -> lines on stdout.

Each ``cmd_*`` takes the :mod:`argparse` namespace of :func:`fringekit.cli.main` and
returns the exit status; errors are raised (``ValueError``/``ConfigError`` for bad input,
:class:`fringekit.pipeline.PredictError` for a failed run) and reported by ``main``.
Heavy stages are imported inside the commands, so ``fringekit --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from fringekit.analyze import (
    MonoOptions,
    PhaseOptions,
    Region,
    RGBOptions,
    analyze,
    choose_method,
)
from fringekit.errors import InputError
from fringekit.output.folders import claim_output
from fringekit.output.versions import package_version

__all__ = [
    "MESH_OPTIONS",
    "cmd_analyze",
    "cmd_calibrate",
    "cmd_compare",
    "cmd_config",
    "cmd_estimate",
    "cmd_mesh",
    "cmd_predict",
    "cmd_sweep",
    "fringekit_version",
    "overrides",
]


def fringekit_version() -> str:
    """The installed fringekit version (``0+unknown`` when run from a source tree)."""
    return package_version("fringekit", missing="0+unknown")


#: ``fringekit mesh`` shorthands -> the config keys they set.
MESH_OPTIONS = {
    "symmetry": ("mesh.symmetry",),
    "thickness_mm": ("sheet.thickness_mm",),
    "substrate_mm": ("substrate.thickness_mm",),
    "width_mm": ("sheet.width_mm", "sheet.length_mm"),
    "indenter_diameter_mm": ("indenter.diameter_mm",),
    "h_contact_mm": ("mesh.h_contact_mm",),
    "refine_radius_mm": ("mesh.refine_radius_mm",),
    "h_sheet_mm": ("mesh.h_sheet_mm",),
    "h_far_mm": ("mesh.h_far_mm",),
}


def cmd_mesh(args: argparse.Namespace) -> int:
    """Mesh a config (default: the reference case) the way ``predict`` does; export VTU."""
    from fringekit.config.files import apply_overrides
    from fringekit.config.inputs import mesh_spec
    from fringekit.meshes import build_mesh, quality_report, write_vtu

    cfg = overrides(args.config, args.set or [])
    shorthands = {
        key: getattr(args, opt)
        for opt, keys in MESH_OPTIONS.items()
        for key in keys
        if getattr(args, opt) is not None
    }
    cfg = apply_overrides(cfg, shorthands) if shorthands else cfg
    spec = mesh_spec(cfg)
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    with claim_output(out, command="mesh", inputs=[args.config]) as work:
        t0 = time.perf_counter()
        mesh = build_mesh(spec, cache_dir=args.cache_dir, use_cache=not args.no_cache)
        elapsed = time.perf_counter() - t0
        rep = quality_report(mesh.points, mesh.cells, mesh.regions)
        write_vtu(mesh, work / "mesh.vtu")
        vtu = out / "mesh.vtu"
        summary = {
            "fringekit_version": fringekit_version(),
            "mesh_spec_SI": spec.to_dict(),
            "quality": rep.as_dict(),
            "facet_sets": {k: len(v) for k, v in mesh.facets.items()},
            "time_s": elapsed,
            "vtu": str(vtu),
        }
        (work / "mesh_summary.json").write_text(json.dumps(summary, indent=2))
    if not args.quiet:
        print(f"fringekit {fringekit_version()} - {cfg['case']} mesh ({spec.symmetry} model)")
        print(f"  {rep}")
        print("  facet sets: " + ", ".join(f"{k} {v}" for k, v in summary["facet_sets"].items()))
        print(f"  built or loaded in {elapsed:.1f} s; wrote {vtu} and {out / 'mesh_summary.json'}")
    return 0


def overrides(cfg_source, sets: list[str], base: dict | None = None) -> dict:
    """Effective config from CONFIG (or ``base``) plus ``--set table.key=value`` overrides."""
    from fringekit.config.files import ConfigError, apply_overrides, load_config, tomllib

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


def cmd_predict(args: argparse.Namespace) -> int:
    from fringekit.predict.pipeline import run_predict

    cfg = overrides(args.config, args.set or [])
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    t0 = time.perf_counter()
    if args.library:
        from fringekit.predict.from_library import run_library_predict

        run_library_predict(cfg, args.library, out, progress=not args.quiet, inputs=[args.config])
        return 0
    summary = run_predict(
        cfg, out, cache_dir=args.cache_dir, use_cache=not args.no_cache, progress=not args.quiet,
        inputs=[args.config],
    )  # fmt: skip
    if not args.quiet:
        took = time.perf_counter() - t0
        print(f"fringekit {fringekit_version()} - {cfg['case']}: done in {took:.1f} s")
        for j, ind in enumerate(summary["indenters"]):
            f = ", ".join(f"{v:.3g}" for v in ind["force_N"])
            print(
                f"  indenter {j}: force [{f}] N, depth {ind['depth_mm']:.4f} mm, "
                f"contact radius {ind['contact_radius_mm']:.3f} mm"
            )
        print(f"  max fringe order {summary['max_fringe_order']:.2f} (contact zone masked)")
        print(f"  results in {out}/ (summary.json, state_*/solution.vtu, images, figures)")
    return 0


def cmd_config(args: argparse.Namespace) -> int:
    from fringekit.config.files import to_toml

    cfg = overrides(args.config, args.set or [])
    sys.stdout.write(to_toml(cfg))
    return 0


def roi_polygon(args: argparse.Namespace):
    """The polygonal region of interest of ``--roi-rect`` or ``--roi-polygon`` (px)."""
    if args.roi_rect is not None and args.roi_polygon is not None:
        raise ValueError("give --roi-rect or --roi-polygon, not both")
    if args.roi_rect is not None:
        r0, c0, r1, c1 = args.roi_rect
        return [(r0, c0), (r0, c1), (r1, c1), (r1, c0)]
    if args.roi_polygon is not None and len(args.roi_polygon) < 3:
        raise ValueError(
            f"--roi-polygon has {len(args.roi_polygon)} vertices; allowed: 3 or more ROW,COL"
        )
    return args.roi_polygon


#: Half-width (px) of an excluded line (``--exclude-polygon`` with two vertices).
LINE_HALF_WIDTH_PX = 1.5


def exclusion_polygon(vertices):
    """An ``--exclude-polygon``: 3 or more vertices as given; two vertices, the line
    between them widened to a 3 px band (a crack)."""
    if len(vertices) >= 3:
        return vertices
    if len(vertices) != 2 or vertices[0] == vertices[1]:
        raise ValueError(
            f"--exclude-polygon {' '.join(f'{r:g},{c:g}' for r, c in vertices)}: allowed: two "
            "distinct vertices (a line) or three or more (a polygon)"
        )
    (r0, c0), (r1, c1) = vertices
    length = ((r1 - r0) ** 2 + (c1 - c0) ** 2) ** 0.5
    nr, nc = -(c1 - c0) / length * LINE_HALF_WIDTH_PX, (r1 - r0) / length * LINE_HALF_WIDTH_PX
    return [(r0 + nr, c0 + nc), (r1 + nr, c1 + nc), (r1 - nr, c1 - nc), (r0 - nr, c0 - nc)]


def cmd_analyze(args: argparse.Namespace) -> int:
    out = Path(args.out or "fringekit-out/analysis")
    region = Region(
        circle=tuple(args.roi_circle) if args.roi_circle else None,
        polygon=roi_polygon(args),
        exclude_circles=[tuple(e) for e in args.exclude_circle or []],
        exclude_polygons=[exclusion_polygon(p) for p in args.exclude_polygon or []],
        disc_diameter_mm=args.roi_disc,
    )
    options = {
        "phase": lambda: PhaseOptions(args.min_modulation, args.fold, args.reference),
        "rgb": lambda: RGBOptions(
            args.calibration, args.light, args.camera, args.max_order, args.exposure,
            tuple(tuple(s) for s in args.seed or []), args.window,
        ),
        "mono": lambda: MonoOptions(args.field, args.flat, args.smooth_px),
    }  # fmt: skip
    method = choose_method(args.method, [str(p) for p in args.images])
    if args.reference and method != "phase":
        raise InputError(
            f"--reference is for --method phase (six zero-load images); the {method} method "
            "has none (calibrate --disc takes a zero-load photo)"
        )
    given = [*args.images, *(args.reference or []), args.dark, args.flat, args.calibration]
    with claim_output(out, command="analyze", inputs=[*given, args.points]) as work:
        an = analyze(
            args.images,
            method=method,
            pixel_mm=args.pixel_mm or 0.0,
            origin_px=tuple(args.origin_px) if args.origin_px else None,
            region=region,
            dark=args.dark,
            anchor_order=args.anchor_order,
            order_at=[tuple(p) for p in args.order_at or []],
            fringe_value_N_per_m=args.f_sigma_N_per_m,
            thickness_mm=args.thickness_mm,
            options=options[method](),
        )
        an.write(work, line=tuple(args.line) if args.line else None, points=args.points)
    summary = an.summary
    if not args.quiet:
        rng = summary["fringe_order_range"]
        print(
            f"fringekit analyze ({summary['method']}): {summary['valid_pixels']} valid, "
            f"{summary['reliable_pixels']} reliable pixels; fringe order "
            + (f"{rng[0]:.2f}..{rng[1]:.2f}" if rng else "none")
            + f"; results in {out}/"
        )
    if "warning" in summary:
        print(f"fringekit analyze: warning: {summary['warning']}", file=sys.stderr)
        if args.strict:
            return 1
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from fringekit.analyze.compare import run_compare

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
            f"fringekit compare: residual RMS {s['rms_fringe']:.3g} fringe, 95th percentile of "
            f"|residual| {s['p95_fringe']:.3g} fringe, over {s['pixels']} pixels; results in "
            f"{out}/"
        )
    return 0


def _disc_photos(args: argparse.Namespace) -> int:
    from fringekit.calibrate.disc import run_disc_photos

    out = Path(args.out or "fringekit-out/disc")
    res = run_disc_photos(
        args.disc, args.load_N, diameter_mm=args.diameter_mm, thickness_mm=args.thickness_mm,
        out=out, wavelength_nm=args.wavelength_nm, reference=args.reference, field=args.field,
        centre=tuple(args.centre) if args.centre else None, radius_px=args.radius_px,
        pixel_mm=args.pixel_mm, dark=args.dark, echo=(lambda s: None) if args.quiet else print,
    )  # fmt: skip
    print(
        f"fringe value f_sigma = {res['f_sigma_N_per_m']:.5g} +- {res['f_sigma_sd_N_per_m']:.2g} "
        f"N/m per fringe from {len(args.disc)} photograph(s), offset "
        f"{res['offset_order']:.3f} fringe; results in {out}/"
    )
    for w in res["summary"]["warnings"]:
        print(f"fringekit calibrate: warning: {w}", file=sys.stderr)
    return 0


def _disc_map(args: argparse.Namespace) -> int:
    from fringekit.calibrate.estimate import run_disc

    if len(args.disc) != 1 or len(args.load_N) != 1:
        raise ValueError("--disc with a fringe-order map takes one map and one --load-N")
    res = run_disc(
        args.disc[0], load_N=args.load_N[0], diameter_mm=args.diameter_mm,
        thickness_mm=args.thickness_mm, pixel_mm=args.pixel_mm,
        centre=tuple(args.centre) if args.centre else None,
    )  # fmt: skip
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


def cmd_calibrate(args: argparse.Namespace) -> int:
    if args.disc:
        from fringekit.calibrate.disc import is_photo

        for name in ("load_N", "diameter_mm", "thickness_mm"):
            if getattr(args, name) is None:
                raise ValueError(f"--disc needs --{name.replace('_', '-')}")
        return _disc_photos(args) if is_photo(args.disc[0]) else _disc_map(args)
    from fringekit.calibrate.load import default_calibration_config, run_calibrate

    base = default_calibration_config() if args.config is None else None
    cfg = overrides(args.config, args.set or [], base=base)
    out = Path(args.out) if args.out else Path("fringekit-out") / cfg["case"]
    cal = run_calibrate(
        cfg, out, cache_dir=args.cache_dir, use_cache=not args.no_cache, progress=not args.quiet,
        inputs=[args.config],
    )  # fmt: skip
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


def cmd_estimate(args: argparse.Namespace) -> int:
    from fringekit.calibrate.estimate import run_estimate

    est = run_estimate(
        args.maps, args.calibration, pixel_mm=args.pixel_mm,
        centre=tuple(args.centre) if args.centre else None, out=args.out,
    )  # fmt: skip
    line = (
        f"normal load {est['normal_N']:.3f} N (standard uncertainty {est['normal_sigma_N']:.2g} N"
        f" from the calibration scatter; {len(est['per_feature'])} features, whose estimates "
        f"span {est['spread_N']:.2g} N)"
    )
    if "shear_N" in est:
        line += f"; shear [{est['shear_N'][0]:.3f}, {est['shear_N'][1]:.3f}] N"
    print(line)
    if "warning" in est:
        print(f"fringekit estimate: warning: {est['warning']}", file=sys.stderr)
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from fringekit.sweep.run import load_sweep, run_sweep

    sweep = load_sweep(args.sweep)
    out = Path(args.out) if args.out else Path("fringekit-out") / sweep["name"]
    res = run_sweep(
        sweep, out, scheduler=args.scheduler, workers=args.workers, cache_dir=args.cache_dir,
        progress=not args.quiet, inputs=[args.sweep],
    )  # fmt: skip
    if not args.quiet:
        print(
            f"fringekit sweep {sweep['name']}: {res['cases']} cases ({res['run']} run, "
            f"{res['skipped']} already finished, {res['failed']} failed) in {res['time_s']:.1f} s;"
            f" table {res['table']}"
        )
    return 1 if res["failed"] else 0
