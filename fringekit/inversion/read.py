"""Reading what ``invert`` fits: the image files (decoded to linear intensity, with the
saturated and no-data pixels), the sensor's config, and the pixel grid."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import colour as cs
import numpy as np

from fringekit.analysis import grey_channel, load_image, load_six_step, strongest_channel
from fringekit.config.files import load_config
from fringekit.errors import ConfigError
from fringekit.measurement.mono import colour_as_grey
from fringekit.measurement.regions import no_data_regions
from fringekit.optics import PixelGrid

__all__ = [
    "Measurement",
    "censored_channels",
    "clipped_black",
    "frame_measurement",
    "pixel_arrays",
    "pixel_grid",
    "read_measurement",
    "sensor_config",
    "sensor_linear",
    "steps_measurement",
]


def _decode(frame, camera_name: str, colour: bool) -> np.ndarray:
    """Linear intensities of a frame in [0, 1]: sRGB decoding for the CIE observer."""
    if colour and camera_name == "CIE1931":
        return np.clip(cs.cctf_decoding(frame.data, function="sRGB"), 0.0, 1.0)
    return frame.data


def sensor_linear(raw: np.ndarray, sensor) -> np.ndarray | None:
    """Linear intensities (rows, cols, C) of stored values ``raw`` (rows, cols, C) through a
    calibrated sensor (its response undone, rest frame taken off, divided by its
    illumination), or None when ``sensor`` is None or not calibrated (a ``sensor init``
    file).

    Examples
    --------
    >>> sensor_linear(np.zeros((2, 2, 1)), None) is None
    True
    """
    if sensor is None or not sensor.calibrated:
        return None
    return sensor.correct(sensor.linear(raw))


def frame_measurement(
    frame, method: str, camera_name: str, sensor=None, channel=None, fitted=False
):
    """(linear (rows, cols, C), raw (rows, cols, C), unusable (rows, cols), note) of one
    :class:`~fringekit.analysis.Frame` read by ``method`` ``"rgb"`` or ``"mono"``: the
    colour image sRGB-decoded for the CIE observer, or its grey channel (the note says
    which channel of a colour photograph of monochromatic light is read; one whose channels
    disagree is refused, naming ``--method mono``). ``sensor``: a
    :class:`~fringekit.library.calibrated.CalibratedSensor`; when it is calibrated, its
    response, rest frame and illumination give the linear intensities instead.
    ``channel``: for mono, the colour channel (0-2) a colour frame is read in, chosen by
    the caller (a stream's, held from frame to frame); no note, no check. The unusable
    pixels are the saturated ones and, when a model is ``fitted`` to the frame pixel by
    pixel without censoring (``sensor calibrate``'s known frames; not a rest frame, whose
    light is subtracted), the colour pixels clipped at black (:func:`clipped_black`).
    ``invert`` and ``track`` keep those and censor the channels instead
    (:func:`censored_channels`)."""
    name = frame.source
    if method == "rgb" and frame.data.ndim != 3:
        raise ConfigError(f"--method rgb needs a colour image; {name} is grey")
    if method == "mono" and frame.data.ndim == 3 and channel is not None:
        data, note = frame.data[..., int(channel)], ""
    else:
        note = "" if method == "rgb" else colour_as_grey(frame.data, None, name, "--method mono")
        data = frame.data if method == "rgb" or frame.data.ndim == 2 else grey_channel(frame.data)
    raw = data.reshape(*data.shape[:2], -1)
    lin = sensor_linear(raw, sensor)
    if lin is None:
        lin = _decode(frame, camera_name, True).reshape(raw.shape) if method == "rgb" else raw
    if fitted:
        return lin, raw, frame.saturated | clipped_black(raw, method).any(axis=2), note
    return lin, raw, frame.saturated, note


def clipped_black(raw: np.ndarray, method: str) -> np.ndarray:
    """(rows, cols, C) bool: the channels of a colour image (``method`` rgb) at the bottom
    of their range, none for the other methods.

    A dark-field colour fringe outside the camera's gamut (the deep blues and purples of
    the first orders) has a channel below zero once its spectrum is turned into the
    camera's RGB: the camera stores 0 there, where the model goes on below it, so such a
    pixel misfits the right answer by up to its clipped depth. On the track bench's
    colour frames 3-4 % of the pixels had red or blue at 0 (the model down to -0.17 of
    full scale), and two contacts' residuals at the true loads were 3.1 times the
    noise's share; without those pixels 1.0-1.35 times, as in grey. A grey or phase
    intensity is never below zero in the model, so a pixel at 0 is the model's 0 there.
    ``invert`` and ``track`` compare the model with such a channel as the camera clips it
    (:meth:`~fringekit.inversion.model.ImageModel.misfit`); ``sensor calibrate`` leaves
    the pixel out of its known frames (:func:`frame_measurement`, ``fitted``).

    Parameters
    ----------
    raw : (rows, cols, C) array
        The stored values scaled to [0, 1] (before any decoding).
    method : {"rgb", "mono", "phase"}

    Examples
    --------
    >>> import numpy as np
    >>> raw = np.array([[[0.0, 0.3, 0.5], [0.2, 0.3, 0.5]]])
    >>> clipped_black(raw, "rgb")[..., 0].tolist(), clipped_black(raw[..., :1], "mono").any()
    ([[True, False]], np.False_)
    """
    if method != "rgb":
        return np.zeros(raw.shape, bool)
    return raw <= 0.0


def steps_measurement(frames) -> tuple[np.ndarray, np.ndarray]:
    """(raw (rows, cols, n), saturated (rows, cols)) of n phase-stepped
    :class:`~fringekit.analysis.Frame` objects: each step grey (a colour one as the mean
    of its channels), saturated where any step is.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import normalise
    >>> steps = [normalise(np.full((2, 3), 51 * k, np.uint8)) for k in range(6)]  # 255: saturated
    >>> raw, sat = steps_measurement(steps)
    >>> raw.shape, bool(sat[0, 0])
    ((2, 3, 6), True)
    """
    raw = np.stack([f.data if f.data.ndim == 2 else f.data.mean(-1) for f in frames], -1)
    return raw, np.any([f.saturated for f in frames], axis=0)


def pixel_arrays(lin: np.ndarray, raw: np.ndarray, sat: np.ndarray):
    """(linear (P, C), usable (P,), nodata (P,)) of an image's linear intensities
    (rows, cols, C), stored values and saturated pixels (rows, cols), P = rows * cols:
    usable pixels are neither saturated nor at the no-data fill level.

    Examples
    --------
    >>> import numpy as np
    >>> raw = np.full((2, 3, 1), 0.4)
    >>> sat = np.zeros((2, 3), bool)
    >>> sat[0, 0] = True
    >>> linear, usable, nodata = pixel_arrays(raw, raw, sat)
    >>> linear.shape, int(usable.sum()), int(nodata.sum())
    ((6, 1), 5, 0)
    """
    nodata = no_data_regions(raw).ravel()
    usable = ~sat.ravel() & ~nodata
    return lin.reshape(usable.size, -1), usable, nodata


@dataclass(frozen=True)
class Measurement:
    """The image ``invert`` fits, as :func:`read_measurement` reads it.

    Attributes
    ----------
    method : {"phase", "rgb", "mono"}
    linear : (P, C) float array
        Linear intensity, P = rows * cols; C = 6 (phase), 3 (rgb) or 1 (mono).
    usable : (P,) bool array
        Pixels neither saturated nor at the no-data fill level.
    nodata : (P,) bool array
        Pixels at the no-data fill level.
    shape : tuple of int
        (rows, cols).
    note : str
        Which channel of a colour photograph of monochromatic light mono reads (or "").
    channel : int or None
        That channel (0-2), for the rest frames to be read in it; None otherwise.
    censored : (P, C) bool array or None
        The colour channels clipped at black (:func:`clipped_black`), which bound the
        light rather than measure it (:attr:`~fringekit.inversion.model.ImageModel.censored`);
        None when there is none.

    Examples
    --------
    >>> import numpy as np
    >>> m = Measurement("mono", np.zeros((6, 1)), np.ones(6, bool), np.zeros(6, bool), (2, 3))
    >>> m.linear.reshape(*m.shape, -1).shape, m.channel
    ((2, 3, 1), None)
    """

    method: str
    linear: np.ndarray
    usable: np.ndarray
    nodata: np.ndarray
    shape: tuple
    note: str = ""
    channel: int | None = None
    censored: np.ndarray | None = None


def read_measurement(paths, method: str | None, camera_name: str, sensor=None) -> Measurement:
    """The :class:`Measurement` of the image files: usable pixels are neither saturated nor
    at the no-data fill level, and (rgb) channels clipped at black are censored; the note
    says which channel of a colour photograph of monochromatic light the mono method reads
    (one whose channels disagree is refused).
    ``sensor``: a :class:`~fringekit.library.calibrated.CalibratedSensor` whose response,
    rest frame and illumination are applied (its image size and method are checked by
    the caller).

    Examples
    --------
    A green-light photograph on a colour camera is read in its green channel:

    >>> import tempfile, numpy as np
    >>> from pathlib import Path
    >>> from fringekit.optics import write_image
    >>> path = Path(tempfile.mkdtemp()) / "green.png"
    >>> rgb = np.zeros((8, 8, 3), np.uint8)
    >>> rgb[..., 1] = np.linspace(10, 200, 64).reshape(8, 8)
    >>> write_image(path, rgb)
    >>> m = read_measurement([path], "mono", "none")
    >>> m.method, m.shape, m.linear.shape, m.channel
    ('mono', (8, 8), (64, 1), 1)
    """
    paths = [str(p) for p in paths]
    if method is None:
        single = len(paths) == 1
        method = ("rgb" if load_image(paths[0]).data.ndim == 3 else "mono") if single else "phase"
    want = 6 if method == "phase" else 1
    if len(paths) != want:
        raise ConfigError(f"--method {method} takes {want} image(s); got {len(paths)}")
    channel, censored = None, None
    if method == "phase":
        raw, sat = steps_measurement(load_six_step(paths))
        lin, note = sensor_linear(raw, sensor), ""
        lin = raw if lin is None else lin
    else:
        frame = load_image(paths[0])
        lin, raw, sat, note = frame_measurement(frame, method, camera_name, sensor)
        if method == "mono" and frame.data.ndim == 3:
            channel = strongest_channel(frame.data)
        censored = censored_channels(raw, method)
    linear, usable, nodata = pixel_arrays(lin, raw, sat)
    return Measurement(method, linear, usable, nodata, raw.shape[:2], note, channel, censored)


def censored_channels(raw: np.ndarray, method: str) -> np.ndarray | None:
    """(P, C) bool: the channels of stored values ``raw`` (rows, cols, C) clipped at black
    (:func:`clipped_black`), P = rows * cols; None when there is none.

    Examples
    --------
    >>> import numpy as np
    >>> censored_channels(np.array([[[0.0, 0.3, 0.5], [0.2, 0.3, 0.5]]]), "rgb").tolist()
    [[True, False, False], [False, False, False]]
    >>> censored_channels(np.zeros((2, 2, 1)), "mono") is None
    True
    """
    black = clipped_black(raw, method)
    return black.reshape(-1, black.shape[2]) if black.any() else None


def sensor_config(images) -> tuple[dict | None, str | None]:
    """The sensor config of an image read without ``--sensor``: the ``config.toml`` of a
    ``predict`` folder the first image lies in (or None, None)."""
    here = Path(images[0]).resolve().parent
    for folder in (here, here.parent, here.parent.parent):
        if (folder / "config.toml").is_file() and (folder / "summary.json").is_file():
            return load_config(folder / "config.toml"), str(folder / "config.toml")
    return None, None


def pixel_grid(shape, pixel_mm: float, origin_px) -> PixelGrid:
    """The sensor-frame pixel grid of an image of ``shape`` (rows, cols) at ``pixel_mm``
    (mm) with the origin at ``origin_px`` (row, col; default the image centre).

    An origin outside the image is refused (:class:`ConfigError`): the origin is a point
    of the sheet, so an image that holds it sees the sheet."""
    rows, cols = shape
    r0, c0 = origin_px if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    if not (-0.5 <= r0 <= rows - 0.5 and -0.5 <= c0 <= cols - 0.5):
        raise ConfigError(
            f"--origin-px {r0:g} {c0:g} lies outside the {rows} x {cols} image; allowed: "
            f"a pixel of it, rows 0..{rows - 1}, cols 0..{cols - 1} (default its centre)"
        )
    return PixelGrid.about_origin((rows, cols), pixel_mm * 1e-3, (r0, c0))
