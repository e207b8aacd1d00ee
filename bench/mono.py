"""Benchmark one-photograph analysis and disc calibration from photographs.

Usage: python bench/mono.py [--rows 2000 --cols 3000] [--disc-px 1000] [--json FILE]

- ``mono``: the indent-like order field (:func:`optics.indent_field`, 0.3 at the border
  to 2.9, masked contact) photographed once in dark field through the realistic model (residual
  birefringence 0.05 rad RMS, 30 % vignetting, 2 % glare, 8-bit, 10k e- full well, 5 e-
  read noise, JPEG 90) and ordered by :func:`analysis.mono_order`;
- ``disc``: Frocht's disc (40 mm, f_sigma 7000 N/m, residual order 0.5) photographed at
  ``--disc-px`` square and fitted by :func:`fringekit.calibrate.disc_photo.fit_disc_photos` from
  one photograph and from a series of five, after :func:`analysis.disc_by_symmetry` and
  :func:`analysis.find_discs`.

Prints the problem size, the time of each stage, the error against the truth and peak
memory; ``--json`` writes the same.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.analysis import disc_by_symmetry, find_discs, mono_order, normalise
from fringekit.calibrate.disc_photo import DiscGeometry, DiscImage, fit_disc_photos
from fringekit.optics import (
    Camera,
    DiametralDisc,
    PhotoModel,
    dark_field_circular,
    indent_field,
    photograph,
    retarder,
)

CAMERA = Camera(exposure=0.9, full_well=10000.0, read_noise=5.0, bit_depth=8)
MODEL = PhotoModel(residual_rms_rad=0.05, vignetting=0.3, glare=0.02, jpeg_quality=90, seed=7)
D, T, F_SIGMA = 0.04, 0.006, 7000.0


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def mono_case(rows: int, cols: int) -> dict:
    order, q, mask = indent_field(rows, cols, core=0.09)
    t0 = time.perf_counter()
    img = photograph(q, dark_field_circular(), CAMERA, MODEL, seed=1)
    t1 = time.perf_counter()
    res = mono_order(normalise(img).data, mask=mask, anchor_order=0.3)
    t2 = time.perf_counter()
    ok = res.reliable
    err = np.abs(res.order - order)[ok]
    return {
        "case": "mono",
        "rows": rows,
        "cols": cols,
        "render_s": t1 - t0,
        "analyse_s": t2 - t1,
        "bands": res.info["bands"],
        "order_rms": float(np.sqrt(np.mean(err**2))),
        "order_p99": float(np.percentile(err, 99)),
        "order_max": float(err.max()),
        "reliable_share": float(ok.sum() / mask.sum()),
        "peak_mem_mb": _peak_mb(),
    }


def _disc_photo(n: int, P: float, seed: int) -> np.ndarray:
    R = 0.4 * n
    r, c = np.mgrid[:n, :n].astype(float)
    px = D / (2 * R)
    xy = np.stack([(c - n / 2) * px, (n / 2 - r) * px, np.zeros_like(r)], -1)
    inside = np.hypot(xy[..., 0], xy[..., 1]) < D / 2
    s = np.nan_to_num(DiametralDisc(P=P, D=D, t=T).stress(xy))
    N = T * np.hypot(s[..., 0, 0] - s[..., 1, 1], 2 * s[..., 0, 1]) / F_SIGMA
    q = retarder(2 * np.pi * np.where(inside, N + 0.5, 0.0), np.zeros_like(N))
    return normalise(photograph(q, dark_field_circular(), CAMERA, MODEL, seed=seed)).data


def disc_case(n: int, loads) -> dict:
    t0 = time.perf_counter()
    photos = [_disc_photo(n, P, k + 1) for k, P in enumerate(loads)]
    t1 = time.perf_counter()
    outline = find_discs(photos[-1], count=1)
    t2 = time.perf_counter()
    g = disc_by_symmetry(photos[-1])
    t3 = time.perf_counter()
    images = [DiscImage(p, P) for p, P in zip(photos, loads, strict=True)]
    geometry = DiscGeometry(g.row, g.col, g.radius)
    fit = fit_disc_photos(images, geometry, diameter=D, thickness=T)
    t4 = time.perf_counter()
    return {
        "case": f"disc x{len(loads)}",
        "rows": n,
        "cols": n,
        "photos": len(loads),
        "render_s": t1 - t0,
        "find_discs_s": t2 - t1,
        "outline_support": outline[0].support if outline else 0.0,
        "symmetry_s": t3 - t2,
        "fit_s": t4 - t3,
        "model_evaluations": fit.evaluations,
        "f_sigma_error_pct": 100 * (fit.f_sigma / F_SIGMA - 1),
        "f_sigma_sd_pct": 100 * fit.f_sigma_sd / F_SIGMA,
        "offset_order": fit.offset_order,
        "peak_mem_mb": _peak_mb(),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=int, default=2000)
    p.add_argument("--cols", type=int, default=3000)
    p.add_argument("--disc-px", type=int, default=1000)
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    out = [mono_case(a.rows, a.cols)]
    m = out[0]
    print(
        f"mono  {a.rows} x {a.cols}: render {m['render_s']:.1f} s, analyse {m['analyse_s']:.1f} s,"
        f" {m['bands']} bands, order RMS {m['order_rms']:.4f} p99 {m['order_p99']:.3f} max "
        f"{m['order_max']:.3f}, reliable {100 * m['reliable_share']:.1f} %, peak "
        f"{m['peak_mem_mb']:.0f} MB",
        flush=True,
    )
    for loads in ([250.0], [80.0, 150.0, 220.0, 290.0, 360.0]):
        d = disc_case(a.disc_px, loads)
        out.append(d)
        print(
            f"{d['case']:7s} {a.disc_px} px: render {d['render_s']:.1f} s, outline "
            f"{d['find_discs_s']:.1f} s (support {d['outline_support']:.2f}), symmetry "
            f"{d['symmetry_s']:.2f} s, fit {d['fit_s']:.1f} s ({d['model_evaluations']} model "
            f"images); f_sigma {d['f_sigma_error_pct']:+.2f} % (sd {d['f_sigma_sd_pct']:.2f} %),"
            f" offset {d['offset_order']:.3f}; peak {d['peak_mem_mb']:.0f} MB",
            flush=True,
        )
    if a.json:
        a.json.write_text(json.dumps({"cases": out}, indent=2))


if __name__ == "__main__":
    main()
