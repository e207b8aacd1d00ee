"""Benchmark ``fringekit invert`` on held-out images rendered by full FEM solves.

Usage: python bench/invert.py [--preset coarse|reference] [--n-indenters 1 2 4 6]
       [--methods rgb mono phase] [--seed 0 1 ...] [--library DIR] [--work DIR] [--json FILE]
       [--set TABLE.KEY=VALUE ...]
       (--work default: bench/out/invert, ignored by git; --set overrides the preset's
       config for the library and the cases alike, e.g. --set mesh.h_contact_mm=0.3 for
       a refinement study)

Builds (or reuses) the library of the preset's sensor, then for each number of indenters
draws one case per seed: positions at random over the field of view at least 4.5 mm
apart (the first pair exactly 6 mm when there are two or more), Fz uniform over the library's
range (0.5-10 N for the reference preset), tangential load 0-0.8 Fz in a random
direction. Each case is solved by ``fringekit predict`` (full model, full stick; the FEM,
not the library), photographed 8-bit with 10k e- full well and 5 e- read noise, and
inverted with each method. Prints per case and in summary the Fz error (N and %),
tangential magnitude error (N and % of Fz), direction error (deg), position error (mm),
missed and spurious indenters, the time per image, and the coverage of the stated
1-sigma: for Fz, the tangential components (Fx, Fy) and the position (x, y), the
fractions of the errors within 1 and 2 sd (about 68 % and 95 % when the sd are honest);
``--json`` writes ``{"cases": [...], "coverage": {method: {quantity: ...}},
"library_build_s", "peak_mb"}``.

Presets: ``coarse`` is examples/coarse_sensor.toml, the tests' sensor (20 mm sheet,
0.6 mm contact mesh, 96 px, library 1-4 N x 5 ratios: minutes); ``reference`` is the
built-in reference sensor at 256 px with the default library (14 loads x 5 ratios: about
9 min on 2 cores; a full-model FEM case of two sheared heads took 15 min, more heads take
longer).
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import math
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.cli.main import main
from fringekit.cli.options import overrides
from fringekit.config.files import apply_overrides, load_config, to_toml
from fringekit.inversion import uncertainty
from fringekit.library.build import DEFAULT_LOADS_N, DEFAULT_RATIOS, build_library

#: the repository (the coarse preset is examples/coarse_sensor.toml)
ROOT = Path(__file__).resolve().parents[1]
PRESETS = {
    "coarse": {
        "config": ROOT / "examples" / "coarse_sensor.toml",
        "loads": (1.0, 1.4, 2.0, 2.8, 4.0),
        "ratios": DEFAULT_RATIOS,
        "fz": (1.2, 3.6),
        "half_width_mm": 3.5,
    },
    "reference": {
        "config": None,
        "loads": DEFAULT_LOADS_N,
        "ratios": DEFAULT_RATIOS,
        "fz": (0.5, 10.0),
        "half_width_mm": 8.0,
    },
}
#: The normal-load fractions of a held-out case's path (steps of about 1.4x).
NORMAL_STEPS = (0.125, 0.18, 0.25, 0.35, 0.5, 0.7, 1.0)
NOISE = {"optics.full_well_e": 10000.0, "optics.read_noise_e": 5.0}
MIN_APART_MM = 4.5
#: Failed draws in a row after which the centres placed so far are dropped (a first centre
#: near the edge of a small field can leave no room for its partner 6 mm away).
RESTART_AFTER = 1000
#: The stated 1-sigma columns of loads.csv, kept with each estimate.
SD_COLUMNS = ("sx_mm", "sy_mm", "sFx_N", "sFy_N", "sFz_N")
#: Each estimated quantity's sd column.
SD_OF = dict(zip(("x_mm", "y_mm", "Fx", "Fy", "Fz"), SD_COLUMNS, strict=True))


def draw_case(rng, n: int, preset: dict) -> list[dict]:
    """n indenters: the first pair exactly 6 mm apart, every other centre at least
    MIN_APART_MM from the rest (3.5 mm spheres plus a margin); loads and shear."""
    w = preset["half_width_mm"]
    pos: list[np.ndarray] = []
    misses = 0
    for _ in range(200000):  # rejection sampling; bounded
        if len(pos) == n:
            break
        if misses > RESTART_AFTER:  # the centres so far leave no room: draw them again
            pos, misses = [], 0
        if len(pos) == 1:
            a = rng.uniform(0, 2 * np.pi)
            p = pos[0] + 6.0 * np.array([np.cos(a), np.sin(a)])
        else:
            p = rng.uniform(-w, w, 2)
        if np.all(np.abs(p) <= w) and all(np.hypot(*(p - q)) >= MIN_APART_MM for q in pos):
            pos.append(p)
            misses = 0
        else:
            misses += 1
    else:
        raise SystemExit(f"cannot place {n} indenters {MIN_APART_MM} mm apart within +-{w} mm")
    out = []
    for p in pos:
        fz = float(rng.uniform(*preset["fz"]))
        t = float(rng.uniform(0.0, 0.8)) * fz
        a = rng.uniform(0, 2 * np.pi)
        out.append(
            {
                "x_mm": float(p[0]),
                "y_mm": float(p[1]),
                "Fz": fz,
                "Fx": t * np.cos(a),
                "Fy": t * np.sin(a),
            }
        )
    return out


def case_config(base: dict, inds: list[dict], name: str) -> dict:
    cfg = copy.deepcopy(base)
    cfg["case"] = name
    cfg["contact"]["friction"] = "stick"
    cfg["mesh"]["symmetry"] = "full"
    proto = cfg["indenter"][0]
    # under full stick the state depends on the load steps (docs/library.md, "Load path
    # and friction"): the normal load in steps of 1.4x from 1/8, then the tangential load
    # in steps of at most 0.2 of the normal load, as the library's chain takes them
    n_shear = max(1, math.ceil(max(np.hypot(d["Fx"], d["Fy"]) / d["Fz"] for d in inds) / 0.2))
    normal = list(NORMAL_STEPS) + [1.0] * n_shear
    shear = [0.0] * len(NORMAL_STEPS) + [(k + 1) / n_shear for k in range(n_shear)]
    cfg["indenter"] = [
        dict(
            proto,
            x_mm=d["x_mm"],
            y_mm=d["y_mm"],
            load_N=[f * d["Fz"] for f in normal],
            shear_N=[[t * d["Fx"], t * d["Fy"]] for t in shear],
        )
        for d in inds
    ]
    return cfg


def match(true: list[dict], est: list[dict]) -> tuple[list, int, int]:
    """Pairs (true, est) by nearest position within 1.5 mm; missed and spurious counts."""
    pairs, used = [], set()
    for t in true:
        d = [np.hypot(t["x_mm"] - e["x_mm"], t["y_mm"] - e["y_mm"]) for e in est]
        j = int(np.argmin(d)) if d else -1
        if j >= 0 and d[j] < 1.5 and j not in used:
            used.add(j)
            pairs.append((t, est[j]))
        else:
            pairs.append((t, None))
    missed = sum(e is None for _, e in pairs)
    return pairs, missed, len(est) - len(used)


def errors(t: dict, e: dict) -> dict:
    ft, fe = np.hypot(t["Fx"], t["Fy"]), np.hypot(e["Fx"], e["Fy"])
    ang = np.degrees(np.arctan2(e["Fy"], e["Fx"]) - np.arctan2(t["Fy"], t["Fx"]))
    return {
        "Fz_N": e["Fz"] - t["Fz"],
        "Fz_pct": 100 * (e["Fz"] - t["Fz"]) / t["Fz"],
        "Ft_N": fe - ft,
        "Ft_pct_of_Fz": 100 * (fe - ft) / t["Fz"],
        "direction_deg": float((ang + 180) % 360 - 180) if ft > 0.1 else None,
        "position_mm": float(np.hypot(e["x_mm"] - t["x_mm"], e["y_mm"] - t["y_mm"])),
        # the errors in units of the stated 1-sigma (loads.csv's sx_mm ... sFz_N)
        "z": {k: (e[k] - t[k]) / e[SD_OF[k]] if e[SD_OF[k]] > 0 else None for k in SD_OF},
    }


def coverage(errs: list[dict]) -> dict:
    """Per quantity (position: x and y; Fz; tangential: Fx and Fy), the number of
    normalised errors and the fractions of them within 1 and 2 of the stated sd
    (:func:`fringekit.inversion.uncertainty.coverage`)."""
    order = ("x_mm", "y_mm", "Fz", "Fx", "Fy")
    z = [[np.nan if e["z"][k] is None else e["z"][k] for k in order] for e in errs]
    return uncertainty.coverage(np.array(z, float).reshape(-1, len(order)))


def read_loads(path: Path) -> list[dict]:
    with open(path) as f:
        return [
            {
                "x_mm": float(r["x_mm"]),
                "y_mm": float(r["y_mm"]),
                "Fz": float(r["Fz_N"]),
                "Fx": float(r["Fx_N"]),
                "Fy": float(r["Fy_N"]),
                **{k: float(r[k]) for k in SD_COLUMNS},
            }
            for r in csv.DictReader(f)
        ]


def images(state: Path, method: str) -> list[str]:
    if method == "phase":
        return [str(state / "six_step" / f"step{k}.png") for k in range(1, 7)]
    return [str(state / ("white_light.png" if method == "rgb" else "dark_field.png"))]


def run_case(base, inds, name, methods, lib, work: Path, pixel_mm) -> list[dict]:
    toml = work / f"{name}.toml"
    toml.write_text(to_toml(case_config(base, inds, name)))
    t0 = time.perf_counter()
    if main(["predict", str(toml), "--out", str(work / name), "--quiet"]) != 0:
        print(f"{name}: the FEM solve failed; case skipped")
        return []
    fem_s = time.perf_counter() - t0
    state = sorted((work / name).glob("state_*"))[-1]
    out = []
    for m in methods:
        t0 = time.perf_counter()
        code = main(
            [
                "invert",
                *images(state, m),
                "--library",
                str(lib),
                "--out",
                str(work / f"{name}-{m}"),
                "--pixel-mm",
                str(pixel_mm),
                "--method",
                m,
                "--quiet",
            ]
        )
        dt = time.perf_counter() - t0
        est = read_loads(work / f"{name}-{m}" / "loads.csv") if code == 0 else []
        pairs, missed, spurious = match(inds, est)
        out.append(
            {
                "name": name,
                "method": m,
                "n_indenters": len(inds),
                "time_s": dt,
                "fem_s": fem_s,
                "exit": code,
                "missed": missed,
                "spurious": spurious,
                "indenters": [
                    {"true": t, "est": e, "errors": errors(t, e) if e else None} for t, e in pairs
                ],
            }
        )
        print(f"{name} {m}: exit {code}, {dt:.1f} s, missed {missed}, spurious {spurious}")
        for t, e in pairs:
            if e:
                er = errors(t, e)
                d = er["direction_deg"]
                print(
                    f"  Fz {t['Fz']:.2f} N: dFz {er['Fz_N']:+.3f} N ({er['Fz_pct']:+.1f} %), "
                    f"dFt {er['Ft_N']:+.3f} N ({er['Ft_pct_of_Fz']:+.1f} % of Fz), "
                    f"dir {'-' if d is None else f'{d:+.1f}'} deg, pos {er['position_mm']:.3f} mm"
                )
    return out


def summary(cases: list[dict]) -> dict:
    """Print each method's errors, and the coverage of its stated sd (:func:`coverage`),
    also for all methods together; return the coverage by method (and ``"all"``)."""
    cover = {}
    for m in sorted({c["method"] for c in cases}):
        errs = [
            i["errors"] for c in cases if c["method"] == m for i in c["indenters"] if i["errors"]
        ]
        if not errs:
            continue

        def col(k, errs=errs):
            return np.array([abs(e[k]) for e in errs if e[k] is not None])

        t = [c["time_s"] for c in cases if c["method"] == m]
        dirs = col("direction_deg")
        print(
            f"{m}: |dFz| median {np.median(col('Fz_pct')):.1f} % max {col('Fz_pct').max():.1f} %;"
            f" |dFt| median {np.median(col('Ft_pct_of_Fz')):.1f} % of Fz; direction median "
            f"{np.median(dirs) if len(dirs) else float('nan'):.1f} deg; "
            f"position median {np.median(col('position_mm')):.3f} mm max "
            f"{col('position_mm').max():.3f} mm; missed "
            f"{sum(c['missed'] for c in cases if c['method'] == m)}, spurious "
            f"{sum(c['spurious'] for c in cases if c['method'] == m)}; "
            f"time per image median {np.median(t):.1f} s"
        )
        cover[m] = coverage(errs)
    every = [i["errors"] for c in cases for i in c["indenters"] if i["errors"]]
    if every:
        cover["all"] = coverage(every)
    for m, cov in cover.items():
        print(
            f"{m}: within 1 / 2 sd: "
            + "; ".join(
                f"{q} {v['within_1sd']:.0%} / {v['within_2sd']:.0%} of {v['n']} "
                f"(median |err|/sd {v['median_z']:.2g})"
                for q, v in cov.items()
                if v["n"]
            )
        )
    return cover


def main_bench(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", choices=sorted(PRESETS), default="coarse")
    ap.add_argument("--n-indenters", nargs="+", type=int, default=[1, 2, 4, 6])
    ap.add_argument("--methods", nargs="+", default=["rgb", "mono", "phase"])
    ap.add_argument("--seed", nargs="+", type=int, default=[0])
    ap.add_argument("--library", default=None, help="library folder (built when missing)")
    ap.add_argument("--work", default="bench/out/invert")
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="override one value of the preset's config (repeatable)",
    )
    a = ap.parse_args(argv)
    preset = PRESETS[a.preset]
    base = overrides(None, a.set, apply_overrides(load_config(preset["config"]), NOISE))
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    lib = Path(a.library or work / f"library-{a.preset}")
    t0 = time.perf_counter()
    build_library(base, lib, loads=preset["loads"], ratios=preset["ratios"], progress=True)
    build_s = time.perf_counter() - t0
    print(f"library {lib}: {build_s:.1f} s (0 when reused)")
    pixel_mm = base["optics"]["field_of_view_mm"] / base["optics"]["pixels"]
    cases = []
    for seed in a.seed:  # one draw per seed (the case names say the seed when several)
        rng = np.random.default_rng(seed)
        tag = f"{a.preset}-s{seed}" if len(a.seed) > 1 else a.preset
        for n in a.n_indenters:
            inds = draw_case(rng, n, preset)
            cases += run_case(base, inds, f"{tag}-{n}", a.methods, lib, work, pixel_mm)
    cover = summary(cases)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory {peak:.0f} MB")
    if a.json:
        Path(a.json).write_text(
            json.dumps(
                {"cases": cases, "coverage": cover, "library_build_s": build_s, "peak_mb": peak},
                indent=1,
                default=float,
            )
        )


if __name__ == "__main__":
    main_bench()
