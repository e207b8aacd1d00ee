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
cross term reaches 0.15 I0 where sin d_l = 1. A grey or colour frame cannot give the
residual's axis; the six phase steps can: for a phase stream the rest is read as a
retarder (:meth:`RestFrames.retarder`) and put into the model, in series with the loads'
retardation, as a stress frozen evenly through the sheet. With a calibrated sensor the
reference replaces the sensor file's rest map: both frames go through the sensor's
correction, and their difference is the frame's light less the reference's, over the
illumination.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from fringekit.analysis import (
    Frame,
    brightest_channel,
    channel_agreement,
    featureless,
    normalise,
    read_pixels,
    six_step,
    strongest_channel,
)
from fringekit.errors import ConfigError, InputError, SourceError
from fringekit.inversion.read import frame_measurement, steps_measurement
from fringekit.library.calibrated import MAP_CELLS, coarse_map, fine_map
from fringekit.measurement.mono import colour_as_grey
from fringekit.measurement.regions import no_data_regions
from fringekit.tracking.source import checked_pixels

__all__ = [
    "DECIDE_RANGE",
    "FOLD_NEAR",
    "PHASE_STEPS",
    "MonoChannel",
    "RestFrames",
    "frame_linear",
    "grey",
    "steps_linear",
]

#: A six-step rest's residual is read where it is below this share of half a fringe.
FOLD_NEAR = 0.9
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


def frame_linear(raw: np.ndarray, method: str, camera: str, name: str, cal=None, channel=None):
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
    channel : int or MonoChannel, optional
        For mono: the channel (0-2) a colour frame is read in, or the stream's
        :class:`MonoChannel`, which picks it; default the frame's own strongest, its
        channels checked to agree.

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
    if isinstance(channel, MonoChannel):
        channel = channel(frame.data, name) if method == "mono" else None
    lin, data, sat, note = frame_measurement(frame, method, camera, cal, channel)
    return _pixels(lin, data, sat, note)


class MonoChannel:
    """The one colour channel a mono stream of colour frames is read in.

    Every frame of a stream has to be read in one channel: the noise level, the gain and
    the rest light are the stream's, not the frame's. The channel is the light's: the
    strongest (:func:`~fringekit.analysis.strongest_channel`) of the first frame whose
    pattern spans DECIDE_RANGE of full scale in that channel, whose channels must agree
    (monochromatic light; white light is refused, naming ``--method mono``). A frame
    without such a pattern (the sensor at rest in even light, each channel its own noise;
    a light touch, whose weak channels are mostly noise) is read in the channel held, or,
    before any frame has decided it, in its brightest; the decision is never made again,
    so a stream is refused at its first strong frame or not at all. ``switched`` is set
    when the decision changes the channel the frames before it were read in (their noise
    level is then not the stream's).

    Examples
    --------
    A sensor at rest under a green LED, then loaded:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> led = np.array([0.15, 1.0, 0.3])
    >>> rest = 0.02 * led + rng.normal(0, 0.002, (32, 32, 3))
    >>> fringes = np.sin(np.linspace(0, 9, 32))[None, :, None] ** 2 * led * np.ones((32, 1, 1))
    >>> pick = MonoChannel()
    >>> pick(rest, "rest.png"), pick(fringes, "loaded.png")
    (1, 1)
    >>> print(pick.note)
    colour frames of monochromatic light (loaded.png's channels agree, correlation 1.00): read
    in their green channel
    """

    def __init__(self):
        self.index: int | None = None
        self.note = ""
        self.decided = False
        self.switched = False

    def __call__(self, data: np.ndarray, name: str) -> int | None:
        """The channel frame ``data`` (normalised, (rows, cols[, 3])) named ``name`` is
        read in; None for a grey frame."""
        if np.ndim(data) != 3:
            return None
        if self.decided:
            return self.index
        span = float(np.ptp(np.percentile(data, [1, 99], axis=(0, 1)), axis=0).max())
        if span < DECIDE_RANGE or featureless(data):
            if self.index is None:
                self.index = brightest_channel(data)
                self.note = (
                    "colour frames without a light pattern: read in their brightest channel, "
                    f"{_CHANNELS[self.index]}"
                )
            return self.index
        colour_as_grey(data, None, name, "--method mono")  # white light is refused
        before, self.decided = self.index, True
        self.index = strongest_channel(data)
        self.switched = before is not None and before != self.index
        earlier = (
            f"; the frames before it in their brightest, {_CHANNELS[before]}"
            if self.switched
            else ""
        )
        self.note = (
            f"colour frames of monochromatic light ({name}'s channels agree, correlation "
            f"{channel_agreement(data)[0]:.2f}): read in their {_CHANNELS[self.index]} "
            f"channel{earlier}"
        )
        return self.index


_CHANNELS = ("red", "green", "blue")
#: A stream's channel is decided by the first frame whose strongest channel's 1-99 %
#: range reaches this share of full scale: in a weaker pattern the faint channels are
#: mostly noise and disagree though the light is one colour (a touch peaking at 0.1 of
#: full scale under a green LED was refused as white light), and white light's channels
#: only part beyond about half an order, whose dark-field light is brighter than this.
DECIDE_RANGE = 0.2


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
    >>> light, unknown = rest.light((32, 48), "mono", "CIE1931")
    >>> frame, *_ = frame_linear(glare + 0.3, "mono", "CIE1931", "frame")
    >>> bool(np.allclose(frame - light, 0.3, atol=2e-3)), int(unknown.sum())
    (True, 0)
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

    def _check_size(self, shape) -> None:
        """Frames of another size than the stream's ``shape`` are refused in one line."""
        if tuple(shape) != self.shape:
            raise ConfigError(
                f"--reference {self.names[0]} is {self.shape[0]} x {self.shape[1]} px; the "
                f"stream's frames are {shape[0]} x {shape[1]} px"
            )

    def check_steps(self) -> None:
        """A phase stream's rest is whole six-step states: another count of frames is
        refused in one line."""
        if len(self.images) % PHASE_STEPS:
            raise ConfigError(
                "--reference with --method phase takes the six steps of the sensor at rest "
                f"(or of several rests, six each); got {len(self.images)} frame(s)"
            )

    def light(self, shape, method: str, camera: str, cal=None, channel=None):
        """The rest light to take off every frame of ``shape`` (rows, cols), and the
        pixels it is not known at.

        The frames are decoded as the stream's (:func:`frame_linear`, in its ``channel``),
        averaged, and smoothed to the calibrated sensor's map grid
        (:func:`~fringekit.library.calibrated.coarse_map`, at most 64 cells a side), so
        that the rest frames' noise is not added to every frame. Frames of another size
        than the stream's are refused in one line.

        Returns
        -------
        light : (P, C) array
            Linear intensity, P = rows * cols.
        unknown : (P,) bool array
            Pixels saturated in a rest frame, and those within two map cells of one
            (the smoothing's reach): there the rest light is at least full scale, not
            known, and the frames' pixels are left out of every fit.
        """
        self._check_size(shape)
        lins, sat = [], np.zeros(shape, bool)
        for im, n in zip(self.images, self.names, strict=True):
            lin, usable, nodata, _ = frame_linear(im, method, camera, n, cal, channel)
            lins.append(lin)
            sat |= ~(usable | nodata).reshape(shape)
        mean = np.mean(lins, axis=0).reshape(*shape, -1)
        light = fine_map(coarse_map(mean), shape).reshape(mean.shape[0] * mean.shape[1], -1)
        return light, _reach(sat)

    def retarder(self, shape, law) -> tuple[np.ndarray, np.ndarray]:
        """The residual retarder of the sheet from six-step rest frames, as the summed
        slab pair :class:`~fringekit.inversion.model.ImageModel` takes (``residual_ab``).

        The frames are one or more rests' six steps (in
        :data:`~fringekit.analysis.SIX_STEP_ORDER`), each step averaged over the rests.
        The six-step formulas (:func:`~fringekit.analysis.six_step`: Patterson and Wang,
        "Simultaneous observation of phase-stepped images for automated photoelasticity",
        J. Strain Anal. 33, 1998) give the rest's retardation d in [0, pi] and its axis t,
        exact where sin d > 0: for a residual under half a fringe, its Poincare rotation
        d (cos 2t, sin 2t). The model's rays turn a summed slab pair (a, b) through the
        double pass into a retarder of 2 k |(a, b)| at half the angle of (a, b)
        (:func:`~fringekit.optics.jones.retarder_spectrum`, k = 2 pi C / lambda at the
        reference wavelength), so (a, b) = d (cos 2t, sin 2t) / (2 k). It is smoothed as
        the rest light is (:meth:`light`). The formulas take the plates as ideal; light
        added evenly to the six steps cancels in their differences, light that differs
        from step to step biases them.

        Returns
        -------
        residual_ab : (P, 2) array
            Pa m, P = rows * cols.
        unknown : (P,) bool array
            Pixels saturated in a step, without modulation, or whose residual reaches
            FOLD_NEAR of half a fringe (beyond it the formulas fold it), and those within
            two map cells of them.

        Examples
        --------
        See ``tests/test_track.py``, which reads a residual back from the model's own six
        steps.
        """
        self._check_size(shape)
        self.check_steps()
        frames = [
            normalise(grey(im), source=n) for im, n in zip(self.images, self.names, strict=True)
        ]
        steps = []
        for k in range(PHASE_STEPS):  # each step averaged over the rests
            same = frames[k::PHASE_STEPS]
            data = np.mean([f.data for f in same], axis=0)
            sat = np.any([f.saturated for f in same], axis=0)
            steps.append(Frame(data, sat, same[0].bit_depth, same[0].source))
        res = six_step(steps)
        # near half a fringe the formulas fold the retardation and lose the axis
        ok = res.valid & (res.delta_axis_insensitive < FOLD_NEAR * np.pi)
        d = np.where(ok, res.delta_axis_insensitive, 0.0)
        v = d[..., None] * np.stack([np.cos(2 * res.isoclinic), np.sin(2 * res.isoclinic)], -1)
        k = float(law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0])
        ab = fine_map(coarse_map(v), shape) / (2.0 * k)
        return ab.reshape(-1, 2), _reach(~ok)


def _reach(bad: np.ndarray) -> np.ndarray:
    """(P,) pixels ``bad`` (rows, cols) and those within two map cells of one (the
    smoothing's reach, :func:`~fringekit.library.calibrated.coarse_map`)."""
    if not bad.any():
        return bad.ravel()
    reach = int(np.ceil(2 * max(1.0, max(bad.shape) / MAP_CELLS)))
    return ndimage.binary_dilation(bad, np.ones((2 * reach + 1,) * 2, bool)).ravel()
