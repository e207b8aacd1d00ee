"""Benchmark the six-step analysis on photograph-like images of a known order field.

Usage: python bench/photo.py [--rows 2000 --cols 3000] [--json FILE]

An indent-like retarder field (order 0.3 at the border to 2.9 in the middle, radial
axes, a masked contact zone) is photographed through the six arrangements with
``optics.photo``: ideal, realistic (residual birefringence 0.05 rad RMS, 30 % vignetting,
2 % glare, shot and read noise, JPEG 90) and harsh (0.2 rad, 50 %, 5 %, JPEG 70). For each
it prints the image size, the time to render, to run the six-step formulas and each of
the two fold resolutions (isoclinic continuity, fringe count), and for each resolution
the order RMS and maximum error on reliable pixels and the reliable share of the pixels
with data; and peak memory.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.analysis import (
    count_fringe_order,
    resolve_ambiguity,
    six_step,
    unwrap_fringe_order,
)
from fringekit.optics import (
    Camera,
    PhotoModel,
    indent_field,
    photograph,
    six_step_arrangements,
)

MODELS = {
    "ideal": PhotoModel(),
    "realistic": PhotoModel(
        residual_rms_rad=0.05, vignetting=0.3, glare=0.02, jpeg_quality=90, seed=7
    ),
    "harsh": PhotoModel(residual_rms_rad=0.2, vignetting=0.5, glare=0.05, jpeg_quality=70, seed=7),
}
CAMERA = Camera(exposure=0.9, full_well=20000.0, read_noise=10.0)


def _score(fo, order, mask) -> dict:
    ok = fo.reliable & mask
    err = np.abs(fo.order[ok] - order[ok])
    return {
        "order_rms": float(np.sqrt(np.mean(err**2))) if err.size else None,
        "order_max": float(err.max()) if err.size else None,
        "reliable_share": float(ok.sum() / mask.sum()),
    }


def run(rows: int, cols: int, name: str) -> dict:
    order, q, mask = indent_field(rows, cols)
    t0 = time.perf_counter()
    frames = [
        photograph(q, a, CAMERA, MODELS[name], seed=k).astype(float) / 255
        for k, a in enumerate(six_step_arrangements())
    ]
    t1 = time.perf_counter()
    res = six_step(frames, mask=mask)
    t2 = time.perf_counter()
    iso = unwrap_fringe_order(res, resolve_ambiguity(res), anchor_order=0.3)
    t3 = time.perf_counter()
    cnt = count_fringe_order(res, anchor_order=0.3)
    t4 = time.perf_counter()
    return {
        "model": name,
        "rows": rows,
        "cols": cols,
        "render_s": t1 - t0,
        "six_step_s": t2 - t1,
        "fold_isoclinic_s": t3 - t2,
        "fold_count_s": t4 - t3,
        "isoclinic": _score(iso, order, mask),
        "count": _score(cnt, order, mask),
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=int, default=2000)
    p.add_argument("--cols", type=int, default=3000)
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    out = []
    for name in MODELS:
        r = run(a.rows, a.cols, name)
        out.append(r)
        print(
            f"{name:9s} {r['rows']} x {r['cols']}  render {r['render_s']:.1f} s  six-step "
            f"{r['six_step_s']:.1f} s  peak {r['peak_mem_mb']:.0f} MB",
            flush=True,
        )
        for fold in ("isoclinic", "count"):
            f = r[fold]
            print(
                f"    fold {fold:9s} {r[f'fold_{fold}_s']:.1f} s  order RMS {f['order_rms']:.4f}"
                f"  max {f['order_max']:.3f}  reliable {100 * f['reliable_share']:.1f} %",
                flush=True,
            )
    if a.json:
        a.json.write_text(json.dumps({"cases": out}, indent=2))


if __name__ == "__main__":
    main()
