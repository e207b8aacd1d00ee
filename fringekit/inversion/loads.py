"""The inverse as an API: :func:`invert` reads the loads off an image, :class:`Inversion`
holds them as a table and writes them.

:func:`invert` computes and writes nothing; :meth:`Inversion.write` gives the folder of
``fringekit invert``:

- ``loads.csv``: one row per indenter, exactly the columns :data:`LOAD_COLUMNS`: the
  axis position at first touch (mm, the frame of ``predict``: x to the right, y up, origin
  at ``origin_px``), sphere diameter, the force the indenter exerts on the sheet (N;
  Fz > 0 presses, Fx/Fy in the sense of a config's ``shear_N``), their 1-sigma and
  ``residual_rms``;
- ``summary.json``: method, image, library, sensor check, noise, gains, iterations,
  ``residual_rms`` (one per indenter, as in ``loads.csv``), warnings and times;
- ``fit.png``: measured, fitted and residual images, with arrows for the tangential
  loads; the residual in fringe amplitudes, each indenter's ``residual_rms`` on it.

``residual_rms`` is the one residual figure of ``invert`` (the terminal, ``loads.csv``,
``summary.json`` and ``fit.png`` all show it): per indenter, the RMS of measured minus
fitted intensity over the fitted pixels within ``WINDOW_MM`` (3 mm) of its axis, as a
fraction of the fitted fringe amplitude (the mean gain of the channels).
"""

from __future__ import annotations

import csv
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fringekit._memory import check_memory
from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.errors import ConfigError
from fringekit.inversion.budget import DEFAULT_MAX_SECONDS, Budget
from fringekit.inversion.detect import SMOOTH_MM, detection_bytes, noise_sd
from fringekit.inversion.figure import fit_figure
from fringekit.inversion.fit import WINDOW_MM, InvertResult
from fringekit.inversion.model import ImageModel
from fringekit.inversion.quick import invert_or_quick
from fringekit.inversion.read import pixel_grid, read_measurement, sensor_config
from fringekit.inversion.refine import refine_fem
from fringekit.inversion.rest import (
    check_rest_method,
    rest_frames,
    take_rest,
)
from fringekit.inversion.scale import check_scale
from fringekit.inversion.verdict import WARN_RESIDUAL, residual_warnings
from fringekit.library.calibrated import CalibratedSensor, as_calibrated
from fringekit.library.store import Library, check_sensor, load_library
from fringekit.output.folders import as_paths, atomic_write

__all__ = ["LOAD_COLUMNS", "Inversion", "invert"]

LOAD_COLUMNS = (
    "x_mm",
    "y_mm",
    "diameter_mm",
    "Fx_N",
    "Fy_N",
    "Fz_N",
    "sx_mm",
    "sy_mm",
    "sFx_N",
    "sFy_N",
    "sFz_N",
    "residual_rms",
)


@dataclass(frozen=True)
class Inversion:
    """Every indenter's position and load vector read off one image.

    Attributes
    ----------
    method : str
        ``"rgb"``, ``"mono"`` or ``"phase"``.
    result : InvertResult
        The fit: parameters (n, 5) x, y (mm), Fz, Fx, Fy (N), their 1-sigma, diameters
        (m), the residual near each indenter, gains, offsets, noise, iterations, times.
    model : ImageModel
        The image, its pixel grid and the library model (for figures and residuals).
    summary : dict
        What ``summary.json`` holds.
    sensor : CalibratedSensor or None
        The calibrated sensor the image was read with: ``result`` is in the image's
        axes, :meth:`table` in the sheet's.

    Examples
    --------
    See :func:`invert`; the table's columns are those of ``loads.csv``:

    >>> import fringekit
    >>> fringekit.inversion.LOAD_COLUMNS[:6]
    ('x_mm', 'y_mm', 'diameter_mm', 'Fx_N', 'Fy_N', 'Fz_N')
    """

    method: str
    result: InvertResult
    model: ImageModel = field(repr=False)
    summary: dict = field(repr=False)
    sensor: CalibratedSensor | None = field(default=None, repr=False)

    def table(self) -> dict[str, np.ndarray]:
        """The loads as columns named :data:`LOAD_COLUMNS` (mm and N), one row per
        indenter; ``reliable`` (bool) says where the residual near the indenter is
        small enough to stand behind its load, and the indenter lies on the sheet (never,
        when the time budget stopped the fit: ``result.stopped``)."""
        r = self.result
        p, s = r.params, r.sd
        if self.sensor is not None:
            p, s = self.sensor.to_sheet(p), self.sensor.to_sheet(s, sd=True)
        cols = (
            p[:, 0],
            p[:, 1],
            r.diameters * 1e3,
            p[:, 3],
            p[:, 4],
            p[:, 2],
            s[:, 0],
            s[:, 1],
            s[:, 3],
            s[:, 4],
            s[:, 2],
            r.residual_rms,
        )
        out = {k: np.asarray(v, float) for k, v in zip(LOAD_COLUMNS, cols, strict=True)}
        out["reliable"] = np.asarray(self.summary["reliable"], bool).reshape(len(p))
        return out

    def write(self, folder: str | os.PathLike) -> Path:
        """Write ``loads.csv``, ``summary.json`` and ``fit.png`` into ``folder`` (created
        if missing; files of those names are replaced); return it."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        table = self.table()
        with open(out / "loads.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(LOAD_COLUMNS)
            for row in zip(*(table[k] for k in LOAD_COLUMNS), strict=True):
                w.writerow([f"{x:.6g}" for x in row])
        fit_figure(out / "fit.png", self.model, self.result)
        atomic_write(out / "summary.json", json.dumps(self.summary, indent=2))
        return out


def _off_sheet(xy_mm: np.ndarray, sheet_mm) -> np.ndarray:
    """(n,) bool: which of the (n, 2) positions (mm, sensor frame) lie off a sheet of
    ``sheet_mm`` = (width, length) centred on the origin.

    Examples
    --------
    >>> _off_sheet(np.array([[0.0, 9.9], [-619.0, 619.0]]), (20, 20))
    array([False,  True])
    """
    half = np.asarray(sheet_mm, float) / 2
    return np.any(np.abs(np.asarray(xy_mm, float).reshape(-1, 2)) > half, axis=1)


def _off_sheet_warnings(params: np.ndarray, off: np.ndarray, sheet_mm) -> list[str]:
    """One warning per indenter found off the sheet (flagged not reliable)."""
    return [
        f"indenter {i + 1} at ({params[i, 0]:.2f}, {params[i, 1]:.2f}) mm lies off the "
        f"{sheet_mm[0]:g} x {sheet_mm[1]:g} mm sheet: not reliable (check --pixel-mm and "
        "--origin-px)"
        for i in np.flatnonzero(off)
    ]


def _check_numbers(pixel_mm, max_seconds) -> None:
    """Refuse a missing or non-positive ``pixel_mm`` and a negative ``max_seconds``."""
    if pixel_mm is None:
        raise ConfigError(
            "--pixel-mm is required: the pixel pitch on the sheet (mm), as "
            "predict's optics.field_of_view_mm / optics.pixels"
        )
    if not np.isfinite(pixel_mm) or pixel_mm <= 0:
        raise ConfigError(
            f"--pixel-mm {pixel_mm} is not allowed: give the pixel pitch on the sheet (mm, "
            "> 0), as predict's optics.field_of_view_mm / optics.pixels"
        )
    if not max_seconds >= 0:  # NaN too
        raise ConfigError(f"--max-seconds {max_seconds} is not allowed; give seconds >= 0")


def _sensor(lib: Library, cal, paths) -> tuple[dict, str | None, list[str]]:
    """The image's sensor config: the sensor file's, else that of a ``predict`` folder
    the image lies in (each checked against the library's), else the library's own with
    a warning."""
    if cal is not None:
        check_sensor(lib, cal.config, "--sensor")
        return cal.config, "the sensor file", []
    cfg, where = sensor_config(paths)
    if cfg is not None:
        check_sensor(lib, cfg, where)
        return cfg, where, []
    return (
        load_config(lib.folder / "config.toml"),
        where,
        [
            "no sensor file given nor predict config found beside the image: the "
            "library's own sensor, camera and light are assumed (--sensor)"
        ],
    )


def _library(library: Library | str | os.PathLike) -> Library:
    return library if isinstance(library, Library) else load_library(library)


def invert(
    images: str | os.PathLike | Sequence[str | os.PathLike],
    library: Library | str | os.PathLike,
    *,
    pixel_mm: float | None = None,
    origin_px: tuple[float, float] | None = None,
    method: str | None = None,
    sensor: str | os.PathLike | CalibratedSensor | None = None,
    reference: str | os.PathLike | Sequence[str | os.PathLike] | None = None,
    residual_steps: Sequence[str | os.PathLike] | None = None,
    refine: str | None = None,
    max_seconds: float = DEFAULT_MAX_SECONDS,
    progress: bool = False,
    echo=print,
    clock=time.monotonic,
) -> Inversion:
    """Every indenter's position and load vector from one image (or six phase steps).

    Parameters
    ----------
    images : path or sequence of paths
        One colour (``rgb``) or grey (``mono``) photograph, or the six phase-stepped
        images (``phase``).
    library : Library or path
        A response library of the same sensor (``fringekit library build``).
    pixel_mm : float
        The pixel pitch on the sheet (mm); required unless ``sensor`` is calibrated.
    origin_px : (row, col), optional
        The pixel of the sensor origin; default the image centre (or the calibrated
        sensor's).
    method : {"rgb", "mono", "phase"}, optional
        Default: ``rgb`` for one colour image, ``mono`` for one grey one, ``phase`` for six.
    sensor : path or CalibratedSensor, optional
        A sensor file (``.json``): of ``fringekit sensor calibrate`` (its config, scales,
        camera response, rest frame, illumination and geometry are applied), or of
        ``fringekit sensor init`` (a config, image size and pitch, nothing fitted); its
        library, image size and method must be these. Default: the config of a
        ``predict`` folder the image lies in, else the library's own.
    reference : path or sequence of paths, optional
        Frames of the sensor at rest, in the image's light (``--reference``;
        :mod:`fringekit.inversion.rest`). rgb and mono: their light (glare, ghosts, stray
        light), averaged and smoothed, is taken off the image (with a calibrated
        ``sensor``, in place of its rest map). phase: the six steps of the rest (or of
        several rests, six each), read as the sheet's residual retarder and put into the
        model in series with the loads' retardation. Pixels where the rest is not known
        (saturated; phase: no modulation, or a residual from 0.45 fringe on) are left
        out, with a warning; ``summary["reference"]`` reports it.
    residual_steps : sequence of paths, optional
        For rgb and mono (``--residual-steps``): the six phase steps of the sensor at rest
        (or 6n), taken once with the polariscope's plates stepped: the sheet's residual
        retarder, read from them as for phase, is put into the model, so that a residual
        beyond what a rest frame's subtraction serves (about 0.05 fringe) is modelled.
        Not with ``reference`` (a dark-field rest frame holds the residual's light, which
        the model then makes).
    refine : {None, "fem"}
        ``"fem"``: after the library fit, rounds of full-FEM defect correction until no
        position or load moves by more than its 1-sigma (one FEM solve each, minutes:
        :mod:`fringekit.inversion.refine`); ``summary["refine"]`` reports them.
    max_seconds : float
        The time budget (s; default 600): once spent, the fit stops at the end of its
        stage and the answer is that stage's, every indenter flagged not reliable
        (``summary["stopped_after"]`` names the stage; after detection only the
        positions are known, the loads are NaN). ``math.inf``: no budget.
    progress : bool
        One line per stage (detection, start scan, far fit, near fit, each round of the
        basin search and of the model selection) through ``echo``.
    echo : callable
        Where the stage lines go.
    clock : callable
        Seconds, read at the end of each stage only (the budget's clock).

    Returns
    -------
    Inversion
        The loads (:meth:`Inversion.table`), the fit and its summary; nothing is written.

    Raises
    ------
    ConfigError, LibraryError
        A bad option, image or library (before the fit).
    InvertError
        An image the library cannot explain (fringes no load in its range makes), or
        whose fringe spacing contradicts ``pixel_mm`` (before the fit).

    Examples
    --------
    The small built-in sensor's 8 N dark-field image under full stick (what a library
    models), read back with a small library of the same sensor (about 40 s in all on 2
    cores; the frictionless image, whose surface flows inwards under the sphere, reads
    8.40 N):

    >>> import tempfile, fringekit
    >>> lib = fringekit.build_library("small", tempfile.mkdtemp() + "/lib",
    ...                               loads=[4, 8, 12], ratios=[0, 0.4], progress=False)
    >>> stick = fringekit.Config.builtin("small").replace({"contact.friction": "stick"})
    >>> folder = fringekit.predict(stick).write(tempfile.mkdtemp())
    >>> inv = fringekit.invert(folder / "state_01" / "dark_field.png", lib, pixel_mm=12 / 64)
    >>> loads = inv.table()
    >>> len(loads["Fz_N"]), bool(abs(loads["Fz_N"][0] - 8.0) < 0.2), bool(loads["reliable"][0])
    (1, True, True)
    """
    t0 = time.perf_counter()
    if refine not in (None, "fem"):
        raise ConfigError(f"--refine {refine!r} is not allowed; give fem (or leave it out)")
    cal = as_calibrated(sensor)
    if cal is not None:
        pixel_mm, origin_px = cal.grid_options(pixel_mm, origin_px)
    _check_numbers(pixel_mm, max_seconds)
    say = echo if progress else (lambda s: None)
    budget = Budget(max_seconds, say=say, clock=clock)  # the whole run's
    paths = as_paths(images)
    lib = _library(library)
    rest = rest_frames(reference, residual_steps)
    if cal is not None:
        cal.check(lib)
    cfg, where, warnings = _sensor(lib, cal, paths)
    optics = optics_setup(cfg)
    meas = read_measurement(paths, method, optics.camera.sensitivities, cal)
    method, shape = meas.method, meas.shape
    if cal is not None:
        lib, optics = cal.model_inputs(lib, optics, shape, method)
    if meas.note:
        warnings.append(meas.note)
    measured, usable, residual_ab, rest_info = _with_rest(
        rest, method, meas.channel, meas.linear, meas.usable, shape, optics, cal, warnings
    )
    check_memory(
        detection_bytes(shape, pixel_mm),
        f"detection's smoothing over {SMOOTH_MM} mm ({SMOOTH_MM / (2 * pixel_mm):.3g} px)",
        f"--pixel-mm {pixel_mm:g}",
        hint="give the pixel pitch on the sheet (mm)",
        error=ConfigError,
    )
    sheet_mm = (cfg["sheet"]["width_mm"], cfg["sheet"]["length_mm"])
    grid = pixel_grid(shape, pixel_mm, origin_px)
    wl = {k: cfg["optics"][k] for k in ("light", "white_light_wavelengths")}
    model = ImageModel.build(lib, grid, method, measured, usable, optics, nodata=meas.nodata, **wl)
    model = replace(model, residual_ab=residual_ab, censored=meas.censored)
    say(
        f"invert: {method}, {shape[0]} x {shape[1]} px, library {lib.folder} "
        f"({len(lib.load_N) - 1} loads x {len(lib.shear_ratio)} ratios)"
    )
    noise = noise_sd(model)
    scale = check_scale(model, pixel_mm, noise)
    if scale is not None:
        lo, hi = scale["pixel_mm_range"]
        say(f"invert: scale check: the fringes suggest {lo:.3g}-{hi:.3g} mm per pixel")
    t_read = time.perf_counter() - t0  # the library, the image, its noise and scale check
    res = invert_or_quick(model, budget=budget, noise=noise)
    fit_times = res.times_s
    res, refined, more = _refine(refine, model, res, cfg, lib, optics, cal, say)
    warnings += more
    more, off = _verdicts(res, cal, sheet_mm, max_seconds)
    warnings += more
    say(_result_line(res, time.perf_counter() - t0))
    summary = {
        "method": method,
        "images": [str(p) for p in paths],
        "library": str(lib.folder),
        "sensor_config": where,
        "calibrated_sensor": None if cal is None else cal.summary(_source(sensor)),
        "reference": rest_info,
        "pixel_mm": pixel_mm,
        "origin_px": list(origin_px) if origin_px is not None else None,
        "n_indenters": int(len(res.params)),
        "iterations": int(res.iterations),
        "residual_rms": [float(r) if np.isfinite(r) else None for r in res.residual_rms],
        "noise_sd": res.noise,
        "gains": [float(g) for g in res.gains],
        "offsets": [float(o) for o in res.offsets],
        "warnings": warnings,
        "reliable": [
            bool(r <= WARN_RESIDUAL and not o and res.stopped is None)
            for r, o in zip(res.residual_rms, off, strict=True)
        ],
        "max_seconds": max_seconds if np.isfinite(max_seconds) else None,
        "stopped_after": res.stopped,
        "scale_check": scale,
        "refine": refined,
        "times_s": _time_split(t_read, fit_times, refined, time.perf_counter() - t0),
    }
    return Inversion(method, res, model, summary, cal)


def _time_split(read_s: float, fit: dict, refined: dict | None, total_s: float) -> dict:
    """``summary.json``'s ``times_s``: reading the inputs, each kind of stage of the fit
    (:meth:`~fringekit.inversion.budget.Budget.stage_times`; the fit's own total as
    ``fit_s``), ``--refine fem`` (its report's ``time_s``) and the whole run (s)."""
    stages = {k: v for k, v in fit.items() if k != "total_s"}
    return {
        "read_s": read_s,
        **stages,
        "fit_s": fit.get("total_s"),
        "refine_s": refined.get("time_s", 0.0) if refined else 0.0,
        "total_s": total_s,
    }


def _result_line(res: InvertResult, seconds: float) -> str:
    """The stage line of the answer: indenters, residuals (or where the budget cut the
    fit short) and the time."""
    rms = ", ".join(f"{r:.3f}" for r in res.residual_rms)
    cut = f"cut short after the {res.stopped}" if res.stopped else None
    what = cut or (
        f"residual_rms {rms or '-'} (within {WINDOW_MM:g} mm of each, of the fringe amplitude)"
    )
    return f"invert: {len(res.params)} indenter(s), {what}, {seconds:.1f} s"


def _with_rest(rest, method, channel, measured, usable, shape, optics, cal, warnings):
    """(measured, usable, residual_ab, summary) with the rest taken into account
    (:func:`~fringekit.inversion.rest.take_rest`), its warnings added to ``warnings``;
    ``--residual-steps`` with phase refused.
    ``channel``: the colour channel a mono colour photograph is read in (the rest frames
    are read in it too)."""
    check_rest_method(rest, method, cal)
    measured, usable, residual_ab, info, more = take_rest(
        rest, method, measured, usable, shape, optics, cal, channel
    )
    warnings += more
    return measured, usable, residual_ab, info


def _source(sensor) -> str | None:
    return None if isinstance(sensor, CalibratedSensor) else str(sensor)


def _refine(refine, model, res: InvertResult, cfg, lib, optics, cal, say):
    """The result after ``--refine fem``, its report (None without it, or when the fit
    found nothing or was cut short; with the seconds it took as ``time_s``) and its
    warnings. A solve that fails leaves the library's answer, with the failure in the
    report and a warning."""
    if refine is None or not len(res.params) or res.stopped is not None:
        return res, None, []
    t0 = time.perf_counter()
    res, report, warnings = _refine_rounds(model, res, cfg, lib, optics, cal, say)
    return res, {**report, "time_s": time.perf_counter() - t0}, warnings


def _refine_rounds(model, res: InvertResult, cfg, lib, optics, cal, say):
    """:func:`_refine`'s rounds: (result, report, warnings)."""
    friction = lib.manifest.get("grid", {}).get("friction", "stick")
    try:
        res, report = refine_fem(model, res, cfg, friction, optics, sensor=cal, say=say)
    except RuntimeError as exc:
        msg = f"--refine fem: the FEM solve failed ({exc}); the library's answer is kept"
        return res, {"rounds": [], "converged": False, "failed": str(exc)}, [msg]
    n = len(report["rounds"])
    if report["converged"]:
        return res, report, []
    return (
        res,
        report,
        [f"--refine fem: a load or position still moved by more than its 1-sigma after {n} rounds"],
    )


def _verdicts(res: InvertResult, cal, sheet_mm, max_seconds) -> tuple[list[str], np.ndarray]:
    """The fit's warnings (time budget, residuals, indenters off the sheet: positions in
    the sheet's axes) and which indenters lie off the sheet."""
    sheet = res.params if cal is None else cal.to_sheet(res.params)
    off = _off_sheet(sheet[:, :2], sheet_mm)
    warnings = _stopped_warnings(res, max_seconds) + residual_warnings(sheet, res.residual_rms)
    return warnings + _off_sheet_warnings(sheet, off, sheet_mm), off


def _stopped_warnings(res: InvertResult, max_seconds: float) -> list[str]:
    """The warning of an answer the time budget cut short (none for a finished fit)."""
    if res.stopped is None:
        return []
    what = (
        "only the positions are known (the loads are NaN)"
        if res.stopped == "detection"
        else "the loads are that stage's, not a converged fit"
    )
    return [
        f"--max-seconds {max_seconds:g} ran out after the {res.stopped}: {what}; every "
        "indenter is flagged not reliable (give a larger --max-seconds)"
    ]
