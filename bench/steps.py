"""Full stick and the load steps: the reference case's answer against how its path is cut.

Under full stick a point of the sheet sticks to the sphere where it first touches it, so
the state depends on the load path but should not depend on how a monotone path is cut
into load states. The reference case (one 3.5 mm sphere at 8 N, the default mesh) is
solved under full stick with 8 N reached in n equal load states for each n of
``--states`` (default 1 4 16 40); with ``--shear T`` the n normal states are followed by
n states of tangential load up to T newtons along x (a half model). Each solve prints its
size, Newton iterations, time split and peak memory, and every later one is compared with
the first: depth and contact radius (%), the indenter's tangential displacement, and the
rendered fringe-order maps beyond 1.3 contact radii (RMS, max, and the max of the
"folded" difference, that of each order's distance to its nearest integer: what the
dark-field image shows, blind to a pixel whose total order took the other branch at a
half or whole order). ``--set KEY=VALUE`` changes the config (``contact.penetration_tol``,
the mesh sizes). Each run uses its own empty cache, so the solve times are real: about
7 min for the default states and 20 min with ``--shear 2`` and states 1 4 16 on 2 cores.

    python bench/steps.py [--states 1 4 16 40] [--shear T] [--set KEY=VALUE] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from fringekit.config import as_config
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import fringe_order_map

LOAD_N = 8.0


def path_overrides(n: int, shear: float) -> dict:
    """Config overrides for 8 N in ``n`` equal states, then ``shear`` N along x in ``n``."""
    normal = [LOAD_N * (k + 1) / n for k in range(n)]
    if shear <= 0:
        return {"contact.friction": "stick", "indenter.load_N": normal}
    tangential = [[0.0, 0.0]] * n + [[shear * (k + 1) / n, 0.0] for k in range(n)]
    return {
        "contact.friction": "stick",
        "indenter.load_N": normal + [LOAD_N] * n,
        "indenter.shear_N": tangential,
    }


def run(overrides: dict) -> tuple[dict, np.ndarray, tuple]:
    """Solve and render the reference case with ``overrides``: (figures, order, centre)."""
    cfg = as_config("reference").replace(overrides)
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        _, sols, stats, failure = solve_config(cfg.data, cache_dir=cache, progress=False)
        t_solve = time.perf_counter() - t0
        if failure is not None:
            raise SystemExit(f"bench/steps.py: the solve failed: {failure}")
        t0 = time.perf_counter()
        order, _, centres = fringe_order_map(sols[-1], cfg.data)
        t_render = time.perf_counter() - t0
    ind = sols[-1].indenters[0]
    figures = {
        "states": len(sols),
        "dofs": stats.dofs,
        "newton_iterations": int(sum(stats.iterations_per_state)),
        "solve_s": t_solve,
        "render_s": t_render,
        "pixel_mm": cfg.data["optics"]["field_of_view_mm"] / order.shape[1],
        "depth_mm": ind.depth * 1e3,
        "contact_radius_mm": ind.contact_radius * 1e3,
        "tangential_displacement_um": float(ind.centre[0]) * 1e6,
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    return figures, order, centres[0]


def folded(order: np.ndarray) -> np.ndarray:
    """Each fringe order's distance to its nearest integer (0 to 0.5)."""
    return np.abs((order + 0.5) % 1.0 - 0.5)


def compare(first: dict, first_map: np.ndarray, centre, row: dict, m: np.ndarray) -> dict:
    """One solve against the first: depth, contact radius, displacement and maps."""
    rows, cols = np.mgrid[: m.shape[0], : m.shape[1]]
    pixel_mm = first["pixel_mm"]
    r = np.hypot(rows - centre[0], cols - centre[1]) * pixel_mm
    ok = (r > 1.3 * first["contact_radius_mm"]) & np.isfinite(m) & np.isfinite(first_map)
    d = m[ok] - first_map[ok]
    return {
        "depth_pct": 100 * (row["depth_mm"] / first["depth_mm"] - 1),
        "contact_radius_pct": 100 * (row["contact_radius_mm"] / first["contact_radius_mm"] - 1),
        "tangential_displacement_um": row["tangential_displacement_um"]
        - first["tangential_displacement_um"],
        "map_rms": float(np.sqrt(np.mean(d * d))),
        "map_max": float(np.abs(d).max()),
        "map_folded_max": float(np.abs(folded(m[ok]) - folded(first_map[ok])).max()),
    }


def _setting(text: str) -> tuple[str, float]:
    key, sep, value = text.partition("=")
    try:
        return key, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--set {text!r} is not allowed; give KEY=NUMBER, e.g. contact.penetration_tol=0.003"
        ) from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--states", type=int, nargs="+", default=[1, 4, 16, 40])
    ap.add_argument("--shear", type=float, default=0.0, help="tangential load after 8 N (N)")
    ap.add_argument("--set", type=_setting, action="append", default=[], dest="settings")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if min(args.states) < 1:
        ap.error(f"--states {args.states} is not allowed; give counts >= 1")
    rows, first = [], None
    for n in args.states:
        row, order, centre = run({**path_overrides(n, args.shear), **dict(args.settings)})
        if first is None:
            first = (order, centre)
        else:
            row["vs_first"] = compare(rows[0], first[0], first[1], row, order)
        rows.append(row)
        print(
            f"{n} state(s) a leg: {row['dofs']} DOF, {row['newton_iterations']} Newton "
            f"iterations, solve {row['solve_s']:.1f} s, render {row['render_s']:.1f} s, peak "
            f"{row['peak_mem_mb']:.0f} MB; depth {row['depth_mm']:.5f} mm, contact radius "
            f"{row['contact_radius_mm']:.4f} mm, tangential displacement "
            f"{row['tangential_displacement_um']:.2f} um",
            flush=True,
        )
        if "vs_first" in row:
            v = row["vs_first"]
            print(
                f"   against {args.states[0]}: depth {v['depth_pct']:+.3f} %, contact radius "
                f"{v['contact_radius_pct']:+.3f} %, tangential displacement "
                f"{v['tangential_displacement_um']:+.2f} um; order beyond 1.3 a RMS "
                f"{v['map_rms']:.4f} max {v['map_max']:.3f} folded max {v['map_folded_max']:.4f}",
                flush=True,
            )
    if args.json:
        args.json.write_text(
            json.dumps({"shear_N": args.shear, "settings": args.settings, "runs": rows}, indent=2)
        )


if __name__ == "__main__":
    main()
