"""Benchmark ``fringekit track`` on a stream of known loads: library-synthesised (speed and
identity; the default) or FEM-rendered (accuracy).

Usage: python bench/track.py [--sequence library|fem] [--frames N] [--pixels 256]
       [--methods mono rgb phase] [--stride 4] [--noise 0.005] [--invert-every 50]
       [--cold-starts 0] [--library DIR] [--work DIR] [--json FILE] [--show]
       (--work default: bench/out/track, ignored by git)

``--sequence fem`` (sequence (a) of the tracking issue, on the coarse sensor, whose
library the bench uses, not on the reference sensor to 8 N as the issue asks: its
library takes hours to build on 2 cores and its FEM frames minutes each): one
``predict`` run under full stick, every load state a frame,
FRAMES of them: two contacts (3.5 mm spheres 6.7 mm apart) ramping Fz together from 0.5
to 3.4 N (TOP_N, inside the library's 4 N) over the first 60 % of the frames, then a
tangential load on one of them ramping along +x to 0.4 of its normal load. The frames
are the predicted 8-bit images (dark field, white light) with camera noise NOISE (of
full scale, a seed per frame) added and quantised again; the truth is the loads the
config prescribes. About 2 minutes of FEM for the 20 states it runs by default (the
solutions are cached in the work folder). The rest of this docstring is the library sequence's.

The sensor is examples/coarse_sensor.toml (20 mm sheet, the tests' sensor) with its
library of 1-4 N x 5 tangential ratios (built once into the work folder, about 2 min on
2 cores). The stream (sequence (b) of the tracking issue): FRAMES frames of PIXELS x
PIXELS over 16 mm, 8-bit with camera noise NOISE (of full scale), five contacts of
3.5 mm spheres:

- S slides 3 mm along x at 2.5 N with 0.5 N tangential load along the slide;
- P1 and P2 pass each other 4.4 mm apart (7 and 7 mm of travel, opposite ways);
- T touches mid-way (its load ramps from 0 to 3 N over 15 % of the stream);
- R is lifted (3 N to 0 over 15 % of the stream).

A contact counts as present in a frame when its normal load is at least the release
level (half the library's first load); a lighter one still touching may be tracked or
not (neither missed nor spurious, its errors not scored). A touch is due in the frame
its load reaches that level, a lift in the frame its load is gone. Prints the cold start
(the first frame: the quick start, or the whole inverse when that does not explain it),
the warm frames' median and 95th percentile time, frames per second, the errors of every
present contact against the truth (Fz in N, tangential magnitude in N and direction in
degrees where it is at least 0.1 N, position in mm), identity swaps, and missed and
spurious contacts per frame, and the frames by which the touch and the lift were read
late, the coverage of the stated 1-sigma (the fractions of the errors in position: x and
y; Fz; and tangential: Fx and Fy within 1 and 2 of their sd); and, on every
INVERT_EVERY-th frame (0: none), the offline ``invert``'s errors and their coverage
against the truth beside the tracker's on the same frames (the issue's target: tracked
within 1.5 times offline) and its time per image; and on COLD_STARTS frames spread over
the stream after the first, the tracker started cold on that frame alone (as after a
restart): its time, the quick start's and the whole inverse's share, and its contacts
and errors, or why it was refused. ``--json`` writes it all, with the peak memory.
``--show`` tracks with the live window's drawing (``track --show``) done in full
off-screen in its own process, as the window does it: its cost to the solver, and the
redraws it made.
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import fringekit
from fringekit.config.files import load_config
from fringekit.errors import RefusedError
from fringekit.inversion import uncertainty
from fringekit.library.build import DEFAULT_RATIOS, build_library
from fringekit.library.store import load_library
from fringekit.optics import write_image
from fringekit.tracking import library_frames, track
from fringekit.tracking.display import LiveDisplay

ROOT = Path(__file__).resolve().parents[1]
SENSOR = ROOT / "examples" / "coarse_sensor.toml"
LOADS = (1.0, 1.4, 2.0, 2.8, 4.0)
FIELD_MM = 16.0
OFFSCREEN = "fringekit.tracking.display:OffscreenWindow"  # --show's drawing, no display
#: The FEM sequence's largest normal load (N): inside the library's range (4 N), where
#: ``invert`` answers (at 4 N it refuses: held at the library's edge).
TOP_N = 3.4
#: The error quantities scored (keys of _score_frame's errors).
QUANTITIES = ("fz_N", "ft_N", "dir_deg", "pos_mm")


def _ramp(t: float, t0: float, t1: float) -> float:
    return float(np.clip((t - t0) / (t1 - t0), 0.0, 1.0))


def contacts(t: float) -> dict[str, tuple]:
    """The five contacts at stream time t in [0, 1]: name -> (x, y mm, Fz, Fx, Fy N)."""
    return {
        "S": (-6.0 + 3.0 * t, 5.5, 2.5, 0.5, 0.0),
        "P1": (-2.2, -5.0 + 6.5 * t, 3.0, 0.0, 0.4),
        "P2": (2.2, 3.0 - 7.0 * t, 2.0, -0.3, 0.0),
        "T": (5.5, 4.5, 3.0 * _ramp(t, 0.40, 0.55), 0.0, 0.0),
        "R": (-6.5, -1.5, 3.0 * (1.0 - _ramp(t, 0.30, 0.45)), 0.0, 0.0),
    }


def stream(n: int) -> list[dict[str, tuple]]:
    return [contacts(k / max(n - 1, 1)) for k in range(n)]


def _library(work: Path, given: str | None):
    if given:
        return load_library(given)
    folder = work / "library"
    if not (folder / "manifest.json").is_file():
        print(f"building the library into {folder} ...", flush=True)
        build_library(
            load_config(SENSOR),
            folder,
            loads=LOADS,
            ratios=DEFAULT_RATIOS,
            cache_dir=work / "cache",
            progress=True,
        )
    return load_library(folder)


def _score_frame(frame, truth: dict, level: float, labels: dict) -> dict:
    """Errors of one frame's contacts against the present truth ones (nearest within
    1 mm), their id labels (id -> name, for swaps), missed and spurious counts."""
    present = {k: v for k, v in truth.items() if v[2] >= level}
    touching = {k: v for k, v in truth.items() if v[2] > 0}
    names = list(touching)
    t = np.array([touching[k] for k in names]).reshape(-1, 5)
    out = {"errors": [], "missed": 0, "spurious": 0, "swaps": 0, "seen": set()}
    for i, row, sd in zip(frame.ids, frame.params, frame.sd, strict=True):
        d = np.hypot(*(t[:, :2] - row[:2]).T) if len(t) else np.array([])
        if not len(d) or d.min() > 1.0:
            out["spurious"] += 1
            continue
        name = names[int(np.argmin(d))]
        out["seen"].add(name)
        if labels.setdefault(int(i), name) != name:
            out["swaps"] += 1
            labels[int(i)] = name
        if name not in present:  # lighter than the level: may be tracked, not scored
            continue
        w = present[name]
        ft, ft_true = np.hypot(row[3], row[4]), np.hypot(w[3], w[4])
        ang = np.degrees(
            np.angle(np.exp(1j * (np.arctan2(row[4], row[3]) - np.arctan2(w[4], w[3]))))
        )
        out["errors"].append(
            {
                "name": name,
                "fz_N": row[2] - w[2],
                "ft_N": ft - ft_true,
                "dir_deg": float(ang) if ft_true >= 0.1 else None,
                "pos_mm": float(np.hypot(row[0] - w[0], row[1] - w[1])),
                # each parameter's error in its stated sd (x, y, Fz, Fx, Fy)
                "z": [float(v) for v in (row - np.asarray(w, float)) / sd],
            }
        )
    out["missed"] = len(set(present) - out["seen"])
    return out


def score(t, truths: list[dict], level: float) -> dict:
    """The stream's scores (module docstring)."""
    labels: dict = {}
    frames = [_score_frame(f, truths[f.index], level, labels) for f in t.frames]
    errs = [e for f in frames for e in f["errors"]]

    def first(name, present: bool):
        """Frames from the first with the load at the level (a touch) or gone to zero
        (a lift) to the first the tracker agrees (None: a sequence without this event)."""
        if name not in truths[0]:
            return None
        want = [
            k
            for k, tr in enumerate(truths)
            if (tr[name][2] >= level if present else tr[name][2] <= 0)
        ]
        got = [
            f.index for f, s in zip(t.frames, frames, strict=True) if (name in s["seen"]) == present
        ]
        start = want[0] if present else [k for k in want if k > 0][0]
        late = [k for k in got if k >= start]
        return (late[0] - start) if late else None

    return {
        **{key: _stats(errs, key) for key in QUANTITIES},
        "coverage": coverage(errs),
        "swaps": int(sum(f["swaps"] for f in frames)),
        "missed_per_frame": float(np.mean([f["missed"] for f in frames])),
        "spurious_per_frame": float(np.mean([f["spurious"] for f in frames])),
        "touch_late_frames": first("T", True),
        "lift_late_frames": first("R", False),
    }


def coverage(errs: list[dict]) -> dict | None:
    """The fractions of the errors within 1 and 2 of their stated sd (``loads.csv``'s
    sx_mm ... sFz_N) per quantity (:func:`fringekit.inversion.uncertainty.coverage`)."""
    return uncertainty.coverage([e["z"] for e in errs]) if errs else None


def _stats(errs: list[dict], key: str) -> dict | None:
    v = np.abs(np.array([e[key] for e in errs if e[key] is not None], float))
    if not len(v):
        return None
    return {
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(v.max()),
    }


def offline(lib, folder: Path, tracked, truths, every: int, pixel_mm: float, method, level):
    """``invert`` on every ``every``-th frame: its errors and the tracker's on the same
    frames (medians and maxima), the ratio of the medians, images refused, time each."""
    frames = {f.index: f for f in tracked.frames}
    inv_errs, trk_errs, refused, times = [], [], [], []
    for k in range(0, len(truths), every):
        t0 = time.perf_counter()
        try:
            images = (
                [folder / f"frame_{k:04d}_step{j}.png" for j in range(1, 7)]
                if method == "phase"
                else folder / f"frame_{k:04d}.png"
            )
            res = fringekit.invert(images, lib, pixel_mm=pixel_mm, method=method)
        except RefusedError as exc:
            refused.append({"frame": k, "reason": str(exc)})
            print(f"{method} frame {k}: offline invert refused: {exc}", flush=True)
            continue
        finally:
            times.append(time.perf_counter() - t0)
            print(f"{method} frame {k}: offline invert {times[-1]:.1f} s", flush=True)
        q = res.result.params
        got = SimpleNamespace(ids=np.arange(len(q)), params=q, sd=res.result.sd)
        inv_errs += _score_frame(got, truths[k], level, {})["errors"]
        if k in frames:
            trk_errs += _score_frame(frames[k], truths[k], level, {})["errors"]
    out = {
        "frames": len(times),
        "refused": refused,
        "time_median_s": float(np.median(times)),
        "coverage": {"invert": coverage(inv_errs), "track": coverage(trk_errs)},
    }
    for key in QUANTITIES:
        a, b = _stats(inv_errs, key), _stats(trk_errs, key)
        ratio = b["median"] / a["median"] if a and b and a["median"] > 0 else None
        out[key] = {"invert": a, "track": b, "track_over_invert_median": ratio}
    return out


def fem_stream(n: int) -> list[dict[str, tuple]]:
    """The FEM sequence's contacts per frame (module docstring): name -> (x, y mm, Fz,
    Fx, Fy N)."""
    n_normal = max(2, int(round(0.6 * n)))
    fz = np.concatenate([np.geomspace(0.5, TOP_N, n_normal), np.full(n - n_normal, TOP_N)])
    ft = np.concatenate([np.zeros(n_normal), np.linspace(0.0, 0.4, n - n_normal + 1)[1:]])
    return [
        {"A": (-3.2, 1.0, float(f), 0.0, 0.0), "B": (3.2, -1.0, float(f), float(t * f), 0.0)}
        for f, t in zip(fz, ft, strict=True)
    ]


def fem_frames(truths: list[dict], method: str, args, work: Path) -> Path:
    """The FEM sequence's frames (``frame_0000.png``, ...) in the work folder: the
    predicted camera images of every state with camera noise added."""
    cfg = load_config(SENSOR)
    cfg["contact"]["friction"] = "stick"
    cfg["mesh"]["symmetry"] = "full"
    cfg["optics"].update(
        field_of_view_mm=FIELD_MM, pixels=args.pixels, center_mm=[0.0, 0.0], render="all"
    )
    proto = cfg["indenter"][0]
    cfg["indenter"] = [
        dict(
            proto,
            x_mm=truths[0][name][0],
            y_mm=truths[0][name][1],
            load_N=[t[name][2] for t in truths],
            shear_N=[[t[name][3], t[name][4]] for t in truths],
        )
        for name in truths[0]
    ]
    t0 = time.perf_counter()
    pred = fringekit.predict(cfg, cache_dir=work / "cache", progress=True)
    print(
        f"FEM sequence: {len(truths)} states solved and rendered in "
        f"{time.perf_counter() - t0:.0f} s",
        flush=True,
    )
    folder = work / f"fem-{method}-{args.pixels}"
    shutil.rmtree(folder, ignore_errors=True)  # the bench's own frames of an earlier run
    folder.mkdir(parents=True)
    for k, rs in enumerate(pred.states):  # a few dozen frames
        img = (rs.white_light if method == "rgb" else rs.dark_field).astype(float) / 255.0
        img += np.random.default_rng(k).normal(0.0, args.noise, img.shape)
        img = np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)
        write_image(folder / f"frame_{k:04d}.png", img)
    return folder


def _library_frames(lib, truths: list[dict], method: str, args, work: Path) -> Path:
    """The library sequence's frames in the work folder."""
    rows = [[c for c in tr.values() if c[2] > 0] for tr in truths]
    folder = work / f"frames-{method}-{args.pixels}"
    library_frames(
        lib,
        rows,
        folder,
        pixels=args.pixels,
        pixel_mm=FIELD_MM / args.pixels,
        method=method,
        noise=args.noise,
        seed=0,
    )
    return folder


def cold_starts(lib, folder: Path, truths, count: int, pixel_mm: float, method, level, stride):
    """The tracker started cold on ``count`` frames spread evenly over the stream after
    its first (each frame a stream of its own, as after a restart): per frame the time,
    the quick start's and the whole inverse's share, the contacts found, missed and
    spurious, how many of them the tracker flags not reliable (a wrong answer it states
    as such, or one it stands behind), the largest errors, or the reason it was
    refused."""
    out = []
    for k in np.linspace(0, len(truths) - 1, count + 1)[1:].round().astype(int):
        one = folder.parent / "cold-starts" / f"{folder.name}-{k:04d}"
        shutil.rmtree(one, ignore_errors=True)
        one.mkdir(parents=True)
        for f in folder.glob(f"frame_{k:04d}*.png"):  # one image, or six steps
            shutil.copy(f, one / f.name)
        t0 = time.perf_counter()
        t = track(one, lib, pixel_mm=pixel_mm, method=method, stride=stride)
        row = {"frame": int(k), "time_s": time.perf_counter() - t0}
        if t.summary["frames_refused"]:
            row["refused"] = t.summary["frames_refused"][0]["reason"]
        if t.frames:
            f = t.frames[0]
            row.update(
                {k2: f.times_s[k2] for k2 in ("quick_start_s", "inverse_s") if k2 in f.times_s}
            )
            s = _score_frame(f, truths[k], level, {})
            row.update(found=len(f.ids), missed=s["missed"], spurious=s["spurious"])
            row["not_reliable"] = int(np.count_nonzero(~np.asarray(f.reliable, bool)))
            for key in QUANTITIES:
                vals = [abs(e[key]) for e in s["errors"] if e[key] is not None]
                row[f"max_{key}"] = max(vals) if vals else None
        print(f"{method} cold start on frame {k}: {json.dumps(row)}", flush=True)
        out.append(row)
    return out


def run(lib, method: str, args, work: Path) -> dict:
    pixel_mm = FIELD_MM / args.pixels
    if args.sequence == "fem":
        truths = fem_stream(args.frames)
        folder = fem_frames(truths, method, args, work)
    else:
        truths = stream(args.frames)
        folder = _library_frames(lib, truths, method, args, work)
    view = LiveDisplay(pixel_mm, None, window=OFFSCREEN) if args.show else None
    t0 = time.perf_counter()
    tr = track(
        folder,
        lib,
        pixel_mm=pixel_mm,
        method=method,
        stride=args.stride,
        progress=True,
        on_frame=view,
    )
    wall = time.perf_counter() - t0
    if view is not None:
        view.close()
    s = tr.summary
    level = 0.5 * lib.load_N[1]
    warm = [f.times_s["frame_s"] for f in tr.frames[1:] if not f.events]
    inverted = (
        offline(lib, folder, tr, truths, args.invert_every, pixel_mm, method, level)
        if args.invert_every > 0
        else None
    )
    return {
        "method": method,
        "sequence": args.sequence,
        "frames": args.frames,
        "pixels": args.pixels,
        "stride": args.stride,
        "cold_start_s": tr.frames[0].times_s["frame_s"],
        "warm_median_s": float(np.median(warm)),
        "warm_p95_s": float(np.percentile(warm, 95)),
        "fps_warm_median": 1.0 / float(np.median(warm)),
        "fps_all": s["fps_achieved"],
        "wall_s": wall,
        "event_frames": len(s["events"]),
        "event_frame_s": [
            [f.index, " ".join(f.events), f.times_s["frame_s"]] for f in tr.frames if f.events
        ],
        "times_s": s["times_s"],
        "show": None if view is None else {"redraws": view.sent, "error": view.error},
        **score(tr, truths, level),
        "offline_invert": inverted,
        "cold_starts": cold_starts(
            lib, folder, truths, args.cold_starts, pixel_mm, method, level, args.stride
        ),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequence", choices=("library", "fem"), default="library")
    ap.add_argument(
        "--frames",
        type=int,
        default=None,
        help="frames of the stream (default 200 for the library sequence, 20 for fem: each "
        "FEM frame is a solved load state)",
    )
    ap.add_argument("--pixels", type=int, default=256)
    ap.add_argument(
        "--methods", nargs="+", choices=("mono", "rgb", "phase"), default=["mono", "rgb"]
    )
    ap.add_argument("--stride", type=int, default=4)
    ap.add_argument("--noise", type=float, default=0.005)
    ap.add_argument("--invert-every", type=int, default=50)
    ap.add_argument(
        "--cold-starts",
        type=int,
        default=0,
        help="start the tracker cold on this many frames spread over the stream (each alone)",
    )
    ap.add_argument("--library", default=None)
    ap.add_argument("--work", default="bench/out/track")
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--show",
        action="store_true",
        help="track with the --show window drawn off-screen (its own process): its cost",
    )
    args = ap.parse_args(argv)
    if args.frames is None:
        args.frames = 20 if args.sequence == "fem" else 200
    if args.sequence == "fem" and "phase" in args.methods:
        ap.error("--sequence fem --methods phase: the FEM frames are one image per state")
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    print(
        f"track bench: {args.frames} frames of {args.pixels} x {args.pixels} px over "
        f"{FIELD_MM:g} mm, methods {args.methods}, stride {args.stride}",
        flush=True,
    )
    lib = _library(work, args.library)
    results = [run(lib, m, args, work) for m in args.methods]
    for r in results:
        print(json.dumps({k: v for k, v in r.items() if k != "times_s"}, indent=1))
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory {peak_mb:.0f} MB")
    if args.json:
        Path(args.json).write_text(json.dumps({"runs": results, "peak_mb": peak_mb}, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])
