"""Faceted rings of the reference case: the rendered fringe order on circles, per mesh.

The reference case (one 3.5 mm sphere at 8 N, quarter model) is solved on each mesh given
as ``H_CONTACT/H_LAYER`` in mm (``--mesh``, default ``0.6/0 0.3/0.6``: the default mesh
before 2026-11-27 and the default now) and rendered as ``fringekit predict`` renders it
(256 px over 20 mm). On circles about the axis at 1.5-6 mm the order is read bilinearly
at 720 angles: its mean, and its spread (max - min), which is zero for an axisymmetric
load on a perfect mesh and is the faceting a photoelastician sees. The last mesh listed is
the comparison for the others: the change of mean order on each circle and the RMS / max
difference of the order maps beyond 1.3 contact radii (1.54-6 mm). ``--reference`` adds
the finest mesh of ``docs/validation.md`` as the last one (0.2 mm, 10 layers, 1 mm in the
sheet, 2.5 mm refined zone growing 0.25 per mm, 8 N in 4 states: about 12 min and 4 GB on
2 cores). Each run uses its own empty cache, so the solve times are real.

    python bench/rings.py [--mesh 0.6/0 0.3/0.6] [--reference] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from fringekit.analysis import circle_profile
from fringekit.config import as_config
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import fringe_order_map

RADII_MM = (1.5, 2.0, 3.0, 4.0, 5.0, 6.0)
N_ANGLES = 720
#: The finest mesh of docs/validation.md, solved in 4 load states (one fails to converge).
REFERENCE = {
    "mesh.h_contact_mm": 0.2,
    "mesh.h_layer_mm": 0.3,
    "mesh.h_sheet_mm": 1.0,
    "mesh.refine_radius_mm": 2.5,
    "mesh.growth": 0.25,
    "indenter.load_N": [2.0, 4.0, 6.0, 8.0],
}


def run(overrides: dict) -> tuple[dict, np.ndarray]:
    """Solve and render the reference case with ``overrides``: (figures, order map)."""
    cfg = as_config("reference").replace(overrides)
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        _, sols, stats, failure = solve_config(cfg.data, cache_dir=cache, progress=False)
        t_solve = time.perf_counter() - t0
        if failure is not None:
            raise SystemExit(f"bench/rings.py: the solve failed: {failure}")
        t0 = time.perf_counter()
        order, _, centres = fringe_order_map(sols[-1], cfg.data)
        t_render = time.perf_counter() - t0
    pixel_mm = cfg.data["optics"]["field_of_view_mm"] / order.shape[1]
    vals = np.array(
        [circle_profile(order, centres[0], r, pixel_size=pixel_mm, n=N_ANGLES)[1] for r in RADII_MM]
    )
    ind = sols[-1].indenters[0]
    figures = {
        "overrides": overrides,
        "dofs": stats.dofs,
        "solve_s": t_solve,
        "render_s": t_render,
        "pixel_mm": pixel_mm,
        "depth_mm": ind.depth * 1e3,
        "contact_radius_mm": ind.contact_radius * 1e3,
        "mean_order": dict(zip(map(str, RADII_MM), vals.mean(axis=1).tolist(), strict=True)),
        "spread": dict(
            zip(map(str, RADII_MM), (vals.max(axis=1) - vals.min(axis=1)).tolist(), strict=True)
        ),
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    return figures, order


def _mesh(text: str) -> dict:
    try:
        h, layer = (float(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--mesh {text!r} is not allowed; give H_CONTACT/H_LAYER in mm, e.g. 0.3/0.6"
        ) from None
    return {"mesh.h_contact_mm": h, "mesh.h_layer_mm": layer}


def _compare(rows: list, maps: list) -> None:
    """Each mesh against the last: mean order per circle, and the maps beyond 1.3 a."""
    last, ref = rows[-1], maps[-1]
    px = ref.shape[0]
    pixel_mm = last["pixel_mm"]
    r, c = np.mgrid[:px, :px]
    rr = np.hypot((c - (px - 1) / 2) * pixel_mm, ((px - 1) / 2 - r) * pixel_mm)
    ring = (rr > 1.3 * last["contact_radius_mm"]) & (rr < 6.0)
    for row, m in zip(rows[:-1], maps[:-1], strict=True):
        ok = ring & np.isfinite(m) & np.isfinite(ref)
        d = m[ok] - ref[ok]
        row["vs_last"] = {
            "mean_order_change": {
                k: row["mean_order"][k] - v for k, v in last["mean_order"].items()
            },
            "map_rms": float(np.sqrt(np.mean(d * d))),
            "map_max": float(np.abs(d).max()),
            "contact_radius_pct": 100 * (row["contact_radius_mm"] / last["contact_radius_mm"] - 1),
        }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", type=_mesh, nargs="+", default=[_mesh("0.6/0"), _mesh("0.3/0.6")])
    ap.add_argument("--reference", action="store_true", help="add the finest mesh (~12 min)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    meshes = args.mesh + ([REFERENCE] if args.reference else [])
    rows, maps = [], []
    for overrides in meshes:
        figures, order = run(overrides)
        rows.append(figures)
        maps.append(order)
        print(
            f"{overrides}: {figures['dofs']} DOF, solve {figures['solve_s']:.1f} s, render "
            f"{figures['render_s']:.1f} s, peak {figures['peak_mem_mb']:.0f} MB; depth "
            f"{figures['depth_mm']:.4f} mm, contact radius {figures['contact_radius_mm']:.4f} mm"
        )
        print(
            "   mean order: "
            + "  ".join(f"{k} mm {v:.3f}" for k, v in figures["mean_order"].items())
        )
        print(
            "   spread:     " + "  ".join(f"{k} mm {v:.3f}" for k, v in figures["spread"].items()),
            flush=True,
        )
    if len(rows) > 1:
        _compare(rows, maps)
        for row in rows[:-1]:
            v = row["vs_last"]
            print(
                f"{row['overrides']} against the last mesh: order map beyond 1.3 a (to 6 mm) "
                f"RMS {v['map_rms']:.4f} max {v['map_max']:.4f}; contact radius "
                f"{v['contact_radius_pct']:+.2f} %; mean order "
                + "  ".join(f"{k} {d:+.3f}" for k, d in v["mean_order_change"].items())
            )
    if args.json:
        args.json.write_text(json.dumps({"meshes": rows}, indent=2))


if __name__ == "__main__":
    main()
