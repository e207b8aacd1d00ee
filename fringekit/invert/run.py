"""``fringekit invert``: images + a library -> every indenter's position and load vector.

Writes into ``--out`` (a fresh folder swapped in when the run ends, so a failed run
leaves an earlier result intact):

- ``loads.csv`` - one row per indenter, exactly the columns :data:`LOAD_COLUMNS`: the
  axis position at first touch (mm, the frame of ``predict``: x to the right, y up, origin
  at ``--origin-px``), sphere diameter, the force the indenter exerts on the sheet (N;
  Fz > 0 presses, Fx/Fy in the sense of a config's ``shear_N``), their 1-sigma and the
  RMS residual within 3 mm of the indenter (fraction of the fitted fringe amplitude);
- ``summary.json`` - method, image, library, sensor check, noise, gains, iterations,
  residual, warnings and times;
- ``fit.png`` - measured, fitted and residual images, with arrows for the tangential loads.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np

from fringekit.config.files import ConfigError, load_config
from fringekit.library.store import check_sensor, load_library
from fringekit.output.figures import NO_DATA_IMAGE_LEVEL
from fringekit.output.folders import run_folder

__all__ = ["LOAD_COLUMNS", "read_measurement", "run_invert", "sensor_config"]

LOAD_COLUMNS = ("x_mm", "y_mm", "diameter_mm", "Fx_N", "Fy_N", "Fz_N", "sx_mm", "sy_mm",
                "sFx_N", "sFy_N", "sFz_N", "residual_rms")  # fmt: skip
#: A region filled with the no-data level in every channel, at least this many pixels,
#: is left out of the fit (the contact discs of ``predict`` images).
NO_DATA_MIN_PX = 12


def _decode(frame, camera_name: str, colour: bool) -> np.ndarray:
    """Linear intensities of a frame in [0, 1]: sRGB decoding for the CIE observer."""
    if colour and camera_name == "CIE1931":
        import colour as cs

        return np.clip(cs.cctf_decoding(frame.data, function="sRGB"), 0.0, 1.0)
    return frame.data


def _no_data(stack: np.ndarray) -> np.ndarray:
    """(rows, cols) bool: regions at the no-data fill level in every channel."""
    from scipy import ndimage

    level = NO_DATA_IMAGE_LEVEL
    hit = np.all(np.abs(stack - level) < 0.6 / 255, axis=-1)
    lab, n = ndimage.label(hit)
    if not n:
        return hit
    sizes = ndimage.sum(hit, lab, np.arange(1, n + 1))
    return np.concatenate([[False], sizes >= NO_DATA_MIN_PX])[lab]


def read_measurement(paths, method: str | None, camera_name: str):
    """(method, measured (P, C) linear, usable (P,), no-data (P,), shape) from the image
    files: usable pixels are neither saturated nor at the no-data fill level."""
    from fringekit.analysis import load_image, load_six_step

    paths = [str(p) for p in paths]
    if method is None:
        single = len(paths) == 1
        method = ("rgb" if load_image(paths[0]).data.ndim == 3 else "mono") if single else "phase"
    want = 6 if method == "phase" else 1
    if len(paths) != want:
        raise ConfigError(f"--method {method} takes {want} image(s); got {len(paths)}")
    if method == "phase":
        frames = load_six_step(paths)
        raw = np.stack([f.data if f.data.ndim == 2 else f.data.mean(-1) for f in frames], -1)
        lin = raw
        sat = np.any([f.saturated for f in frames], axis=0)
    else:
        f = load_image(paths[0])
        if method == "rgb" and f.data.ndim != 3:
            raise ConfigError(f"--method rgb needs a colour image; {paths[0]} is grey")
        data = f.data if method == "rgb" or f.data.ndim == 2 else f.data.mean(-1)
        raw = data.reshape(*data.shape[:2], -1)
        lin = _decode(f, camera_name, method == "rgb").reshape(raw.shape) if method == "rgb" \
            else raw  # fmt: skip
        sat = f.saturated
    nodata = _no_data(raw)
    rows, cols = raw.shape[:2]
    usable = (~sat & ~nodata).ravel()
    return method, lin.reshape(rows * cols, -1), usable, nodata.ravel(), (rows, cols)


def sensor_config(sensor, images) -> tuple[dict | None, str | None]:
    """The image's sensor config: ``--sensor`` (a config file or a ``predict`` output
    folder), else a ``config.toml`` of a ``predict`` folder the first image lies in."""
    if sensor is not None:
        p = Path(sensor)
        path = p / "config.toml" if p.is_dir() else p
        if not path.is_file():
            raise ConfigError(f"--sensor {sensor}: no config file there")
        return load_config(path), str(path)
    here = Path(images[0]).resolve().parent
    for folder in (here, here.parent, here.parent.parent):
        if (folder / "config.toml").is_file() and (folder / "summary.json").is_file():
            return load_config(folder / "config.toml"), str(folder / "config.toml")
    return None, None


def _grid(shape, pixel_mm: float, origin_px):
    from fringekit.optics import PixelGrid

    rows, cols = shape
    r0, c0 = origin_px if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    p = pixel_mm * 1e-3
    return PixelGrid((rows, cols), p, (-(c0 - (cols - 1) / 2) * p, (r0 - (rows - 1) / 2) * p))


def _write_loads(path: Path, res) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(LOAD_COLUMNS)
        for v, s, d, r in zip(res.params, res.sd, res.diameters, res.residual_rms, strict=True):
            w.writerow([f"{x:.6g}" for x in (v[0], v[1], d * 1e3, v[3], v[4], v[2],
                                              s[0], s[1], s[3], s[4], s[2], r)])  # fmt: skip


def run_invert(
    images, library, out, *, method=None, pixel_mm=None, origin_px=None, sensor=None,
    progress=True, echo=print,
) -> dict:  # fmt: skip
    """Invert one image (or six) against a library; write ``out``; return the summary."""
    from fringekit.config.inputs import optics_setup
    from fringekit.invert.figure import fit_figure
    from fringekit.invert.fit import invert_image
    from fringekit.invert.model import ImageModel
    from fringekit.invert.verdict import WARN_RESIDUAL, residual_warnings

    t0 = time.perf_counter()
    if pixel_mm is None:
        raise ConfigError("--pixel-mm is required: the pixel pitch on the sheet (mm), as "
                          "predict's optics.field_of_view_mm / optics.pixels")  # fmt: skip
    lib = load_library(library)
    cfg, where = sensor_config(sensor, images)
    warnings = []
    if cfg is None:
        cfg = load_config(lib.folder / "config.toml")
        warnings.append("no sensor config given or found beside the image: the library's "
                        "own sensor, camera and light are assumed (--sensor)")  # fmt: skip
    else:
        check_sensor(lib, cfg, where)
    optics = optics_setup(cfg)
    method, measured, usable, nodata, shape = read_measurement(
        images, method, optics.camera.sensitivities
    )
    grid = _grid(shape, pixel_mm, origin_px)
    model = ImageModel.build(
        lib,
        grid,
        method,
        measured,
        usable,
        optics,
        light=cfg["optics"]["light"],
        white_light_wavelengths=cfg["optics"]["white_light_wavelengths"],
        nodata=nodata,
    )
    say = echo if progress else (lambda s: None)
    say(f"invert: {method}, {shape[0]} x {shape[1]} px, library {lib.folder} "
        f"({len(lib.load_N) - 1} loads x {len(lib.shear_ratio)} ratios)")  # fmt: skip
    res = invert_image(model)
    warnings += residual_warnings(res.params, res.residual_rms)
    say(f"invert: {len(res.params)} indenter(s), residual {res.residual:.3f} of the fringe "
        f"amplitude, {time.perf_counter() - t0:.1f} s")  # fmt: skip
    with run_folder(out) as work:
        _write_loads(work / "loads.csv", res)
        fit_figure(work / "fit.png", model, res)
        summary = {
            "method": method, "images": [str(p) for p in images], "library": str(lib.folder),
            "sensor_config": where, "pixel_mm": pixel_mm,
            "origin_px": list(origin_px) if origin_px is not None else None,
            "n_indenters": int(len(res.params)), "iterations": int(res.iterations),
            "residual": res.residual, "noise_sd": res.noise,
            "gains": [float(g) for g in res.gains], "offsets": [float(o) for o in res.offsets],
            "warnings": warnings,
            "reliable": [bool(r <= WARN_RESIDUAL) for r in res.residual_rms],
            "times_s": {**res.times_s, "total_s": time.perf_counter() - t0},
        }  # fmt: skip
        (work / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary
