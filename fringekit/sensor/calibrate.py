"""``fringekit sensor calibrate`` as an API: a library calibrated to one physical sensor
from its rest frames and a few frames of known loads.

The steps (each in its module):

1. the black level: the mean of the dark frames per channel (``--dark``), else the rest
   frames' darkest pixels (their 0.1th percentile), which assumes somewhere the sheet is
   free of residual stress;
2. the rest frame: the mean of the rest frames (``--reference``);
3. the known frames' joint fit (:func:`~fringekit.sensor.fit.fit_known`): modulus and
   fringe-value scales, the response's exponent, the illumination, the rotation of the
   tangential loads and every contact's position in the image, the contacts started
   where detection finds fringes (nearest to a known position, else the strongest);
4. the geometry (:func:`~fringekit.sensor.geometry.sheet_geometry`) from the fitted and
   the known positions; when it moves the pitch or the origin, step 3 again on the
   calibrated grid (the scales depend on the pitch: a fringe pattern seen larger looks
   like a softer sheet).

For the phase method (``--method phase``) every frame is six phase steps. The rest steps
are not subtracted: they are read as the sheet's residual retarder
(:func:`~fringekit.inversion.rest.steps_retarder`, at each response and fringe value the
fit tries), which the model holds in series with the loads' retardation, and the sensor
file keeps it (``CalibratedSensor.residual``); the six steps share one illumination and
one offset per frame.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.errors import ConfigError
from fringekit.inversion.detect import detect, noise_sd
from fringekit.inversion.fit import subsample
from fringekit.inversion.rest import (
    PHASE_STEPS,
    RESIDUAL_STEPS,
    residual_fringes,
    steps_retarder,
)
from fringekit.inversion.verdict import WARN_RESIDUAL
from fringekit.library.calibrated import (
    CalibratedSensor,
    coarse_map,
    is_sensor_file,
    linearise,
)
from fringekit.library.store import Library, load_library
from fringekit.output.folders import as_paths, atomic_write
from fringekit.sensor.figure import calibration_figure
from fringekit.sensor.fit import UNDETERMINED_SD, KnownFit, fit_known, illumination_basis
from fringekit.sensor.frames import read_frame, read_frames, read_known, read_steps
from fringekit.sensor.geometry import sheet_geometry
from fringekit.sensor.render import image_model

__all__ = ["SensorCalibration", "calibrate_sensor", "check_out"]

#: Refit on the calibrated grid when the pitch moves by more than this fraction, or the
#: origin by more than this many pixels.
REFIT_PITCH = 2e-5
REFIT_ORIGIN_PX = 0.02
#: Fits at most (the first on the nominal grid): the modulus scale follows the pitch at
#: about four times its relative change (a pattern seen larger looks like a softer sheet).
MAX_ROUNDS = 4


def _method(method, rest: np.ndarray | None) -> str:
    if method not in (None, "rgb", "mono", "phase"):
        raise ConfigError(f"--method {method!r} is not allowed; give rgb, mono or phase")
    return method or ("rgb" if rest is not None and rest.ndim == 3 else "mono")


def _peek(path) -> np.ndarray:
    """The first rest frame's data (its channels tell the default method)."""
    return read_frame(path, "--reference").data


def _rest_options(reference, residual_steps) -> list:
    """The rest frames' paths: ``reference``'s or ``residual_steps``' (one of the two, or
    one :class:`~fringekit.errors.ConfigError` line)."""
    refs, steps = as_paths(reference), as_paths(residual_steps)
    if refs and steps:
        raise ConfigError(
            f"{RESIDUAL_STEPS} with --reference is not allowed: the rest frame holds the "
            "residual's light, which the model makes from the steps; give one of them"
        )
    if not (refs or steps):
        raise ConfigError("--reference: give at least one frame of the sensor at rest")
    return refs or steps


def _grey_only(method: str) -> None:
    """Six rest steps for a grey sensor only (as ``invert --residual-steps``)."""
    if method != "mono":
        raise ConfigError(
            f"{RESIDUAL_STEPS} is for --method mono (with --method phase give the six rest "
            "steps as --reference); got --method " + method
        )


def _black(dark, rest: np.ndarray, method: str, shape) -> tuple[np.ndarray, np.ndarray, str]:
    """(black (C,), its 1-sigma (C,), where it came from)."""
    if dark:
        d, _ = read_frames(dark, method, "--dark", shape)
        flat = d.reshape(-1, d.shape[-1])
        return flat.mean(0), flat.std(0) / math.sqrt(len(flat)), "dark frames"
    steps = rest.shape[-1] == PHASE_STEPS  # six steps: one camera
    flat = rest.reshape(-1, 1 if steps else rest.shape[-1])
    low = np.percentile(flat, 0.1, axis=0)
    return low, flat.std(0) / math.sqrt(len(flat)), "the rest frames' darkest pixels (no --dark)"


def _starts(base, frames, rest, black, gamma0: float) -> list[np.ndarray]:
    """Start positions (n_f, 2) (mm, image axes) of every frame's contacts: a known
    position where it is, an unknown one where detection finds the strongest fringes not
    yet taken (or the origin, when it finds none)."""
    out = []
    rows, cols = base.grid.shape
    for fr in frames:
        unknown = np.isnan(fr.loads[:, 0])
        found = []
        if unknown.any():
            d = linearise(fr.raw, black, gamma0)
            if rest.shape[-1] == d.shape[-1]:  # not rest steps of a grey sensor
                d = d - linearise(rest, black, gamma0)
            m = replace(base, measured=d.reshape(rows * cols, -1), usable=fr.usable)
            m = subsample(m, 2)
            found = [tuple(v) for v in detect(m, noise_sd(m))]
        pos = [
            (found.pop(0) if found else (0.0, 0.0)) if u else (x, y)
            for (x, y), u in zip(fr.loads[:, :2], unknown, strict=True)
        ]
        out.append(np.array(pos, float))
    return out


def _fit(lib, cfg, method, shape, pixel_mm, origin_px, frames, rest, black, starts, before=None):
    """The joint fit on the grid of (pixel_mm, origin_px) (started from the scales of the
    fit ``before``, when given), and the geometry it gives."""
    base = image_model(
        lib, CalibratedSensor.uncalibrated(cfg, lib, shape, method, pixel_mm, origin_px)
    )
    scales = None
    if before is not None:
        scales = (before.modulus_scale, before.fringe_scale, before.gamma, before.rotation_deg)
    fit = fit_known(base, frames, rest, black, starts, scales)
    geo = sheet_geometry(
        np.concatenate(fit.positions_mm),
        np.concatenate(fit.position_sd_mm),
        np.concatenate([fr.loads[:, :2] for fr in frames]),
        pixel_mm,
        origin_px,
        fit.rotation_deg,
        fit.sd["rotation_deg"],
    )
    return fit, geo


def _moved(geo, fit_pitch: float, fit_origin) -> bool:
    return (
        abs(geo.pixel_mm / fit_pitch - 1) > REFIT_PITCH
        or math.dist(geo.origin_px, fit_origin) > REFIT_ORIGIN_PX
    )


def _reexpress(fit: KnownFit, old_pitch, old_origin, geo) -> list[np.ndarray]:
    """The fitted positions (image axes) on the calibrated grid."""
    out = []
    for xy in fit.positions_mm:
        col = old_origin[1] + xy[:, 0] / old_pitch
        row = old_origin[0] - xy[:, 1] / old_pitch
        out.append(
            np.column_stack(
                [(col - geo.origin_px[1]) * geo.pixel_mm, (geo.origin_px[0] - row) * geo.pixel_mm]
            )
        )
    return out


def _illumination(fit: KnownFit, shape) -> tuple[np.ndarray, float, list]:
    """The illumination on the coarse grid, mean 1 over the image, its largest 1-sigma
    (relative) there, and the exposure gain per channel (the mean it was divided by)."""
    rows, cols = shape
    cells = coarse_map(np.zeros(shape)).shape
    rr = np.linspace(0, rows - 1, cells[0])
    cc = np.linspace(0, cols - 1, cells[1])
    R, Cc = np.meshgrid(rr, cc, indexing="ij")
    B = illumination_basis(shape, R.ravel(), Cc.ravel())
    maps, sds = [], []
    for c in range(fit.coefficients.shape[1]):
        m = B @ fit.coefficients[:, c]
        mean = float(m.mean())
        maps.append(m / mean)
        sds.append(np.sqrt(np.einsum("ij,jk,ik->i", B, fit.coefficient_cov[c], B)) / abs(mean))
    L = np.mean(maps, axis=0).reshape(cells)
    gains = [float(np.mean(B @ fit.coefficients[:, c])) for c in range(fit.coefficients.shape[1])]
    return L, float(np.max(sds)), gains


def calibrate_sensor(
    library: Library | str | os.PathLike,
    reference,
    known: str | os.PathLike,
    *,
    pixel_mm: float,
    origin_px=None,
    dark=None,
    method: str | None = None,
    residual_steps=None,
    progress: bool = False,
    echo=print,
) -> CalibratedSensor:
    """A library calibrated to one physical sensor (module docstring).

    Parameters
    ----------
    library : Library or path
        The sensor's response library.
    reference : path or sequence of paths
        Frames of the sensor at rest, in the light of the measurements (averaged); for
        phase, one or more sets of the six steps.
    known : path
        ``KNOWN.csv``: ``image,x_mm,y_mm,Fx_N,Fy_N,Fz_N`` per contact (image paths relative
        to the table, for phase six joined by ``;``; blank x_mm, y_mm: the position is
        fitted; ``diameter_mm`` optional).
    pixel_mm : float
        The nominal pixel pitch on the sheet (mm): the pitch, unless two or more known
        positions give it.
    origin_px : (row, col), optional
        The nominal pixel of the sheet's origin (default the image centre).
    dark : path or sequence of paths, optional
        Frames with the light off (the black level).
    method : {"rgb", "mono", "phase"}, optional
        Default rgb for colour frames, mono for grey (phase is given, never guessed).
    residual_steps : path or sequence of paths, optional
        For mono, instead of ``reference``: the six phase steps of the sensor at rest (or
        several sets of six), in the grey image's light, read as the sheet's residual
        retarder (as for phase) and put into the model of every frame instead of a rest
        frame subtracted: for a sheet whose residual birefringence is beyond what the
        subtraction serves (about 0.05 fringe).
    progress : bool
        One line per step through ``echo``.

    Returns
    -------
    CalibratedSensor
        The scales, response, maps and geometry with their 1-sigma; ``report`` holds the
        per-frame residuals and warnings. Nothing is written (``save`` writes it).

    Examples
    --------
    Frames rendered by a sensor 15 % stiffer than its library, with a fringe value 8 %
    lower and a camera of gamma 2.2, calibrated back (about 45 s on 2 cores, most of it the
    library):

    >>> import tempfile, numpy as np, fringekit
    >>> from pathlib import Path
    >>> from fringekit.library.calibrated import CalibratedSensor
    >>> from fringekit.sensor import sensor_frame
    >>> from fringekit.optics import write_image
    >>> lib = fringekit.build_library("small", tempfile.mkdtemp() + "/lib",
    ...                               loads=[4, 8, 12], ratios=[0, 0.4], progress=False)
    >>> cfg, sha = fringekit.Config.builtin("small").data, lib.manifest["manifest_sha256"]
    >>> truth = CalibratedSensor(cfg, sha, "mono", (48, 48), 0.25, (23.5, 23.5), 0.0,
    ...                          1.15, 0.92, 2.2, (0.02,))
    >>> d = Path(tempfile.mkdtemp())
    >>> write_image(d / "rest.png", sensor_frame(lib, truth, [], bit_depth=16))
    >>> rows = ["image,x_mm,y_mm,Fx_N,Fy_N,Fz_N"]
    >>> for i, fz in enumerate([3.0, 5.0, 7.0]):
    ...     frame = sensor_frame(lib, truth, [(0, 0, 0, 0, fz)], bit_depth=16)
    ...     write_image(d / f"k{i}.png", frame)
    ...     rows.append(f"k{i}.png,0,0,0,0,{fz}")
    >>> _ = (d / "known.csv").write_text("\\n".join(rows))
    >>> cal = fringekit.calibrate_sensor(lib, d / "rest.png", d / "known.csv", pixel_mm=0.25)
    >>> s = cal.sensor
    >>> round(s.modulus_scale, 2), round(s.fringe_scale, 2), round(s.gamma, 1)
    (1.15, 0.92, 2.2)
    """
    t0 = time.perf_counter()
    say = echo if progress else (lambda s: None)
    lib = library if isinstance(library, Library) else load_library(library)
    if not (math.isfinite(pixel_mm) and pixel_mm > 0):
        raise ConfigError(
            f"--pixel-mm {pixel_mm} is not allowed; give the nominal pitch on the sheet (mm, > 0)"
        )
    refs = _rest_options(reference, residual_steps)
    method = _method(method, _peek(refs[0]))
    if method == "phase":
        rest, rest_sat = read_steps(refs, "--reference")
    elif residual_steps is not None:
        _grey_only(method)
        rest, rest_sat = read_steps(refs, RESIDUAL_STEPS)
    else:
        rest, rest_sat = read_frames(refs, method, "--reference")
    darks = as_paths(dark)
    shape = rest.shape[:2]
    origin_px = (
        tuple(origin_px) if origin_px is not None else ((shape[0] - 1) / 2, (shape[1] - 1) / 2)
    )
    black, black_sd, black_from = _black(darks, rest, method, shape)
    frames = read_known(known, method, lib, shape)
    cfg = load_config(lib.folder / "config.toml")
    gamma0 = 2.2 if method == "rgb" else 1.0  # sRGB, or a linear machine-vision camera
    say(
        f"sensor calibrate: {method}, {shape[0]} x {shape[1]} px, {len(frames)} known "
        f"frame(s), black level from {black_from}"
    )
    base = image_model(
        lib, CalibratedSensor.uncalibrated(cfg, lib, shape, method, pixel_mm, origin_px)
    )
    starts = _starts(base, frames, rest, black, gamma0)
    fit, geo = _fit(lib, cfg, method, shape, pixel_mm, origin_px, frames, rest, black, starts)
    say(_line(fit, geo, time.perf_counter() - t0))
    grid = (pixel_mm, origin_px)
    for _ in range(MAX_ROUNDS - 1):  # the scales on the grid the geometry gives, till it stays
        if not _moved(geo, *grid):
            break
        starts = _reexpress(fit, *grid, geo)
        grid = (geo.pixel_mm, geo.origin_px)
        fit, geo = _fit(lib, cfg, method, shape, *grid, frames, rest, black, starts, fit)
        say(_line(fit, geo, time.perf_counter() - t0) + " (on the calibrated grid)")
    rest_maps = _rest_maps(cfg, method, fit, rest, rest_sat, black)
    return _assemble(
        lib, cfg, method, shape, fit, geo, rest_maps, black, black_sd, black_from, frames, t0
    )


@dataclass(frozen=True)
class SensorCalibration:
    """A calibration: the sensor file's content and the fit it came from.

    Attributes
    ----------
    sensor : CalibratedSensor
        What ``SENSOR.json`` holds (``invert --sensor``, ``track --sensor``).
    fit : KnownFit
        The known frames' joint fit (the figure's images).
    images : list of str
        The known frames, in the fit's order.

    Examples
    --------
    See :func:`calibrate_sensor`; ``write`` refuses a name that is not ``.json``:

    >>> try:
    ...     check_out("sensor.txt")
    ... except ValueError as exc:
    ...     print(exc)
    --out sensor.txt: give a file name ending in .json (the sensor file)
    """

    sensor: CalibratedSensor
    fit: KnownFit = field(repr=False)
    images: list = field(repr=False)

    def write(self, path: str | os.PathLike) -> Path:
        """Write the sensor file at ``path`` (``.json``) and its figure beside it (the same
        name with ``.png``), each whole or not at all; return the file's path. A file there
        that fringekit did not write is refused (:func:`check_out`)."""
        path = check_out(path)
        atomic_write(path.with_suffix(".png"), lambda p: calibration_figure(p, self))
        return self.sensor.save(path)


def check_out(path) -> Path:
    """The sensor file's path, checked before any work: a ``.json`` name whose file, and
    figure (``.png``) beside it, are absent or a sensor calibration's (an earlier one is
    replaced; any other file is the user's and is kept)."""
    path = Path(path)
    if path.suffix.lower() != ".json":
        raise ConfigError(f"--out {path}: give a file name ending in .json (the sensor file)")
    if path.is_dir() or (path.exists() and not is_sensor_file(path)):
        raise ConfigError(
            f"--out {path}: something that is not a sensor file is there; give a new name"
        )
    figure = path.with_suffix(".png")
    if figure.exists() and not is_sensor_file(path):
        raise ConfigError(
            f"--out {path}: {figure.name} beside it is not fringekit's; give a new name"
        )
    if not path.parent.is_dir():
        raise ConfigError(f"--out {path}: no folder {path.parent}")
    return path


def _rotation(fit: KnownFit, geo) -> tuple[float, float]:
    """The rotation (deg) and its 1-sigma: of the positions (two or more known), of the
    tangential loads, or inverse-variance weighted when both have one."""
    vals = [v for v in _rotation_estimates(fit, geo).values() if v is not None]
    if not vals:
        return 0.0, math.nan
    if len(vals) == 1 or not all(sd > 0 for _, sd in vals):
        return vals[0]
    w = [1.0 / sd**2 for _, sd in vals]
    return sum(wi * v for wi, (v, _) in zip(w, vals, strict=True)) / sum(w), 1.0 / math.sqrt(sum(w))


def _rotation_estimates(fit: KnownFit, geo) -> dict:
    """The two estimates :func:`_rotation` combines (and the report gives), each (deg,
    1-sigma) or None: of the known positions (two or more) and of the tangential loads'
    directions (when a known frame has one)."""
    pos = (geo.rotation_deg, geo.sd["rotation_deg"]) if geo.n_known >= 2 else None
    tan = (fit.rotation_deg, fit.sd["rotation_deg"])
    return {"positions": pos, "tangential_loads": tan if math.isfinite(tan[1]) else None}


def _line(fit: KnownFit, geo, seconds: float) -> str:
    return (
        f"sensor calibrate: modulus x{fit.modulus_scale:.4f} +- {fit.sd['modulus_scale']:.4f}, "
        f"fringe value x{fit.fringe_scale:.4f} +- {fit.sd['fringe_scale']:.4f}, gamma "
        f"{fit.gamma:.3f}, pitch {geo.pixel_mm:.5g} mm, origin ({geo.origin_px[0]:.2f}, "
        f"{geo.origin_px[1]:.2f}) px, rotation {geo.rotation_deg:.2f} deg, {seconds:.1f} s"
    )


def _rest_maps(cfg, method, fit: KnownFit, rest, rest_sat, black) -> dict:
    """The sensor file's maps of the sheet at rest, on the coarse grid, at the fitted
    response: the rest light (rgb, mono) or the residual retarder of six rest steps at the
    fitted fringe value (phase, and mono with ``residual_steps``), with its retardation
    (fringes) and the pixels it is not read at."""
    lin = linearise(rest, black, fit.gamma)
    if rest.shape[-1] != PHASE_STEPS:  # the rest light, subtracted
        return {"rest": coarse_map(lin), "residual": None, "report": {}}
    law = optics_setup(cfg).law
    law = replace(law, f_sigma=law.f_sigma * fit.fringe_scale)
    ab, unknown = steps_retarder(lin, rest_sat.reshape(rest.shape[:2]), law)
    fringes = residual_fringes(ab, law)
    report = {
        "residual_max_fringe": float(fringes.max()),
        "residual_unknown_px": int(np.count_nonzero(unknown)),
    }
    return {"rest": None, "residual": coarse_map(ab.reshape(*rest.shape[:2], 2)), "report": report}


def _assemble(lib, cfg, method, shape, fit, geo, rest, black, black_sd, black_from, frames, t0):
    """The calibration of the fit and geometry, with its 1-sigma and report; ``rest``:
    :func:`_rest_maps`."""
    illumination, illumination_sd, gains = _illumination(fit, shape)
    rot, rot_sd = _rotation(fit, geo)
    warnings = [
        f"known frame {fr.path.name} is not explained: residual {r:.2f} of the fringe amplitude "
        f"(above {WARN_RESIDUAL}); check its loads and positions in the table"
        for fr, r in zip(frames, fit.residual_rms, strict=True)
        if not r <= WARN_RESIDUAL
    ]
    if rest["report"].get("residual_unknown_px"):
        warnings.append(
            f"the rest steps give no residual retarder at {rest['report']['residual_unknown_px']}"
            " px (saturated, without modulation, or near half a fringe): taken as none there"
        )
    warnings += [
        f"the {name.replace('_', ' ')} ended on a bound of the fit ({getattr(fit, name):.4g}): "
        "the known frames do not determine it; check their loads, the pitch and the rest frame"
        for name in fit.at_bound
    ]
    warnings += [
        f"the {name.replace('_', ' ')} is not determined by the known frames "
        f"({getattr(fit, name):.4g} +- {fit.sd[name]:.2g}, over {UNDETERMINED_SD:.0%} of it); "
        "known frames over a wider range of loads, or six phase steps, determine it better"
        for name in fit.undetermined()
    ]
    sd = {
        **{k: fit.sd[k] for k in ("modulus_scale", "fringe_scale", "gamma")},
        "rotation_deg": rot_sd,
        "pixel_mm": geo.sd["pixel_mm"],
        "origin_px": geo.sd["origin_px"],
        "black": [float(v) for v in black_sd],
        "illumination": illumination_sd,
    }
    report = {
        **rest["report"],
        "black_level_from": black_from,
        "exposure_gain": gains,
        "known_positions": geo.n_known,
        "rotation_estimates_deg": _rotation_estimates(fit, geo),
        "frames": [
            {"image": str(fr.path), "residual_rms": float(r), "positions_image_mm": p.tolist()}
            for fr, r, p in zip(frames, fit.residual_rms, fit.positions_mm, strict=True)
        ],
        "warnings": warnings,
        "seconds": time.perf_counter() - t0,
    }
    sensor = CalibratedSensor(
        cfg,
        lib.manifest.get("manifest_sha256", ""),
        method,
        tuple(int(v) for v in shape),
        geo.pixel_mm,
        tuple(geo.origin_px),
        rot,
        fit.modulus_scale,
        fit.fringe_scale,
        fit.gamma,
        tuple(float(v) for v in black),
        illumination,
        rest["rest"],
        {k: _finite(v) for k, v in sd.items()},
        report,
        rest["residual"],
    )
    return SensorCalibration(sensor, fit, [str(fr.path) for fr in frames])


def _finite(v):
    """A 1-sigma for JSON: NaN (not determined) as None."""
    if isinstance(v, list):
        return [_finite(x) for x in v]
    v = float(v)
    return v if math.isfinite(v) else None
