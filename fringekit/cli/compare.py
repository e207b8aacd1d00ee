"""``fringekit compare``: a prediction against a measurement: registration, residual maps and
statistics.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from fringekit.cli.options import (
    PIXEL_MM,
    ROTATION_DEG,
    finite,
    in_range,
)
from fringekit.measurement.compare import run_compare

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    co = sub.add_parser("compare", help="prediction vs measurement: residuals and figures")
    co.add_argument("prediction", help="predict output folder or maps.npz")
    co.add_argument("measurement", help="analyze output folder or maps.npz")
    co.add_argument("--out", default=None, help="output folder (default fringekit-out/compare)")
    co.add_argument("--predicted-pixel-mm", type=in_range(PIXEL_MM), default=None)
    co.add_argument("--measured-pixel-mm", type=in_range(PIXEL_MM), default=None)
    co.add_argument("--centre-measured", nargs=2, type=finite, metavar=("ROW", "COL"))
    co.add_argument("--rotation-deg", type=in_range(ROTATION_DEG), default=0.0)
    co.add_argument("--quiet", action="store_true")
    co.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out or "fringekit-out/compare")
    s = run_compare(
        args.prediction,
        args.measurement,
        out,
        predicted_pixel_size=(args.predicted_pixel_mm or 0) * 1e-3 or None,
        measured_pixel_size=(args.measured_pixel_mm or 0) * 1e-3 or None,
        centre_measured=tuple(args.centre_measured) if args.centre_measured else None,
        rotation_deg=args.rotation_deg,
    )
    if not args.quiet:
        print(
            f"fringekit compare: residual RMS {s['rms_fringe']:.3g} fringe, 95th percentile of "
            f"|residual| {s['p95_fringe']:.3g} fringe, over {s['pixels']} pixels; results in "
            f"{out}/"
        )
    return 0
