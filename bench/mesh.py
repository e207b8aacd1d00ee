"""Meshing benchmark: reference quarter, half, full meshes and the four-indenter plate.

Prints node, element and DOF counts, meshing time, quality and peak memory of each
case (always regenerated, never from the cache), with the deterministic layered mesher
or, with ``--mesher tetwild``, fTetWild.

    python bench/mesh.py [--json FILE] [--mesher layered|tetwild] [--threads N]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
import tracemalloc
from dataclasses import replace

from fringekit.meshes import IndenterSite, MeshSpec, build_mesh, quality_report


def _cases():
    s = 8e-3  # reference loading plate: four heads on an (assumed) 16 mm square pitch
    plate = tuple(IndenterSite(x, y, 1.75e-3) for x in (-s, s) for y in (-s, s))
    return [
        ("quarter", MeshSpec(symmetry="quarter")),
        ("half", MeshSpec(symmetry="half")),
        ("full", MeshSpec(symmetry="full")),
        ("plate4", MeshSpec(indenters=plate, symmetry="quarter")),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write the figures to this JSON file")
    ap.add_argument("--threads", type=int, default=0, help="fTetWild threads (0 = all cores)")
    ap.add_argument("--mesher", choices=("layered", "tetwild"), default="layered")
    args = ap.parse_args()
    rows = []
    for name, spec in _cases():
        spec = replace(spec, mesher=args.mesher)
        tracemalloc.start()
        t0 = time.perf_counter()
        mesh = build_mesh(spec, use_cache=False, num_threads=args.threads)
        dt = time.perf_counter() - t0
        _, peak_py = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        rep = quality_report(mesh.points, mesh.cells, mesh.regions)
        # ru_maxrss is the process high-water mark (KiB on Linux), incl. fTetWild's C++ heap
        peak = max(peak_py / 2**20, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        rows.append(
            {
                "name": name,
                "nodes": mesh.n_points,
                "cells": mesh.n_cells,
                "dofs": mesh.n_dofs,
                "time_s": round(dt, 2),
                "min_dihedral_deg": round(rep.min_dihedral_deg, 2),
                "min_radius_ratio": round(rep.min_radius_ratio, 3),
                "cells_per_region": rep.cells_per_region,
                "peak_mem_mb": round(peak, 1),
            }
        )
        r = rows[-1]
        print(
            f"{name:8s} nodes {r['nodes']:7d}  cells {r['cells']:7d}  DOF {r['dofs']:7d}  "
            f"time {r['time_s']:6.1f} s  min dihedral {r['min_dihedral_deg']:5.1f} deg  "
            f"min radius ratio {r['min_radius_ratio']:.3f}  peak {r['peak_mem_mb']:.0f} MB "
            f"(process high-water mark)",
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"cases": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
