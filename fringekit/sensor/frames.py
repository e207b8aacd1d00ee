"""The frames ``fringekit sensor calibrate`` reads: the rest frames, the dark frames and
the known-load frames with their table (``KNOWN.csv``).

Every frame is read as stored values in [0, 1] (no response undone: the calibration fits
the response), (rows, cols, C) with C = 3 for ``rgb`` and 1 for ``mono``; for ``phase``
a frame is six phase steps (in :data:`~fringekit.analysis.SIX_STEP_ORDER`; in KNOWN.csv
six file names joined by ``;``), each grey (a colour one as the mean of its channels), C
= 6. A bad file, a frame of another size or a table that cannot be read is one
:class:`~fringekit.errors.ConfigError` line naming it.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fringekit.analysis import normalise, read_pixels
from fringekit.errors import ConfigError, InputError
from fringekit.inversion.read import frame_measurement, steps_measurement
from fringekit.inversion.rest import PHASE_STEPS

__all__ = ["KNOWN_COLUMNS", "KnownFrame", "read_frame", "read_frames", "read_known", "read_steps"]

#: The columns of KNOWN.csv (``diameter_mm`` may be added: the sphere of each row).
KNOWN_COLUMNS = ("image", "x_mm", "y_mm", "Fx_N", "Fy_N", "Fz_N")


@dataclass(frozen=True)
class KnownFrame:
    """One frame of known loads.

    Attributes
    ----------
    path : Path
        The image (phase: its first step).
    raw : (rows, cols, C) stored values in [0, 1]
    usable : (rows * cols,) bool — not saturated and, for ``rgb``, no channel clipped
        at black in any of its files (:func:`~fringekit.inversion.read.clipped_black`)
    loads : (n, 5) x_mm, y_mm (NaN where the position is not known), Fx_N, Fy_N, Fz_N,
        in the sheet's axes
    diameters_mm : (n,) sphere diameters
    """

    path: Path
    raw: np.ndarray
    usable: np.ndarray
    loads: np.ndarray
    diameters_mm: np.ndarray


def read_frame(path, option: str):
    """One image file as a :class:`~fringekit.analysis.Frame`: a frame of one value (a dark
    frame, a sheet at rest free of residual stress) is read too."""
    try:
        return normalise(read_pixels(path), source=str(path))
    except (InputError, OSError, ValueError) as exc:
        raise ConfigError(f"{option} {path}: cannot be read ({exc})") from None


def _read(path, method: str, option: str, fitted: bool) -> tuple[np.ndarray, np.ndarray]:
    """(raw (rows, cols, C), unusable (rows, cols)) of one image file: saturated, or
    ``fitted`` and clipped at black (:func:`~fringekit.inversion.read.frame_measurement`)."""
    frame = read_frame(path, option)
    if method == "phase":  # one step: grey, a colour one as the mean of its channels
        raw, sat = steps_measurement([frame])
        return raw.astype(float), sat
    # stored values only
    _, raw, bad, _ = frame_measurement(frame, method, "none", fitted=fitted)
    return raw.astype(float), bad


def read_frames(
    paths, method: str, option: str, shape=None, fitted: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """The mean (rows, cols, C) of one or more frames of one size, and where any is
    saturated (rows * cols,); ``shape``: the size they must have (named in the error).
    ``fitted``: frames the model is fitted to (the known-load ones), where a colour pixel
    clipped at black in any frame is left out too: the model may go below the 0 stored
    there (:func:`~fringekit.inversion.read.clipped_black`); not the rest and dark
    frames, whose light is subtracted."""
    if not paths:
        raise ConfigError(f"{option}: give at least one image")
    frames, sats = [], []
    for p in paths:
        raw, sat = _read(p, method, option, fitted)
        want = (shape or frames[0].shape[:2]) if frames else shape
        if want is not None and raw.shape[:2] != tuple(want):
            raise ConfigError(
                f"{option} {p} is {raw.shape[0]} x {raw.shape[1]} px; the other frames are "
                f"{want[0]} x {want[1]} px: give frames of one camera and size"
            )
        frames.append(raw)
        sats.append(sat.ravel())
    return np.mean(frames, axis=0), np.any(sats, axis=0)


def read_steps(paths, option: str, shape=None) -> tuple[np.ndarray, np.ndarray]:
    """The six phase steps (rows, cols, 6) of one or more six-step sets (each step the mean
    over the sets), and where any frame is saturated (rows * cols,); a count of frames
    that is not a whole number of sets is refused in one line naming ``option``.

    Examples
    --------
    >>> try:
    ...     read_steps(["a.png"] * 4, "--reference")
    ... except ValueError as exc:
    ...     print(str(exc)[-14:])
    got 4 frame(s)
    """
    paths = list(paths)
    if not paths or len(paths) % PHASE_STEPS:
        raise ConfigError(
            f"{option}: give the six phase steps (or several sets of six, step by step); "
            f"got {len(paths)} frame(s)"
        )
    steps, sats = [], []
    for k in range(PHASE_STEPS):  # each step over the sets, all of one size
        m, sat = read_frames(paths[k::PHASE_STEPS], "phase", option, shape)
        shape = m.shape[:2]
        steps.append(m)
        sats.append(sat)
    return np.concatenate(steps, axis=-1), np.any(sats, axis=0)


def _number(row: dict, key: str, line: int, path, blank_ok: bool = False) -> float:
    text = (row.get(key) or "").strip()
    if text == "" and blank_ok:
        return math.nan
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise ConfigError(f"{path} line {line}: {key} {text!r} is not a number")
    return v


def _rows(path: Path) -> list[dict]:
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            missing = [c for c in KNOWN_COLUMNS if c not in (reader.fieldnames or [])]
            if missing:
                raise ConfigError(
                    f"--known {path}: no column {missing[0]!r}; the columns are "
                    f"{','.join(KNOWN_COLUMNS)} (diameter_mm optional)"
                )
            return list(reader)
    except OSError as exc:
        raise ConfigError(f"--known {path}: cannot be read ({exc.strerror})") from None


def read_known(path, method: str, lib, shape) -> list[KnownFrame]:
    """The known-load frames of ``KNOWN.csv`` (image paths relative to its folder), one per
    image, in the table's order; loads beyond the library's range, a missing image or one
    of another size than ``shape`` are refused, naming the line."""
    path = Path(path)
    rows = _rows(path)
    if not rows:
        raise ConfigError(f"--known {path}: no rows; give one row per contact of each image")
    by_image: dict[str, tuple] = {}
    for line, row in enumerate(rows, start=2):
        name = (row.get("image") or "").strip()
        files = _images(name, method, path, line)
        x, y = (_number(row, k, line, path, blank_ok=True) for k in ("x_mm", "y_mm"))
        if math.isnan(x) != math.isnan(y):
            raise ConfigError(f"{path} line {line}: give both x_mm and y_mm, or leave both blank")
        fx, fy, fz = (_number(row, k, line, path) for k in ("Fx_N", "Fy_N", "Fz_N"))
        d = _diameter(row, line, path, lib)
        _check_range(lib, fx, fy, fz, line, path)
        by_image.setdefault(name, (files, []))[1].append((x, y, fx, fy, fz, d))
    out = []
    for files, contacts in by_image.values():
        if method == "phase":
            raw, sat = read_steps(files, "--known image", shape)
        else:
            raw, sat = read_frames(files, method, "--known image", shape, fitted=True)
        a = np.array(contacts, float)
        out.append(KnownFrame(files[0], raw, ~sat, a[:, :5], a[:, 5]))
    return out


def _images(name: str, method: str, path: Path, line: int) -> list[Path]:
    """The files of a KNOWN.csv ``image`` cell (six joined by ``;`` for phase), each
    checked to be there."""
    names = [n.strip() for n in name.split(";")] if name else []
    want = PHASE_STEPS if method == "phase" else 1
    if len(names) != want:
        what = "six files joined by ';' (the phase steps)" if want > 1 else "one file"
        raise ConfigError(
            f"{path} line {line}: image {name!r} is not allowed; give {what} for --method {method}"
        )
    for n in names:
        if not n or not (path.parent / n).is_file():
            raise ConfigError(f"{path} line {line}: image {n!r} not found (in {path.parent})")
    return [path.parent / n for n in names]


def _diameter(row: dict, line: int, path, lib) -> float:
    if (row.get("diameter_mm") or "").strip():
        d = _number(row, "diameter_mm", line, path)
        if lib.nearest_diameter(d) is None:
            raise ConfigError(
                f"{path} line {line}: diameter_mm {d:g} is not one of the library's "
                f"({', '.join(f'{v:g}' for v in lib.diameters_mm)})"
            )
        return d
    if len(lib.diameters_mm) > 1:
        raise ConfigError(
            f"{path} line {line}: the library holds several sphere diameters; give a "
            "diameter_mm column"
        )
    return lib.diameters_mm[0]


def _check_range(lib, fx: float, fy: float, fz: float, line: int, path) -> None:
    ratio = math.hypot(fx, fy) / fz if fz > 0 else math.inf
    if not (0 < fz <= lib.max_load_N) or ratio > lib.max_ratio + 1e-9:
        raise ConfigError(
            f"{path} line {line}: Fz_N {fz:g} with tangential {math.hypot(fx, fy):g} N is "
            f"outside the library's range (Fz 0-{lib.max_load_N:g} N, tangential up to "
            f"{lib.max_ratio:g} Fz)"
        )
