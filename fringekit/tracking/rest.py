"""A stream's frames as the model sees them, and the sensor at rest (``track
--reference``).

A frame is decoded as ``invert`` decodes an image (:func:`frame_linear`): a colour frame
whose three channels are equal is a grey one; a calibrated sensor's response, rest frame
and illumination are applied. The light of a dark-field sensor at rest (the residual
birefringence of the sheet, the adhesive and the window, glare and ghosts of the partial
mirror) is not in the library's model. :class:`RestFrames` reads frames of the sensor at
rest, taken in the stream's light, and gives the smooth map of that light, which the
tracker takes off every frame.

Taking the rest light off as an intensity is exact for light that adds to the fringes'
(glare, ghosts of the partial mirror, stray and ambient light). For a residual
retardation it is an approximation that holds only where the residual is small. In a
circular dark field, a residual retarder (retardation d_r) in series with the load's
(d_l, principal directions dt apart) gives I = I0 (1 - cos d_r cos d_l - sin d_r sin
d_l cos 2dt) / 2 (the Poincare sphere's two rotations: Theocaris and Gdoutos, *Matrix
Theory of Photoelasticity*). Less the rest light I0 (1 - cos d_r) / 2, that is the
load's light times cos d_r, minus a cross term (I0 / 2) sin d_r sin d_l cos 2dt. At a
residual of 0.05 fringe (rest light 2.4 % of I0), the load's light is 5 % low, and the
cross term reaches 0.15 I0 where sin d_l = 1. A residual retarder has to be fitted as a
retarder (not yet done). With a calibrated sensor the reference replaces the sensor
file's rest map: both frames go through the sensor's correction, and their difference
is the frame's light less the reference's, over the illumination.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from fringekit.analysis import normalise, read_pixels
from fringekit.errors import ConfigError, InputError, SourceError
from fringekit.inversion.read import frame_measurement, steps_measurement
from fringekit.library.calibrated import coarse_map, fine_map
from fringekit.measurement.regions import no_data_regions
from fringekit.tracking.source import checked_pixels

__all__ = ["PHASE_STEPS", "RestFrames", "frame_linear", "grey", "steps_linear"]

#: Frames a load state takes with the phase method (the six phase steps, in
#: :data:`fringekit.analysis.SIX_STEP_ORDER`).
PHASE_STEPS = 6


def grey(raw: np.ndarray) -> np.ndarray:
    """The frame, (rows, cols) when it is grey: a colour frame whose three channels are
    equal (a grey camera's video) is one.

    Examples
    --------
    >>> import numpy as np
    >>> grey(np.ones((2, 3, 3), np.uint8)).shape
    (2, 3)
    """
    same = raw.ndim == 3 and all(np.array_equal(raw[..., 0], raw[..., c]) for c in (1, 2))
    return raw[..., 0] if same else raw


def frame_linear(raw: np.ndarray, method: str, camera: str, name: str, cal=None):
    """One decoded frame as the model sees it.

    Parameters
    ----------
    raw : (rows, cols) or (rows, cols, 3) array
        The frame's pixels as stored (integers or floats in [0, 1]).
    method : {"rgb", "mono"}
    camera : str
        The camera's sensitivities (the config's ``optics.camera``): CIE1931 colour frames
        are sRGB-decoded.
    name : str
        The frame's name, for messages.
    cal : CalibratedSensor, optional
        A sensor whose response, rest frame and illumination are applied.

    Returns
    -------
    measured : (P, C) array
        Linear intensities, P = rows * cols pixels, C = 3 (rgb) or 1 (mono).
    usable : (P,) bool array
        Neither saturated nor no-data.
    nodata : (P,) bool array
    note : str
        Which channel of a colour frame the mono method reads ("" for rgb).

    Examples
    --------
    >>> import numpy as np
    >>> m, usable, nodata, note = frame_linear(np.full((4, 5), 0.25), "mono", "CIE1931", "f")
    >>> m.shape, bool(usable.all()), float(m[0, 0])
    ((20, 1), True, 0.25)
    """
    frame = normalise(grey(raw), source=name)
    lin, data, sat, note = frame_measurement(frame, method, camera, cal)
    return _pixels(lin, data, sat, note)


def _pixels(lin, raw, sat, note: str):
    """(measured (P, C), usable (P,), nodata (P,), note) of a frame's linear intensities,
    stored values and saturated pixels: usable pixels are neither saturated nor no-data."""
    nodata = no_data_regions(raw)
    usable = (~sat & ~nodata).ravel()
    return lin.reshape(usable.size, -1), usable, nodata.ravel(), note


def steps_linear(images, names):
    """The six phase-stepped frames of one load state as the model sees them (as
    ``invert --method phase`` reads six images: each step grey, a colour one as the mean of
    its channels).

    Parameters
    ----------
    images : sequence of six (rows, cols) or (rows, cols, 3) arrays
        The steps' pixels as stored, in :data:`~fringekit.analysis.SIX_STEP_ORDER`.
    names : sequence of six str
        Their names, for messages.

    Returns
    -------
    measured : (P, 6) array
        The steps' intensities in [0, 1], P = rows * cols.
    usable : (P,) bool array
        Saturated in no step, and not no-data.
    nodata : (P,) bool array
    note : str
        Always "" (kept for :func:`frame_linear`'s shape).

    Examples
    --------
    >>> import numpy as np
    >>> steps = [np.full((4, 5), k * 40, np.uint8) for k in range(6)]
    >>> m, usable, nodata, note = steps_linear(steps, [f"s{k}" for k in range(6)])
    >>> m.shape, round(float(m[0, 5]), 3)
    ((20, 6), 0.784)
    """
    frames = [normalise(grey(im), source=n) for im, n in zip(images, names, strict=True)]
    raw, sat = steps_measurement(frames)
    return _pixels(raw, raw, sat, "")


@dataclass(frozen=True)
class RestFrames:
    """Frames of the sensor at rest (``track --reference``), as stored.

    Attributes
    ----------
    images : tuple of arrays
        The frames' pixels as stored, all of one size.
    names : tuple of str
        Their files.

    Examples
    --------
    A rest frame's glare, taken off a frame that holds it:

    >>> import tempfile, numpy as np
    >>> from pathlib import Path
    >>> from fringekit.optics import write_image
    >>> path = Path(tempfile.mkdtemp()) / "rest.png"
    >>> glare = np.linspace(0.1, 0.2, 48)[None, :].repeat(32, 0)
    >>> write_image(path, np.round(glare * 65535).astype(np.uint16))
    >>> rest = RestFrames.read([path])
    >>> light = rest.light((32, 48), "mono", "CIE1931")
    >>> frame, *_ = frame_linear(glare + 0.3, "mono", "CIE1931", "frame")
    >>> bool(np.allclose(frame - light, 0.3, atol=2e-3))
    True
    """

    images: tuple
    names: tuple

    @classmethod
    def read(cls, paths, option: str = "--reference") -> RestFrames:
        """Read ``paths`` (one path or several); an unreadable file, or frames of
        different sizes, are refused in one line naming ``option``."""
        paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
        if not paths:
            raise ConfigError(f"{option}: give at least one frame of the sensor at rest")
        images = []
        for p in paths:
            try:
                images.append(checked_pixels(read_pixels(p), f"{option} {p}"))
            except SourceError as exc:
                raise InputError(str(exc)) from None
            except (OSError, ValueError) as exc:
                raise InputError(f"{option}: {exc}") from None
        shapes = {im.shape[:2] for im in images}
        if len(shapes) > 1:
            sizes = ", ".join(f"{r} x {c}" for r, c in sorted(shapes))
            raise ConfigError(f"{option}: the rest frames differ in size ({sizes} px)")
        return cls(tuple(images), tuple(str(p) for p in paths))

    @property
    def shape(self) -> tuple[int, int]:
        """The frames' size (rows, cols)."""
        return tuple(self.images[0].shape[:2])

    def light(self, shape, method: str, camera: str, cal=None) -> np.ndarray:
        """The rest light (P, C) to take off every frame of ``shape`` (rows, cols): the
        frames decoded as the stream's (:func:`frame_linear`), averaged, and smoothed to
        the calibrated sensor's map grid (:func:`~fringekit.library.calibrated.coarse_map`,
        at most 64 cells a side), so that the rest frames' noise is not added to every
        frame. Frames of another size than the stream's are refused in one line."""
        if tuple(shape) != self.shape:
            raise ConfigError(
                f"--reference {self.names[0]} is {self.shape[0]} x {self.shape[1]} px; the "
                f"stream's frames are {shape[0]} x {shape[1]} px"
            )
        lins = [
            frame_linear(im, method, camera, n, cal)[0]
            for im, n in zip(self.images, self.names, strict=True)
        ]
        mean = np.mean(lins, axis=0).reshape(*shape, -1)
        return fine_map(coarse_map(mean), shape).reshape(mean.shape[0] * mean.shape[1], -1)
