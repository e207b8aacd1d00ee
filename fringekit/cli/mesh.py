"""``fringekit mesh``: the mesh ``predict`` would use for a config, summarised and written as
VTU.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fringekit import __version__
from fringekit.cli.options import (
    in_range,
    overrides,
)
from fringekit.config.files import apply_overrides
from fringekit.config.inputs import mesh_spec
from fringekit.meshes import build_mesh, quality_report, write_vtu
from fringekit.output.folders import claim_output

__all__ = ["add_parser", "run"]


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


def add_parser(sub) -> None:
    m = sub.add_parser(
        "mesh", help="mesh a config (default: the reference case) as predict does; export VTU"
    )
    m.add_argument(
        "config",
        nargs="?",
        default=None,
        help="TOML config file or built-in case; default reference",
    )
    m.add_argument(
        "--set",
        action="append",
        metavar="TABLE.KEY=VALUE",
        help="override one config value (repeatable)",
    )
    m.add_argument(
        "--symmetry",
        choices=("auto", "full", "half", "quarter"),
        default=None,
        help="sets mesh.symmetry",
    )
    for opt, keys in MESH_OPTIONS.items():
        if opt != "symmetry":
            flag = "--" + opt.replace("_", "-")
            m.add_argument(
                flag, type=in_range(keys[0]), default=None, help="sets " + " and ".join(keys)
            )
    m.add_argument("--out", default=None, help="output folder (default fringekit-out/<case>)")
    m.add_argument("--cache-dir", default=None, help="mesh cache root")
    m.add_argument("--no-cache", action="store_true", help="always regenerate the mesh")
    m.add_argument("--quiet", action="store_true")
    m.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Mesh a config (default: the reference case) the way ``predict`` does; export VTU."""
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
            "fringekit_version": __version__,
            "mesh_spec_SI": spec.to_dict(),
            "quality": rep.as_dict(),
            "facet_sets": {k: len(v) for k, v in mesh.facets.items()},
            "time_s": elapsed,
            "vtu": str(vtu),
        }
        (work / "mesh_summary.json").write_text(json.dumps(summary, indent=2))
    if not args.quiet:
        print(f"fringekit {__version__} - {cfg['case']} mesh ({spec.symmetry} model)")
        print(f"  {rep}")
        print("  facet sets: " + ", ".join(f"{k} {v}" for k, v in summary["facet_sets"].items()))
        print(f"  built or loaded in {elapsed:.1f} s; wrote {vtu} and {out / 'mesh_summary.json'}")
    return 0
