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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.errors import ConfigError
from fringekit.inversion.figure import fit_figure
from fringekit.inversion.fit import WINDOW_MM, InvertResult, invert_image
from fringekit.inversion.model import ImageModel
from fringekit.inversion.read import pixel_grid, read_measurement, sensor_config
from fringekit.inversion.verdict import WARN_RESIDUAL, residual_warnings
from fringekit.library.store import Library, check_sensor, load_library
from fringekit.output.folders import atomic_write

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

    def table(self) -> dict[str, np.ndarray]:
        """The loads as columns named :data:`LOAD_COLUMNS` (mm and N), one row per
        indenter; ``reliable`` (bool) says where the residual near the indenter is
        small enough to stand behind its load."""
        r = self.result
        p, s = r.params, r.sd
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
        out["reliable"] = np.asarray(r.residual_rms) <= WARN_RESIDUAL
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


def _library(library: Library | str | os.PathLike) -> Library:
    return library if isinstance(library, Library) else load_library(library)


def invert(
    images: str | os.PathLike | Sequence[str | os.PathLike],
    library: Library | str | os.PathLike,
    *,
    pixel_mm: float,
    origin_px: tuple[float, float] | None = None,
    method: str | None = None,
    sensor: str | os.PathLike | None = None,
    progress: bool = False,
    echo=print,
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
        The pixel pitch on the sheet (mm).
    origin_px : (row, col), optional
        The pixel of the sensor origin; default the image centre.
    method : {"rgb", "mono", "phase"}, optional
        Default: ``rgb`` for one colour image, ``mono`` for one grey one, ``phase`` for six.
    sensor : path, optional
        The sensor's config (a TOML file or a ``predict`` folder); default the config of a
        ``predict`` folder the image lies in, else the library's own.
    progress : bool
        One line per stage through ``echo``.
    echo : callable
        Where the stage lines go.

    Returns
    -------
    Inversion
        The loads (:meth:`Inversion.table`), the fit and its summary; nothing is written.

    Raises
    ------
    ConfigError, LibraryError
        A bad option, image or library (before the fit).
    InvertError
        An image the library cannot explain (fringes no load in its range makes).

    Examples
    --------
    The small built-in sensor's 8 N dark-field image, read back with a small library of
    the same sensor (about 30 s in all on 2 cores):

    >>> import tempfile, fringekit
    >>> lib = fringekit.build_library("small", tempfile.mkdtemp() + "/lib",
    ...                               loads=[4, 8, 12], ratios=[0, 0.4], progress=False)
    >>> folder = fringekit.predict("small").write(tempfile.mkdtemp())
    >>> inv = fringekit.invert(folder / "state_01" / "dark_field.png", lib, pixel_mm=12 / 64)
    >>> loads = inv.table()
    >>> len(loads["Fz_N"]), bool(abs(loads["Fz_N"][0] - 8.0) < 0.4), bool(loads["reliable"][0])
    (1, True, True)
    """
    t0 = time.perf_counter()
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
    paths = [images] if isinstance(images, (str, os.PathLike)) else list(images)
    lib = _library(library)
    cfg, where = sensor_config(sensor, paths)
    warnings = []
    if cfg is None:
        cfg = load_config(lib.folder / "config.toml")
        warnings.append(
            "no sensor config given or found beside the image: the library's "
            "own sensor, camera and light are assumed (--sensor)"
        )
    else:
        check_sensor(lib, cfg, where)
    optics = optics_setup(cfg)
    method, measured, usable, nodata, shape = read_measurement(
        paths, method, optics.camera.sensitivities
    )
    o = cfg["optics"]
    model = ImageModel.build(
        lib,
        pixel_grid(shape, pixel_mm, origin_px),
        method,
        measured,
        usable,
        optics,
        light=o["light"],
        white_light_wavelengths=o["white_light_wavelengths"],
        nodata=nodata,
    )
    say = echo if progress else (lambda s: None)
    say(
        f"invert: {method}, {shape[0]} x {shape[1]} px, library {lib.folder} "
        f"({len(lib.load_N) - 1} loads x {len(lib.shear_ratio)} ratios)"
    )
    res = invert_image(model)
    warnings += residual_warnings(res.params, res.residual_rms)
    rms = ", ".join(f"{r:.3f}" for r in res.residual_rms)
    say(
        f"invert: {len(res.params)} indenter(s), residual_rms {rms or '-'} (within "
        f"{WINDOW_MM:g} mm of each, of the fringe amplitude), {time.perf_counter() - t0:.1f} s"
    )
    summary = {
        "method": method,
        "images": [str(p) for p in paths],
        "library": str(lib.folder),
        "sensor_config": where,
        "pixel_mm": pixel_mm,
        "origin_px": list(origin_px) if origin_px is not None else None,
        "n_indenters": int(len(res.params)),
        "iterations": int(res.iterations),
        "residual_rms": [float(r) for r in res.residual_rms],
        "noise_sd": res.noise,
        "gains": [float(g) for g in res.gains],
        "offsets": [float(o) for o in res.offsets],
        "warnings": warnings,
        "reliable": [bool(r <= WARN_RESIDUAL) for r in res.residual_rms],
        "times_s": {**res.times_s, "total_s": time.perf_counter() - t0},
    }
    return Inversion(method, res, model, summary)
