"""Benchmark image analysis on 1024 x 1024 images (issue 5).

Usage: python bench/analysis.py [--size 1024] [--rows 2000] [--json FILE]

Six-step phase shifting plus ambiguity resolution and unwrapping on an indentation-like
field (6 fringes, isoclinic winding around the masked centre, 1 % noise), and RGB search
(plain KD-tree and refined window search from one seed) with a table of ``--rows`` rows
from the synthetic white-LED colour chart. Prints times, accuracy and peak memory.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.analysis.phase import six_step
from fringekit.analysis.rgb import CalibrationTable, search, search_refined
from fringekit.analysis.unwrap import unwrap_fringe_order
from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source


def field(n: int):
    r, c = np.mgrid[:n, :n] - (n - 1) / 2
    rho = np.hypot(r, c) / n
    order = 6.0 * np.exp(-((rho / 0.22) ** 2))
    theta = np.arctan2(r, c)
    mask = (rho > 0.05) & (rho < 0.5)
    return order, theta, mask


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--size", type=int, default=1024)
    p.add_argument("--rows", type=int, default=2000)
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    n = a.size
    order, theta, mask = field(n)
    d = 2 * np.pi * order
    rng = np.random.default_rng(0)
    table = (
        1 + np.cos(d),
        1 - np.cos(d),
        1 - np.sin(2 * theta) * np.sin(d),
        1 + np.cos(2 * theta) * np.sin(d),
        1 + np.sin(2 * theta) * np.sin(d),
        1 - np.cos(2 * theta) * np.sin(d),
    )
    imgs = [np.clip(0.02 + 0.45 * t + 0.01 * rng.standard_normal(t.shape), 0, 1) for t in table]

    t0 = time.perf_counter()
    res = six_step(imgs, mask=mask)
    fo = unwrap_fringe_order(res)
    t_phase = time.perf_counter() - t0
    err = fo.order - order
    rms_phase = float(np.sqrt(np.nanmean(err[fo.reliable] ** 2)))

    lam = PSM4_ASSUMED.wavenumber_grid(31)
    o, rgb = colour_chart(PSM4_ASSUMED, light_source("LED", lam), Camera(), max_order=5.0, n=a.rows)
    tab = CalibrationTable.from_chart(o, rgb)
    lim = order <= 5.0
    img = np.stack([np.interp(order, o, rgb[:, k]) for k in range(3)], axis=-1)
    img = np.clip(img + 0.005 * rng.standard_normal(img.shape), 0, 1)
    t0 = time.perf_counter()
    plain = search(img, tab, mask=mask)
    t_plain = time.perf_counter() - t0
    seed_rc = (n // 2, int(0.95 * n))
    t0 = time.perf_counter()
    refined = search_refined(img, tab, [(seed_rc, float(order[seed_rc]))], mask=mask)
    t_ref = time.perf_counter() - t0
    sel = mask & lim & (order <= 3.0)

    def rms(x):
        return float(np.sqrt(np.nanmean(x[sel] ** 2)))

    out = {
        "pixels": n * n,
        "time_phase_unwrap_s": t_phase,
        "time_rgb_plain_s": t_plain,
        "time_rgb_refined_s": t_ref,
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "table_rows": a.rows,
        "phase_rms_fringe": rms_phase,
        "phase_reliable_fraction": float(fo.reliable.sum() / mask.sum()),
        "rgb_plain_rms_to_order3": rms(plain.order - order),
        "rgb_refined_rms_to_order3": rms(refined.order - order),
    }
    print(f"{n} x {n} px, {a.rows}-row table")
    print(
        f"  six-step + resolve + unwrap {t_phase:6.2f} s   RMS {rms_phase:.4f} fringe, "
        f"reliable {100 * out['phase_reliable_fraction']:.1f} % of the mask"
    )
    print(
        f"  RGB plain                  {t_plain:6.2f} s   RMS (N<=3) "
        f"{out['rgb_plain_rms_to_order3']:.4f}"
    )
    print(
        f"  RGB refined                {t_ref:6.2f} s   RMS (N<=3) "
        f"{out['rgb_refined_rms_to_order3']:.4f}"
    )
    print(f"  peak memory {out['peak_mem_mb']:.0f} MB")
    if a.json:
        a.json.write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
