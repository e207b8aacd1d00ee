"""Benchmark ``fringekit sensor calibrate`` on a "real" sensor rendered by full FEM.

Usage: python bench/sensor.py [--pixels 128] [--noise 0.003] [--seed 0] [--library DIR]
       [--residual-fringe 0.3] [--refine] [--refine-frames N] [--reuse] [--phase]
       [--residual-steps]
       [--max-seconds S] [--work DIR] [--json FILE]
       (--work default: bench/out/sensor, ignored by git; --reuse: the frames of an earlier
       run in the work folder, not rendered again)

The library is examples/coarse_sensor.toml's (20 mm sheet) over 1-4 N x 5 tangential
ratios (built once into the work folder, about 2 min on 2 cores). The true sensor departs
from the library's config as the calibration issue asks:

- the sheet's modulus +15 % (Young's modulus; Poisson's ratio kept, so every material
  constant scales) and its material fringe value -8 %;
- a 3 degree retardance error of both quarter-wave plates;
- a residual retarder in series with the sheet: a smooth field up to 0.3 fringe, its axis
  turning across the field;
- 30 % vignetting (a radial fall-off to 0.7 in the corners), a flare of 0.02, a black
  level of 0.03 and a camera gamma of 2.2, 8 bits, Gaussian noise NOISE;
- the image turned 2 degrees and its centre 0.4 mm off the sheet's origin.

Frames (mono, dark-field circular at the reference wavelength, PIXELS x PIXELS over
16 mm): one rest frame, one dark frame, three known-load frames (one sheared contact each)
and six test frames of 1-4 sheared contacts (positions and loads drawn with SEED), each a
full-FEM solve of the true sensor under full stick (the library's contact law).

Prints each fitted parameter against its truth, and per-contact errors of the test frames
read (a) without calibration (the nominal pitch) and (b) with the sensor file: position
(mm), Fz (% of Fz), tangential magnitude (% of Fz) and direction (deg, where the
tangential load is at least 0.1 N), against the invert issue's targets (Fz 3 %,
tangential 10 % and 5 deg, position 0.05 mm), and with ``--refine`` (c) with the sensor
file and ``--refine fem`` (one to four FEM solves per frame: about half an hour).

``--residual-steps`` calibrates the grey frames with the six phase steps of the rest
(through the true plates, residual and camera, at 16 bits) instead of the rest frame:
the residual retarder modelled, not subtracted.

``--phase`` runs instead the six-step method: the six phase steps of the rest, the three
known frames and the six test frames (the same FEM solves, the true plates, residual,
geometry and camera, at 16 bits), calibrated by ``sensor calibrate --method phase`` (the
rest steps read as the residual retarder), and the test frames read (d) without
calibration (the nominal pitch, no rest) and (e) through the sensor file (each inverse
within ``--max-seconds``, default 600); with ``--refine``, (f) the first
``--refine-frames`` through the sensor file with ``--refine fem`` (its residual retarder
frozen into the FEM's sheet).
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np
from scipy import ndimage
from skimage.transform import warp

import fringekit
from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.library.build import DEFAULT_RATIOS, build_library
from fringekit.library.calibrated import CalibratedSensor
from fringekit.library.store import load_library
from fringekit.optics import dark_field_circular, intensity, six_step_arrangements, write_image
from fringekit.optics.jones import qmul, retarder
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import mono_map

ROOT = Path(__file__).resolve().parents[1]
SENSOR = ROOT / "examples" / "coarse_sensor.toml"
LOADS = (1.0, 1.4, 2.0, 2.8, 4.0)
FIELD_MM = 16.0
#: The true sensor (module docstring).
TRUE = {
    "modulus_scale": 1.15,
    "fringe_scale": 0.92,
    "qwp_error_deg": 3.0,
    "residual_fringe": 0.3,
    "vignetting": 0.3,
    "flare": 0.02,
    "black": 0.03,
    "gamma": 2.2,
    "gain": 0.75,
    "rotation_deg": 2.0,
    "offset_mm": (0.4, 0.0),
}
#: Known-load frames: x, y (mm), Fx, Fy, Fz (N), one contact each.
KNOWN = [(-3.0, 2.5, 0.5, 0.0, 2.0), (3.0, 1.0, 0.0, 0.8, 3.0), (0.5, -3.5, -0.6, 0.5, 3.6)]
#: The normal-load fractions of a path (steps of about 1.4x), then the tangential load in
#: steps of at most 0.2 of the normal load, as the library's chain takes them.
NORMAL_STEPS = (0.125, 0.18, 0.25, 0.35, 0.5, 0.7, 1.0)
TARGETS = {"position_mm": 0.05, "Fz_pct": 3.0, "Ft_pct": 10.0, "angle_deg": 5.0}


def true_config(contacts) -> dict:
    """The true sensor's config under ``contacts`` (x, y, Fx, Fy, Fz), full stick, the
    whole sheet imaged (20 mm) at the frames' pitch."""
    cfg = load_config(SENSOR)
    cfg["sheet"]["E_MPa"] *= TRUE["modulus_scale"]
    o = cfg["optics"]
    o["f_sigma_N_per_m"] *= TRUE["fringe_scale"]
    o["qwp_error_deg"] = TRUE["qwp_error_deg"]
    cfg["contact"]["friction"] = "stick"
    cfg["mesh"]["symmetry"] = "full"
    proto = cfg["indenter"][0]
    ratio = max([math.hypot(c[2], c[3]) / c[4] for c in contacts] + [0.0])
    n_shear = max(1, math.ceil(ratio / 0.2))
    normal = list(NORMAL_STEPS) + [1.0] * n_shear
    shear = [0.0] * len(NORMAL_STEPS) + [(k + 1) / n_shear for k in range(n_shear)]
    cfg["indenter"] = [
        dict(
            copy.deepcopy(proto),
            x_mm=x,
            y_mm=y,
            load_N=[f * fz for f in normal],
            shear_N=[[t * fx, t * fy] for t in shear],
        )
        for x, y, fx, fy, fz in contacts
    ] or [dict(copy.deepcopy(proto), load_N=[0.0], shear_N=[[0.0, 0.0]])]
    return cfg


def _residual(grid) -> np.ndarray:
    """The residual retarder's quaternions (rows, cols, 4): retardation up to
    residual_fringe (a smooth bump off-centre), its axis turning across the field."""
    xy = grid.xy().reshape(*grid.shape, 2) * 1e3
    x, y = xy[..., 0], xy[..., 1]
    fringe = TRUE["residual_fringe"] * np.exp(-((x - 3.0) ** 2 + (y + 2.0) ** 2) / 40.0)
    return retarder(2 * np.pi * fringe, 0.3 + 0.05 * x)


def sheet_intensity(contacts, work: Path, pixel_mm: float, phase: bool = False) -> np.ndarray:
    """Dark-field intensity (n, n) (linear, source 1), or with ``phase`` the six steps'
    (n, n, 6), of the whole sheet under ``contacts`` by full FEM, at ``pixel_mm`` on the
    sheet's axes, through the true sensor's plates; contact-zone pixels take their nearest
    valid neighbour's value (a camera sees the sheet there too)."""
    cfg = true_config(contacts)
    n = int(round(20.0 / pixel_mm))
    cfg["optics"].update(field_of_view_mm=n * pixel_mm, pixels=n, center_mm=[0.0, 0.0])
    optics = optics_setup(cfg)
    if contacts:
        _, sols, _, failure = solve_config(cfg, cache_dir=work / "cache", progress=False)
        if failure:
            raise RuntimeError(failure)
        omap, _ = mono_map(sols[-1], cfg, optics)
        q, valid = omap.q[:, :, 0], omap.mask
    else:
        q = np.zeros((n, n, 4))
        q[..., 0] = 1.0
        valid = np.ones((n, n), bool)
    q = qmul(_residual(optics.grid), q)
    if phase:
        img = np.stack([intensity(q, a) for a in six_step_arrangements(**optics.errors)], -1)
    else:
        img = intensity(q, dark_field_circular(**optics.errors))
    idx = ndimage.distance_transform_edt(~valid, return_distances=False, return_indices=True)
    return img[tuple(idx)]


def truth_sensor(pixels: int) -> dict:
    """The true geometry: pitch (mm), origin pixel (row, col), rotation (deg)."""
    p = FIELD_MM / pixels
    c = (pixels - 1) / 2
    dx, dy = TRUE["offset_mm"]
    return {
        "pixel_mm": p,
        "origin_px": (c - dy / p, c + dx / p),
        "rotation_deg": TRUE["rotation_deg"],
    }


def _into_image(sheet: np.ndarray, pixels: int) -> np.ndarray:
    """A sheet image (n, n[, k]) (the sheet's axes, 20 mm, at the frames' pitch) turned and
    shifted into the camera's (pixels, pixels[, k]) by the true geometry."""
    geo = truth_sensor(pixels)
    p, (r_o, c_o), t = geo["pixel_mm"], geo["origin_px"], math.radians(geo["rotation_deg"])
    n = sheet.shape[0]

    def to_sheet(cr: np.ndarray) -> np.ndarray:  # image (col, row) -> sheet image (col, row)
        x, y = (cr[:, 0] - c_o) * p, (r_o - cr[:, 1]) * p
        qx, qy = math.cos(t) * x + math.sin(t) * y, -math.sin(t) * x + math.cos(t) * y
        return np.column_stack([qx / p + (n - 1) / 2, (n - 1) / 2 - qy / p])

    shape = (pixels, pixels) + sheet.shape[2:]
    return warp(sheet, to_sheet, output_shape=shape, order=1, mode="edge")


def camera_frame(sheet: np.ndarray, pixels: int, rng, noise: float, bits: int = 8) -> np.ndarray:
    """The camera's 8-bit (or 16-bit) frame (pixels, pixels) of a sheet intensity image
    (the sheet's axes, 20 mm, at the frames' pitch): turned and shifted into the image,
    vignetted, with flare, black level, gamma and noise."""
    img = _into_image(sheet, pixels)
    rr, cc = np.mgrid[0:pixels, 0:pixels]
    c = (pixels - 1) / 2
    rho2 = ((rr - c) ** 2 + (cc - c) ** 2) / (2 * c**2)
    lin = TRUE["gain"] * (1.0 - TRUE["vignetting"] * rho2) * img + TRUE["flare"]
    b = TRUE["black"]
    raw = b + (1 - b) * np.clip(lin, 0, None) ** (1 / TRUE["gamma"])
    raw = raw + rng.normal(0.0, noise, raw.shape)
    top, kind = (255, np.uint8) if bits == 8 else (65535, np.uint16)
    return np.round(np.clip(raw, 0, 1) * top).astype(kind)


def phase_steps(sheet: np.ndarray, pixels: int, rng, noise: float) -> list[np.ndarray]:
    """The six 16-bit phase steps (pixels, pixels) of a sheet's six intensities (n, n, 6):
    the true geometry and camera (:func:`camera_frame`'s vignetting, flare, black level,
    gamma and noise; the six steps' brightest, (1 + cos d) / 2 of the light, at about the
    dark-field frames' exposure)."""
    return [
        camera_frame(sheet[..., k], pixels, rng, noise, bits=16) for k in range(sheet.shape[-1])
    ]


def draw_tests(rng, n_frames: int = 6) -> list[list[tuple]]:
    """Test frames of 1-4 sheared contacts, at least 5 mm apart within 6 mm of the
    centre, Fz 1.2-3.6 N, tangential up to 0.35 Fz in any direction."""
    frames = []
    for k in range(n_frames):
        want, pts = 1 + k % 4, []
        while len(pts) < want:
            xy = rng.uniform(-6.0, 6.0, 2)
            if all(math.dist(xy, q[:2]) >= 5.0 for q in pts):
                fz = rng.uniform(1.2, 3.6)
                ft, ang = rng.uniform(0.05, 0.35) * fz, rng.uniform(0, 2 * math.pi)
                pts.append((*xy, ft * math.cos(ang), ft * math.sin(ang), fz))
        frames.append([tuple(float(v) for v in q) for q in pts])
    return frames


def contact_errors(table: dict, truth: list[tuple]) -> list[dict]:
    """Per true contact, the errors of the nearest read contact (None: none within 2 mm)."""
    got = np.column_stack([table[k] for k in ("x_mm", "y_mm", "Fx_N", "Fy_N", "Fz_N")])
    out = []
    for x, y, fx, fy, fz in truth:
        d = np.hypot(got[:, 0] - x, got[:, 1] - y) if len(got) else np.array([np.inf])
        if not len(got) or d.min() > 2.0:
            out.append(None)
            continue
        g = got[int(np.argmin(d))]
        ft = math.hypot(fx, fy)
        ang = math.degrees(math.atan2(g[3], g[2]) - math.atan2(fy, fx))
        out.append(
            {
                "position_mm": float(d.min()),
                "Fz_pct": float(100 * abs(g[4] - fz) / fz),
                "Ft_pct": float(100 * abs(math.hypot(g[2], g[3]) - ft) / fz),
                "angle_deg": float(abs((ang + 180) % 360 - 180)) if ft >= 0.1 else None,
            }
        )
    return out


def _library(work: Path, given: str | None):
    if given:
        return load_library(given)
    folder = work / "library"
    if not (folder / "manifest.json").is_file():
        print(f"building the library into {folder} ...", flush=True)
        cfg = load_config(SENSOR)
        cfg["contact"]["friction"] = "stick"
        build_library(cfg, folder, loads=LOADS, ratios=DEFAULT_RATIOS, cache_dir=work / "cache")
    return load_library(folder)


def render(work: Path, args, rng) -> tuple[list, float]:
    """Write the frames and KNOWN.csv into work/frames; return the test frames' truth and
    the seconds spent (FEM and rendering)."""
    t0 = time.perf_counter()
    d = work / "frames"
    d.mkdir(parents=True, exist_ok=True)
    p = FIELD_MM / args.pixels
    write_image(
        d / "rest.png", camera_frame(sheet_intensity([], work, p), args.pixels, rng, args.noise)
    )
    dark = TRUE["black"] + rng.normal(0.0, args.noise, (args.pixels, args.pixels))
    write_image(d / "dark.png", np.round(np.clip(dark, 0, 1) * 255).astype(np.uint8))
    rows = ["image,x_mm,y_mm,Fx_N,Fy_N,Fz_N"]
    for i, c in enumerate(KNOWN):
        print(f"known frame {i + 1}/{len(KNOWN)}: FEM ...", flush=True)
        img = camera_frame(sheet_intensity([c], work, p), args.pixels, rng, args.noise)
        write_image(d / f"known_{i}.png", img)
        rows.append(f"known_{i}.png," + ",".join(f"{v:g}" for v in c))
    (d / "known.csv").write_text("\n".join(rows) + "\n")
    tests = draw_tests(rng)
    (d / "truth.json").write_text(json.dumps(tests))
    for i, contacts in enumerate(tests):
        print(f"test frame {i + 1}/{len(tests)} ({len(contacts)} contacts): FEM ...", flush=True)
        img = camera_frame(sheet_intensity(contacts, work, p), args.pixels, rng, args.noise)
        write_image(d / f"test_{i}.png", img)
    return tests, time.perf_counter() - t0


def read_tests(lib, d: Path, tests, steps: bool = False, **kw) -> tuple[list, float]:
    """Per test frame: the per-contact errors (or the reason it was refused); ``steps``:
    the frames' six phase steps (``test_I_stepK.png``)."""
    t0 = time.perf_counter()
    out = []
    for i, truth in enumerate(tests):
        one = d / f"test_{i}.png"
        images = [d / f"test_{i}_step{k}.png" for k in range(1, 7)] if steps else one
        try:
            table = fringekit.invert(images, lib, **kw).table()
            out.append(
                {"frame": i, "contacts": contact_errors(table, truth), "n_read": len(table["Fz_N"])}
            )
        except fringekit.InvertError as exc:
            out.append({"frame": i, "refused": str(exc)})
    return out, time.perf_counter() - t0


def run_phase(lib, work: Path, args, tests) -> dict:
    """(d) and (e): the six steps of the rest, the known and the test frames (FEM solves
    from the work folder's cache), calibrated with ``sensor calibrate --method phase``;
    the test frames read without and with the sensor file."""
    d = work / "phase"
    d.mkdir(parents=True, exist_ok=True)
    rng, p = np.random.default_rng(args.seed + 1), FIELD_MM / args.pixels
    t0 = time.perf_counter()
    frames = [("rest", []), *((f"known_{i}", [c]) for i, c in enumerate(KNOWN))]
    frames += [(f"test_{i}", c) for i, c in enumerate(tests)]
    for name, contacts in frames:
        print(f"phase steps of {name}: FEM ...", flush=True)
        sheet = sheet_intensity(contacts, work, p, phase=True)
        for k, img in enumerate(phase_steps(sheet, args.pixels, rng, args.noise), strict=True):
            write_image(d / f"{name}_step{k + 1}.png", img)
    rows = ["image,x_mm,y_mm,Fx_N,Fy_N,Fz_N"]
    for i, c in enumerate(KNOWN):
        steps = ";".join(f"known_{i}_step{k}.png" for k in range(1, 7))
        rows.append(f"{steps}," + ",".join(f"{v:g}" for v in c))
    (d / "known.csv").write_text("\n".join(rows) + "\n")
    t_render = time.perf_counter() - t0
    t0 = time.perf_counter()
    rest = [d / f"rest_step{k}.png" for k in range(1, 7)]
    dark = work / "frames" / "dark.png"  # the camera's, with the light off
    cal = fringekit.calibrate_sensor(
        lib, rest, d / "known.csv", pixel_mm=p, dark=dark, method="phase", progress=True
    )
    t_cal = time.perf_counter() - t0
    path = cal.write(work / "sensor_phase.json")
    kw = {"steps": True, "max_seconds": args.max_seconds}
    dd, t_d = read_tests(lib, d, tests, pixel_mm=p, **kw)
    e, t_e = read_tests(lib, d, tests, sensor=path, **kw)
    few = tests[: args.refine_frames]
    f, t_f = read_tests(lib, d, few, sensor=path, refine="fem", **kw) if args.refine else (None, 0)
    return {
        "pixels": args.pixels,
        "noise": args.noise,
        "seed": args.seed,
        "truth": TRUE,
        "targets": TARGETS,
        "fitted": _fitted(cal.sensor, args.pixels),
        "residual_max_fringe": cal.sensor.report.get("residual_max_fringe"),
        "warnings": cal.sensor.report["warnings"],
        "d_phase_uncalibrated": {"summary": summary(dd), "frames": dd},
        "e_phase_calibrated": {"summary": summary(e), "frames": e},
        "f_phase_refine_fem": None if f is None else {"summary": summary(f), "frames": f},
        "times_s": {
            "fem_and_render": t_render,
            "calibrate": t_cal,
            "invert_d": t_d,
            "invert_e": t_e,
            "invert_f": t_f,
        },
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def summary(frames: list[dict]) -> dict:
    """Median and largest error per quantity, the share of contacts within every target,
    missed contacts and refused frames."""
    errs = [e for f in frames for e in f.get("contacts", []) if e is not None]
    out = {
        "refused_frames": sum("refused" in f for f in frames),
        "missed_contacts": sum(e is None for f in frames for e in f.get("contacts", [])),
        "contacts_read": len(errs),
    }
    for k in TARGETS:
        v = [e[k] for e in errs if e[k] is not None]
        out[k] = {"median": float(np.median(v)), "max": float(np.max(v))} if v else None
    ok = [all(e[k] is None or e[k] <= t for k, t in TARGETS.items()) for e in errs]
    out["within_targets"] = f"{sum(ok)}/{len(ok)}"
    return out


def _fitted(s: CalibratedSensor, pixels: int) -> dict:
    """Each fitted parameter of the sensor file ``s``, its 1-sigma and its truth."""
    geo = truth_sensor(pixels)
    fitted = {
        k: {"fitted": getattr(s, k), "sd": s.sd.get(k), "truth": v}
        for k, v in (
            ("modulus_scale", TRUE["modulus_scale"]),
            ("fringe_scale", TRUE["fringe_scale"]),
            ("gamma", TRUE["gamma"]),
            ("pixel_mm", geo["pixel_mm"]),
            ("rotation_deg", geo["rotation_deg"]),
        )
    }
    fitted["origin_px"] = {
        "fitted": list(s.origin_px),
        "sd": s.sd.get("origin_px"),
        "truth": list(geo["origin_px"]),
    }
    fitted["black"] = {"fitted": list(s.black), "truth": TRUE["black"]}
    return fitted


def _report(result: dict, json_path) -> None:
    """Print the phase run's fit, summaries and times; write ``result`` to ``json_path``."""
    for k, v in result["fitted"].items():
        print(f"{k}: {v}")
    print("warnings:", result["warnings"])
    for name in ("d_phase_uncalibrated", "e_phase_calibrated", "f_phase_refine_fem"):
        if result[name] is not None:
            print(name, json.dumps(result[name]["summary"]))
    print(json.dumps(result["times_s"]), f"peak memory {result['peak_mb']:.0f} MB")
    if json_path:
        Path(json_path).write_text(json.dumps(result, indent=2))


def rest_option(work: Path, d: Path, args) -> dict:
    """``calibrate_sensor``'s rest: the rest frame, or with ``--residual-steps`` the six
    rest steps through the true plates, residual and camera (16 bits), written to ``d``."""
    if not args.residual_steps:
        return {"reference": d / "rest.png"}
    sheet = sheet_intensity([], work, FIELD_MM / args.pixels, phase=True)
    rng = np.random.default_rng(args.seed + 2)
    steps = [d / f"rest_step{k + 1}.png" for k in range(6)]
    for path, img in zip(steps, phase_steps(sheet, args.pixels, rng, args.noise), strict=True):
        write_image(path, img)
    return {"reference": None, "residual_steps": steps}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pixels", type=int, default=128)
    ap.add_argument("--noise", type=float, default=0.003)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--library", default=None)
    ap.add_argument("--refine", action="store_true", help="also (c): --refine fem")
    ap.add_argument(
        "--residual-fringe",
        type=float,
        default=TRUE["residual_fringe"],
        help="the residual retarder's peak (fringe; the issue's 0.3 by default)",
    )
    ap.add_argument("--reuse", action="store_true", help="the frames of an earlier run")
    ap.add_argument(
        "--refine-frames", type=int, default=6, help="(c) on the first N test frames only"
    )
    ap.add_argument(
        "--phase",
        action="store_true",
        help="instead of the dark-field calibration: the six-step method's, (d) and (e)",
    )
    ap.add_argument("--max-seconds", type=float, default=600.0, help="per phase inverse")
    ap.add_argument(
        "--residual-steps",
        action="store_true",
        help="calibrate the grey frames with six rest steps instead of the rest frame",
    )
    ap.add_argument("--work", default="bench/out/sensor")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    TRUE["residual_fringe"] = args.residual_fringe
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    p = FIELD_MM / args.pixels
    print(
        f"sensor bench: {args.pixels} x {args.pixels} px over {FIELD_MM:g} mm, mono, "
        f"noise {args.noise}",
        flush=True,
    )
    lib = _library(work, args.library)
    d = work / "frames"
    if args.reuse and (d / "truth.json").is_file():
        tests, t_render = (
            [[tuple(c) for c in f] for f in json.loads((d / "truth.json").read_text())],
            0.0,
        )
    else:
        tests, t_render = render(work, args, np.random.default_rng(args.seed))
    if args.phase:
        return _report(run_phase(lib, work, args, tests), args.json)
    t0 = time.perf_counter()
    rest = rest_option(work, d, args)
    cal = fringekit.calibrate_sensor(
        lib, known=d / "known.csv", pixel_mm=p, dark=d / "dark.png", progress=True, **rest
    )
    t_cal = time.perf_counter() - t0
    path = cal.write(work / "sensor.json")
    s = cal.sensor
    fitted = _fitted(s, args.pixels)
    a, t_a = read_tests(lib, d, tests, pixel_mm=p)
    b, t_b = read_tests(lib, d, tests, sensor=path)
    few = tests[: args.refine_frames]
    c, t_c = read_tests(lib, d, few, sensor=path, refine="fem") if args.refine else (None, 0.0)
    result = {
        "pixels": args.pixels,
        "noise": args.noise,
        "seed": args.seed,
        "truth": TRUE,
        "fitted": fitted,
        "calibration_warnings": s.report["warnings"],
        "known_residual_rms": [f["residual_rms"] for f in s.report["frames"]],
        "targets": TARGETS,
        "a_uncalibrated": {"summary": summary(a), "frames": a},
        "b_calibrated": {"summary": summary(b), "frames": b},
        "c_refine_fem": None if c is None else {"summary": summary(c), "frames": c},
        "b_on_the_frames_of_c": None if c is None else summary(b[: len(few)]),
        "times_s": {
            "fem_and_render": t_render,
            "calibrate": t_cal,
            "invert_a": t_a,
            "invert_b": t_b,
            "invert_c": t_c,
        },
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    for k, v in fitted.items():
        print(f"{k:14s} fitted {v['fitted']}  truth {v['truth']}  sd {v.get('sd')}")
    for name in ("a_uncalibrated", "b_calibrated", "c_refine_fem"):
        if result[name] is not None:
            print(name, json.dumps(result[name]["summary"]))
    if c is not None:
        print("b on the frames of c", json.dumps(result["b_on_the_frames_of_c"]))
    print(json.dumps(result["times_s"]), f"peak memory {result['peak_mb']:.0f} MB")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main(sys.argv[1:])
