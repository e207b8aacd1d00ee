"""Frames as the model sees them, and the sensor at rest (``--reference`` and
``--residual-steps`` of ``invert`` and ``track``).

A frame is decoded as ``invert`` decodes an image (:func:`frame_linear`): a colour frame
whose three channels are equal is a grey one; a calibrated sensor's response, rest frame
and illumination are applied. The light of a dark-field sensor at rest (the residual
birefringence of the sheet, the adhesive and the window, glare and ghosts of the partial
mirror) is not in the library's model. :class:`RestFrames` reads frames of the sensor at
rest, taken in the measurement's light, and gives the smooth map of that light, which is
taken off the image (or every frame of a stream).

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
residual's axis; the six phase steps can: for the phase method the rest is read as a
retarder (:meth:`RestFrames.retarder`) and put into the model, in series with the loads'
retardation, as a stress frozen evenly through the sheet; a grey image's model holds it
likewise when six rest steps are given (``--residual-steps``). With a calibrated sensor the
reference replaces the sensor file's rest map: both frames go through the sensor's
correction, and their difference is the frame's light less the reference's, over the
illumination.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from fringekit.analysis import normalise, read_pixels, six_step
from fringekit.errors import ConfigError, InputError, SourceError
from fringekit.inversion.read import (
    frame_measurement,
    pixel_arrays,
    sensor_linear,
    steps_measurement,
)
from fringekit.library.calibrated import MAP_CELLS, coarse_map, fine_map
from fringekit.output.folders import as_paths

__all__ = [
    "FOLD_NEAR",
    "BRIGHT_REST",
    "PHASE_STEPS",
    "RESIDUAL_STEPS",
    "RestFrames",
    "check_rest_method",
    "checked_pixels",
    "frame_linear",
    "grey",
    "residual_fringes",
    "rest_frames",
    "rest_summary",
    "sensor_residual",
    "steps_linear",
    "steps_retarder",
    "take_rest",
    "bright_rest_warning",
    "unknown_warning",
]

#: The option of six rest steps that give a grey measurement the sheet's residual
#: retarder (``invert`` and ``track``'s ``--residual-steps``).
RESIDUAL_STEPS = "--residual-steps"
#: A dark-field rest light whose mean over the frame is above this share of full scale is
#: warned of: a dark field at rest is dark (six phase steps average about half).
BRIGHT_REST = 0.3
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


def checked_pixels(img: np.ndarray, where: str) -> np.ndarray:
    """A decoded image as a frame's image: alpha dropped, (rows, cols) or (rows, cols, 3),
    uint8 or uint16; another shape or type is refused in one line that begins with
    ``where`` (:class:`~fringekit.errors.SourceError`).

    Examples
    --------
    >>> import numpy as np
    >>> checked_pixels(np.zeros((2, 3, 4), np.uint8), "frame 0").shape
    (2, 3, 3)
    """
    if img.ndim == 3 and img.shape[2] in (1, 2):  # grey, grey + alpha
        img = img[..., 0]
    elif img.ndim == 3 and img.shape[2] == 4:  # RGBA
        img = img[..., :3]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise SourceError(
            f"{where}: image shape {img.shape} is not allowed (a stack of pages?); allowed: "
            "one (rows, cols) grey or (rows, cols, 3) colour image per file"
        )
    if img.dtype not in (np.uint8, np.uint16):
        raise SourceError(
            f"{where}: pixel type {img.dtype} is not allowed; allowed: 8- or 16-bit integer images"
        )
    return np.ascontiguousarray(img)


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
    channel : int or callable, optional
        For mono: the channel (0-2) a colour frame is read in, or a callable that picks it
        from the normalised frame and its name (a stream's
        :class:`~fringekit.tracking.channel.MonoChannel`); default the frame's own
        strongest, its channels checked to agree.

    Returns
    -------
    measured : (P, C) array
        Linear intensities, P = rows * cols pixels, C = 3 (rgb) or 1 (mono).
    usable : (P,) bool array
        Neither saturated nor no-data (a colour channel clipped at black is the
        caller's to censor: :func:`~fringekit.inversion.read.censored_channels`).
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
    if callable(channel):
        channel = channel(frame.data, name) if method == "mono" else None
    lin, data, sat, note = frame_measurement(frame, method, camera, cal, channel)
    return (*pixel_arrays(lin, data, sat), note)


def steps_linear(images, names, cal=None):
    """The six phase-stepped frames of one load state as the model sees them (as
    ``invert --method phase`` reads six images: each step grey, a colour one as the mean of
    its channels; through the calibrated sensor ``cal``, when given).

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
    lin = sensor_linear(raw, cal)
    return (*pixel_arrays(raw if lin is None else lin, raw, sat), "")


@dataclass(frozen=True)
class RestFrames:
    """Frames of the sensor at rest (``--reference``, ``--residual-steps``), as stored.

    Attributes
    ----------
    images : tuple of arrays
        The frames' pixels as stored, all of one size.
    names : tuple of str
        Their files.
    option : str
        The option that gave them, for messages.

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
    option: str = "--reference"

    @classmethod
    def read(cls, paths, option: str = "--reference") -> RestFrames:
        """Read ``paths`` (one path or several); an unreadable file, or frames of
        different sizes, are refused in one line naming ``option``."""
        paths = as_paths(paths)
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
        return cls(tuple(images), tuple(str(p) for p in paths), option)

    @property
    def shape(self) -> tuple[int, int]:
        """The frames' size (rows, cols)."""
        return tuple(self.images[0].shape[:2])

    def _check_size(self, shape) -> None:
        """Frames of another size than the measurement's ``shape`` are refused in one
        line."""
        if tuple(shape) != self.shape:
            raise ConfigError(
                f"{self.option} {self.names[0]} is {self.shape[0]} x {self.shape[1]} px; the "
                f"measured frames are {shape[0]} x {shape[1]} px"
            )

    def are_steps(self, method: str) -> bool:
        """Whether the frames are six-step sets read as the residual retarder
        (:meth:`retarder`): phase's ``--reference`` and ``--residual-steps``; otherwise
        they are the rest light to take off (:meth:`light`)."""
        return method == "phase" or self.option == RESIDUAL_STEPS

    def check_steps(self) -> None:
        """Six-step rest frames (phase's ``--reference``, ``--residual-steps``) are whole
        six-step sets: another count of frames is refused in one line."""
        if len(self.images) % PHASE_STEPS:
            where = self.option + (" with --method phase" if self.option == "--reference" else "")
            raise ConfigError(
                f"{where}: the residual retarder is read from the six phase steps of "
                "the sensor at rest (or of several rests, six each); got "
                f"{len(self.images)} frame(s)"
            )

    def light(self, shape, method: str, camera: str, cal=None, channel=None):
        """The rest light to take off a measurement of ``shape`` (rows, cols) (an image, or
        every frame of a stream), and the pixels it is not known at.

        The frames are decoded as the measurement (:func:`frame_linear`, in its
        ``channel``), averaged, and smoothed to the calibrated sensor's map grid
        (:func:`~fringekit.library.calibrated.coarse_map`, at most 64 cells a side), so
        that the rest frames' noise is not added to the measurement. Frames of another
        size are refused in one line.

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
            name = f"{self.option} {n}"
            lin, usable, nodata, _ = frame_linear(im, method, camera, name, cal, channel)
            lins.append(lin)
            sat |= ~(usable | nodata).reshape(shape)
        mean = np.mean(lins, axis=0).reshape(*shape, -1)
        light = fine_map(coarse_map(mean), shape).reshape(mean.shape[0] * mean.shape[1], -1)
        return light, _reach(sat)

    def retarder(self, shape, law, cal=None) -> tuple[np.ndarray, np.ndarray]:
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
        from step to step biases them. ``cal``: a calibrated sensor, whose response is
        undone first (the formulas need linear intensities).

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
        See ``tests/test_residual_retarder.py``, which reads a residual back from the
        model's own six steps.
        """
        self._check_size(shape)
        self.check_steps()
        frames = [
            normalise(grey(im), source=n) for im, n in zip(self.images, self.names, strict=True)
        ]
        data = np.stack(  # each step averaged over the rests
            [np.mean([f.data for f in frames[k::PHASE_STEPS]], axis=0) for k in range(PHASE_STEPS)],
            -1,
        )
        sat = np.any([f.saturated for f in frames], axis=0)
        lin = sensor_linear(data, cal)
        return steps_retarder(data if lin is None else lin, sat, law)


def steps_retarder(steps: np.ndarray, saturated: np.ndarray | None, law):
    """The residual retarder of six rest steps (the kernel of :meth:`RestFrames.retarder`).

    Parameters
    ----------
    steps : (rows, cols, 6) array
        The steps' linear intensities, in :data:`~fringekit.analysis.SIX_STEP_ORDER`.
    saturated : (rows, cols) bool array or None
        Pixels saturated in a step (None: none).
    law : StressOpticLaw
        The sheet's (its fringe value sets the slab pair of a retardation).

    Returns
    -------
    residual_ab : (P, 2) array
        Pa m, P = rows * cols.
    unknown : (P,) bool array
        As :meth:`RestFrames.retarder`'s.

    Examples
    --------
    A residual of 0.15 fringe (the double pass) read back from its six steps:

    >>> import fringekit
    >>> from fringekit.config.inputs import optics_setup
    >>> from fringekit.optics import intensity, six_step_arrangements
    >>> from fringekit.optics.jones import retarder_spectrum
    >>> law = optics_setup(fringekit.Config.builtin("small").data).law
    >>> k = law.retardation_per_stress_length(np.array([law.wavelength_ref]))
    >>> a = np.full(64, 0.15 * 2 * np.pi / k[0])  # one ray's retardation 2 pi 0.15 rad
    >>> q = retarder_spectrum(a * np.cos(0.4), a * np.sin(0.4), k)[:, 0].reshape(8, 8, 4)
    >>> steps = np.stack([intensity(q, s) for s in six_step_arrangements()], -1)
    >>> ab, unknown = steps_retarder(steps, None, law)
    >>> round(float(residual_fringes(ab, law).mean()), 6), int(unknown.sum())
    (0.15, 0)
    """
    res = six_step([steps[..., k] for k in range(PHASE_STEPS)])
    if saturated is None:
        saturated = np.zeros(steps.shape[:2], bool)
    # near half a fringe the formulas fold the retardation and lose the axis
    ok = res.valid & ~saturated & (res.delta_axis_insensitive < FOLD_NEAR * np.pi)
    d = np.where(ok, res.delta_axis_insensitive, 0.0)
    v = d[..., None] * np.stack([np.cos(2 * res.isoclinic), np.sin(2 * res.isoclinic)], -1)
    k = float(law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0])
    ab = fine_map(coarse_map(v), steps.shape[:2]) / (2.0 * k)
    return ab.reshape(-1, 2), _reach(~ok)


def _reach(bad: np.ndarray) -> np.ndarray:
    """(P,) pixels ``bad`` (rows, cols) and those within two map cells of one (the
    smoothing's reach, :func:`~fringekit.library.calibrated.coarse_map`)."""
    if not bad.any():
        return bad.ravel()
    reach = int(np.ceil(2 * max(1.0, max(bad.shape) / MAP_CELLS)))
    return ndimage.binary_dilation(bad, np.ones((2 * reach + 1,) * 2, bool)).ravel()


def rest_frames(reference, residual_steps) -> RestFrames | None:
    """The frames of the sensor at rest: ``--reference``'s, or the six rest steps of
    ``--residual-steps`` (whole six-step sets); the two together are refused in one line.

    Examples
    --------
    >>> rest_frames(None, None) is None
    True
    """
    if residual_steps is None:
        return None if reference is None else RestFrames.read(reference)
    if reference is not None:
        raise ConfigError(
            "--residual-steps with --reference is not allowed: the rest frame holds the "
            "residual's light, which the model makes from the steps; give one of them"
        )
    steps = RestFrames.read(residual_steps, RESIDUAL_STEPS)
    steps.check_steps()
    return steps


def check_rest_method(rest: RestFrames | None, method: str | None, cal=None) -> None:
    """``--residual-steps`` serves the mono method of a sensor without a rest map: with
    ``method`` phase (which takes its rest steps as ``--reference``), rgb (white light,
    sRGB-decoded, which steps read as stored do not match), or a calibrated sensor ``cal``
    whose rest map holds the residual's light (which the model would make again), it is
    refused in one line.

    Examples
    --------
    >>> check_rest_method(None, "phase")
    """
    if rest is None or rest.option != RESIDUAL_STEPS:
        return
    if method == "phase":
        raise ConfigError(
            "--residual-steps is for --method mono; with --method phase give the six rest "
            "steps as --reference"
        )
    if method == "rgb":
        raise ConfigError(
            "--residual-steps is for --method mono: the six steps are read as stored, in "
            "the monochromatic light of the grey image; a white-light rgb image is not "
            "served yet (use --method mono, or a phase rest with --method phase)"
        )
    if cal is not None and cal.calibrated and cal.rest is not None:
        raise ConfigError(
            "--residual-steps with a calibrated --sensor is not allowed yet: its rest map "
            "holds the residual's light, which the model would make again from the steps; "
            "give a sensor file without one (sensor init), or leave out --residual-steps"
        )


def residual_fringes(residual_ab: np.ndarray, law) -> np.ndarray:
    """(P,) the retardation (fringes, the double pass) of a residual's summed slab pairs
    ``residual_ab`` (P, 2) (Pa m) at the reference wavelength: 2 k |(a, b)| / 2 pi
    (:meth:`RestFrames.retarder`).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED as law
    >>> k = float(law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0])
    >>> ab = np.array([[0.25 * np.pi / k, 0.0]])  # pi / 2 through the double pass
    >>> residual_fringes(ab, law).round(6)
    array([0.25])
    """
    k = float(law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0])
    return 2.0 * k * np.hypot(*np.asarray(residual_ab, float).T) / (2.0 * np.pi)


def rest_summary(rest: RestFrames | None, light=None, unknown=None, fringes=None):
    """``summary["reference"]``: the rest frames, the light taken off (its mean and
    largest value per channel, linear 0-1, from ``light`` (P, C)) or (phase) the residual
    retarder's mean and largest retardation (``fringes`` (P,), in fringes), and the count
    of pixels left out where it is not known (``unknown`` (P,) bool); None without a
    reference.

    Examples
    --------
    >>> import numpy as np
    >>> rest = RestFrames((np.zeros((2, 2), np.uint8),), ("rest.png",))
    >>> rest_summary(rest, light=np.full((4, 1), 0.1), unknown=np.zeros(4, bool))
    {'frames': ['rest.png'], 'light_mean': [0.1], 'light_max': [0.1], 'unknown_px': 0}
    """
    if rest is None:
        return None
    out: dict = {"frames": list(rest.names)}
    if light is not None:
        out["light_mean"] = [float(v) for v in light.mean(0)]
        out["light_max"] = [float(v) for v in light.max(0)]
    if fringes is not None:
        out["residual_mean_fringe"] = float(fringes.mean())
        out["residual_max_fringe"] = float(fringes.max())
    if unknown is not None:
        out["unknown_px"] = int(np.count_nonzero(unknown))
    return out


def sensor_residual(cal, shape, law):
    """(residual_ab (P, 2), summary) of a sensor file's residual retarder (the six rest
    steps it was calibrated with: phase, or grey with ``--residual-steps``) on an image of
    ``shape``, or (None, None): what ``invert`` and ``track`` model when no rest frames
    are given.

    Examples
    --------
    >>> sensor_residual(None, (4, 4), None)
    (None, None)
    """
    ab = cal.residual_ab(shape) if cal is not None else None
    if ab is None:
        return None, None
    fringes = residual_fringes(ab, law)
    summary = {
        "frames": [],
        "residual_from": "the sensor file",
        "residual_mean_fringe": float(fringes.mean()),
        "residual_max_fringe": float(fringes.max()),
    }
    return ab, summary


def bright_rest_warning(light: np.ndarray | None) -> list[str]:
    """The one warning (a list of zero or one line) for a dark-field rest light (P, C)
    whose mean is above BRIGHT_REST of full scale: six phase steps given as ``--reference``
    (they average about half), or a rest frame not taken in the dark field.

    Examples
    --------
    >>> import numpy as np
    >>> bright_rest_warning(np.full((4, 1), 0.02)), len(bright_rest_warning(np.full((4, 1), 0.5)))
    ([], 1)
    """
    if light is None or float(np.mean(light)) <= BRIGHT_REST:
        return []
    return [
        f"--reference: the rest light averages {float(np.mean(light)):.2f} of full scale, "
        "which a dark field at rest does not; phase steps of the rest go in "
        "--residual-steps (mono) or with --method phase, and a rest frame must be taken "
        "in the measurement's polariscope"
    ]


def unknown_warning(unknown: np.ndarray | None, phase: bool, where: str) -> list[str]:
    """The one warning (a list of zero or one line) for pixels whose rest light, or
    (``phase``) residual retarder, is not known: left out of every fit of ``where``
    ("the fit", "every frame").

    Examples
    --------
    >>> import numpy as np
    >>> unknown_warning(np.array([True, False, True]), False, "the fit")[0][:45]
    '2 px saturated in the rest frames (or within '
    """
    if unknown is None or not unknown.any():
        return []
    what = (
        "saturated or without modulation in the rest steps, or whose residual reaches 0.45 "
        "fringe (or within two map cells of one), were left out of "
        f"{where}: their residual retarder is not known"
        if phase
        else "saturated in the rest frames (or within two map cells of one) were left out "
        f"of {where}: their rest light is not known"
    )
    return [f"{int(np.count_nonzero(unknown))} px {what}"]


def take_rest(rest, method: str, measured, usable, shape, optics, cal=None, channel=None):
    """One measurement with the sensor's rest taken into account (``invert --reference``,
    ``--residual-steps``).

    Parameters
    ----------
    rest : RestFrames or None
        The frames of the sensor at rest (None: the measurement as it is, with the sensor
        file's residual retarder when ``cal`` holds one). Dark-field frames (rgb,
        mono), whose light is taken off; or six-step frames (phase, and any method's
        ``--residual-steps``: ``rest.option``), read as the sheet's residual retarder
        (through ``cal``'s response).
    method : {"rgb", "mono", "phase"}
    measured : (P, C) array
        The measurement's linear intensities, P = rows * cols.
    usable : (P,) bool array
    shape : (rows, cols)
        The measurement's size; rest frames of another are refused in one line.
    optics : OpticsSetup
        The sensor's optics (its law and camera).
    cal : CalibratedSensor, optional
        Applied to the rest frames as to the measurement.
    channel : int, optional
        For mono: the colour channel the measurement was read in.

    Returns
    -------
    measured : (P, C) array
        Less the rest light (dark-field rest frames); else unchanged.
    usable : (P,) bool array
        Less the pixels where the rest is not known.
    residual_ab : (P, 2) array or None
        Six-step rest frames: the residual retarder (:meth:`RestFrames.retarder`) for the
        model's ``residual_ab``; None otherwise.
    summary : dict or None
        :func:`rest_summary`.
    warnings : list of str
        :func:`unknown_warning`'s.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.config.inputs import optics_setup
    >>> import fringekit
    >>> optics = optics_setup(fringekit.Config.builtin("small").data)
    >>> rest = RestFrames((np.full((4, 4), 0.1),), ("rest.png",))
    >>> m, ok, ab, summary, warn = take_rest(
    ...     rest, "mono", np.full((16, 1), 0.3), np.ones(16, bool), (4, 4), optics)
    >>> round(float(m[0, 0]), 6), ab, summary["light_max"], warn
    (0.2, None, [0.1], [])
    """
    if rest is None:
        return (measured, usable, *sensor_residual(cal, shape, optics.law), [])
    if rest.are_steps(method):
        ab, unknown = rest.retarder(shape, optics.law, cal)
        summary = rest_summary(rest, unknown=unknown, fringes=residual_fringes(ab, optics.law))
        return measured, usable & ~unknown, ab, summary, unknown_warning(unknown, True, "the fit")
    light, unknown = rest.light(shape, method, optics.camera.sensitivities, cal, channel)
    summary = rest_summary(rest, light=light, unknown=unknown)
    warnings = unknown_warning(unknown, False, "the fit") + bright_rest_warning(light)
    return measured - light, usable & ~unknown, None, summary, warnings
