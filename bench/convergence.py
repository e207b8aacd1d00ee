"""Mesh convergence of the reference case: which mesh is fine enough?

The reference indenter (3.5 mm, 8 N vertical, load path 1..8 N, quarter model) is solved
on meshes that differ only in the edge length under the indenter (``--h-contact-mm``,
default 0.6 0.4 0.3; the sheet's layers refine with it unless ``--h-layer-mm`` is
given), made by the deterministic layered mesher or, with ``--mesher tetwild``, by
fTetWild (which follows the request only roughly; the median lateral edge under the
indenter is printed for both). For each it prints DOF, solve time, the 8 N depth and
contact radius, the through-thickness integral
S(r) = int (s_rr - s_tt) dz (N/mm) along y = 0 and the rotation-free fringe order it
gives in reflection, N(r) = 2 |S(r)| / f_sigma (PSM-4, assumed f_sigma), and the change
of each from the next coarser mesh. The load is axisymmetric, so S must not depend on the
polar angle: the spread of N over 13 angles 0..90 deg on each circle (max - min) is the
mesh's faceting, as a photoelastician sees it in the rings' polygonal kinks.

    python bench/convergence.py [--h-contact-mm 0.6 0.4 0.3] [--h-sheet-mm 2] [--h-layer-mm H]
                                [--mesher layered|tetwild] [--json FILE]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.fea import Indenter, solve
from fringekit.meshes import MeshSpec, Sizing, build_mesh
from fringekit.optics import PSM4_ASSUMED

_spec = importlib.util.spec_from_file_location("bench_fea", Path(__file__).with_name("fea.py"))
_bench_fea = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_bench_fea)

RADII_MM = (1.5, 2.0, 2.5, 3.0, 4.0, 6.0)


ANGLES_DEG = np.linspace(0.0, 90.0, 13)


def run(
    h_mm: float, mesher: str = "layered", h_sheet_mm: float = 2.0, h_layer_mm: float | None = None
) -> dict:
    sizing = Sizing(
        h_contact=h_mm * 1e-3,
        refine_radius=2e-3,
        h_sheet=h_sheet_mm * 1e-3,
        h_far=8e-3,
        h_layer=(h_mm if h_layer_mm is None else h_layer_mm) * 1e-3,
    )
    mesh = build_mesh(MeshSpec(sizing=sizing, symmetry="quarter", mesher=mesher))
    t0 = time.perf_counter()
    sols, stats = solve(mesh, [Indenter(normal_force=tuple(float(f) for f in range(1, 9)))])
    elapsed = time.perf_counter() - t0
    ind = sols[-1].indenters[0]
    tri = mesh.facet_nodes("contact")[:, :3]
    P = mesh.points[tri]
    near = np.hypot(P[:, :, 0].mean(1), P[:, :, 1].mean(1)) < 1.5e-3
    edge = np.linalg.norm(P[:, 1] - P[:, 0], axis=1)[near]
    # S on each circle at every angle; the first angle (0 deg) is the y = 0 line of S(r)
    S_by_angle = [_bench_fea.through_thickness_S(sols[-1], RADII_MM, a) for a in ANGLES_DEG]
    S = S_by_angle[0]
    orders = 2e3 * np.abs([list(Sa.values()) for Sa in S_by_angle]) / PSM4_ASSUMED.f_sigma
    return {
        "mesher": mesher,
        "h_contact_mm": h_mm,
        "median_edge_under_indenter_mm": float(np.median(edge)) * 1e3,
        "dofs": stats.dofs,
        "time_s": elapsed,
        "newton_iterations": sum(stats.iterations_per_state),
        "depth_8N_mm": ind.depth * 1e3,
        "contact_radius_8N_mm": ind.contact_radius * 1e3,
        "S_r_N_per_mm": S,
        "order_r": dict(zip(S, orders[0].tolist(), strict=True)),
        "order_spread_over_angle": dict(
            zip(S, (orders.max(0) - orders.min(0)).tolist(), strict=True)
        ),
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h-contact-mm", type=float, nargs="+", default=[0.6, 0.4, 0.3])
    ap.add_argument("--h-sheet-mm", type=float, default=2.0, help="largest edge in the sheet")
    ap.add_argument(
        "--h-layer-mm",
        type=float,
        default=None,
        help="thinnest sheet layer (default: each h_contact, so the layers refine with it)",
    )
    ap.add_argument("--mesher", choices=("layered", "tetwild"), default="layered")
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    for h in sorted(args.h_contact_mm, reverse=True):
        r = run(h, args.mesher, args.h_sheet_mm, args.h_layer_mm)
        prev = rows[-1] if rows else None
        rows.append(r)
        d = ""
        if prev:
            dd = 100 * (r["depth_8N_mm"] / prev["depth_8N_mm"] - 1)
            da = 100 * (r["contact_radius_8N_mm"] / prev["contact_radius_8N_mm"] - 1)
            d = f"  (depth {dd:+.2f} %, contact radius {da:+.2f} % from h = {prev['h_contact_mm']})"
        print(
            f"h_contact {h:.2f} mm (edges {r['median_edge_under_indenter_mm']:.2f} mm)  "
            f"DOF {r['dofs']:7d}  {r['time_s']:6.1f} s  "
            f"{r['newton_iterations']} Newton iterations  depth {r['depth_8N_mm']:.4f} mm  "
            f"contact radius {r['contact_radius_8N_mm']:.4f} mm{d}"
        )
        line = "   N(r) = 2|S|/f_sigma: " + "  ".join(
            f"{k} mm {v:.3f}" + (f" ({v - prev['order_r'][k]:+.3f})" if prev else "")
            for k, v in r["order_r"].items()
        )
        print(line)
        print(
            "   spread of N over angle (max - min): "
            + "  ".join(f"{k} mm {v:.3f}" for k, v in r["order_spread_over_angle"].items()),
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps({"meshes": rows}, indent=2))


if __name__ == "__main__":
    main()
