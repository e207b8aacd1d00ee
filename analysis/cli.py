"""The ``fringekit`` command.

Subcommands available now: ``mesh`` (generate, summarise and export the mesh of the
reference sensor or of a variant given on the command line). ``predict``, ``analyze``,
``compare``, ``calibrate`` and ``sweep`` arrive with their pipeline stages.
User errors exit with status 2 and a one-line reason, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["main"]

PLANNED = ("predict", "analyze", "compare", "calibrate", "estimate", "sweep", "config")


def _version() -> str:
    try:
        return version("fringekit")
    except PackageNotFoundError:  # running from a source tree
        return "0+unknown"


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


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="fringekit",
        description="Contact stress and photoelastic fringe prediction for photoelastic "
        "tactile sensors.",
        epilog="Planned subcommands (not yet available): " + ", ".join(PLANNED),
    )
    p.add_argument("--version", action="version", version=f"fringekit {_version()}")
    sub = p.add_subparsers(dest="command")
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
    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f"fringekit {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
