"""``fringekit track``: every contact's load vector through a video, a folder of frames
or a live camera (:func:`fringekit.tracking.track`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fringekit.cli.options import (
    PIXEL_MM,
    at_least_one,
    in_range,
    origin_px_option,
    positive,
    residual_steps_option,
)
from fringekit.tracking.run import run_track
from fringekit.tracking.tracker import TRACK_STRIDE

__all__ = ["add_parser", "run"]


def add_parser(sub) -> None:
    tr = sub.add_parser("track", help="every contact's load through a video or camera stream")
    tr.add_argument(
        "source", help="a folder of frames, a video file (mp4, avi, mkv, mov) or camera:N"
    )
    tr.add_argument("--library", required=True, help="library folder (fringekit library build)")
    tr.add_argument(
        "--out", default="fringekit-out/track", help="output folder (default fringekit-out/track)"
    )
    tr.add_argument(
        "--pixel-mm",
        type=in_range(PIXEL_MM),
        default=None,
        help="pixel pitch on the sheet (mm); required without --sensor",
    )
    tr.add_argument(
        "--method",
        choices=("rgb", "mono", "phase"),
        default=None,
        help="default: rgb for colour frames, mono for grey ones; phase: every six frames in "
        "a row are one load state's six phase steps",
    )
    origin_px_option(tr)
    tr.add_argument(
        "--sensor",
        default=None,
        help="the sensor file: SENSOR.json of fringekit sensor calibrate (or of sensor "
        "init, a config with nothing fitted); default: the library's config",
    )
    tr.add_argument(
        "--reference",
        nargs="+",
        default=None,
        metavar="FRAME",
        help="frame(s) of the sensor at rest in the stream's light: their light (glare, "
        "stray light) is taken off every frame, in place of a sensor file's rest map; "
        "for phase, the rest's six steps: the sheet's residual retarder goes into the model",
    )
    residual_steps_option(tr)
    tr.add_argument(
        "--stride",
        type=at_least_one,
        default=TRACK_STRIDE,
        help=f"fit every STRIDE-th pixel in both directions per frame (default {TRACK_STRIDE})",
    )
    tr.add_argument("--fps", type=positive, default=None, help="frame rate of a folder of frames")
    tr.add_argument("--max-frames", type=at_least_one, default=None, help="stop after N frames")
    tr.add_argument(
        "--video", action="store_true", help="also write track.mp4 (frames with overlay)"
    )
    tr.add_argument("--show", action="store_true", help="a live window with the overlay")
    tr.add_argument("--quiet", action="store_true", help="no progress bar")
    tr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    s = run_track(
        args.source,
        args.library,
        Path(args.out),
        pixel_mm=args.pixel_mm,
        origin_px=args.origin_px,
        method=args.method,
        sensor=args.sensor,
        reference=args.reference,
        residual_steps=args.residual_steps,
        stride=args.stride,
        fps=args.fps,
        max_frames=args.max_frames,
        video=args.video,
        show=args.show,
        progress=not args.quiet,
    )
    for w in s["warnings"]:
        print(f"fringekit track: warning: {w}", file=sys.stderr)
    if not args.quiet:
        fps = s["fps_achieved"]
        print(
            f"fringekit track: {s['frames_solved']} frame(s), {len(s['contacts'])} contact(s), "
            f"{fps:.1f} frames/s -> {args.out}/loads.csv"
            if fps
            else f"fringekit track: no frame solved -> {args.out}"
        )
    stop = s["stopped"]
    if stop is not None:
        print(
            f"fringekit track: stopped after {stop['after_frames']} frame(s): {stop['reason']} "
            f"(the frames solved are in {args.out})",
            file=sys.stderr,
        )
        return 130 if stop["reason"].startswith("interrupted") else 2
    video_error = (s.get("video") or {}).get("error") or ""
    return 130 if video_error.startswith("interrupted") else 0
