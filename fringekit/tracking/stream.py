"""``fringekit track`` as an API: :func:`track` reads every contact's load off a stream of
frames, :class:`Track` holds them as a table and writes them.

:func:`track` computes and writes nothing; :meth:`Track.write` gives the folder of
``fringekit track``:

- ``loads.csv``: one row per contact per frame, exactly the columns
  :data:`TRACK_COLUMNS`: the frame, its time (s), the contact's id (kept from its touch to
  its release), position (mm, the frame of ``predict`` and ``invert``), load vector (N),
  their 1-sigma, ``residual_rms`` (as ``invert``'s) and ``reliable``;
- ``summary.json``: the source, library, method, frames read / solved / dropped, the
  frames per second achieved, the time per stage, every event (start, touch, release,
  recover) and warning, and why the stream stopped when it did not end;
- ``loads.png``: each contact's normal and tangential load against time, with its 1-sigma
  band.
"""

from __future__ import annotations

import csv
import json
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from fringekit.analysis import normalise
from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.errors import ConfigError, SourceError
from fringekit.inversion.read import censored_channels
from fringekit.inversion.rest import (
    PHASE_STEPS,
    bright_rest_warning,
    check_rest_method,
    frame_linear,
    grey,
    residual_fringes,
    rest_frames,
    rest_summary,
    sensor_residual,
    steps_linear,
    unknown_warning,
)
from fringekit.inversion.verdict import InvertError
from fringekit.library.calibrated import CalibratedSensor, as_calibrated
from fringekit.library.store import Library, check_sensor, load_library
from fringekit.output.folders import atomic_write
from fringekit.tracking.channel import MonoChannel
from fringekit.tracking.figure import loads_figure
from fringekit.tracking.frame import TrackedFrame
from fringekit.tracking.source import FrameSource, RawFrame, open_source
from fringekit.tracking.synthetic import blank_model
from fringekit.tracking.tracker import TRACK_STRIDE, Tracker

__all__ = ["TRACK_COLUMNS", "Track", "track"]

TRACK_COLUMNS = (
    "frame",
    "time_s",
    "id",
    "x_mm",
    "y_mm",
    "Fx_N",
    "Fy_N",
    "Fz_N",
    "sx_mm",
    "sy_mm",
    "sFx_N",
    "sFy_N",
    "sFz_N",
    "residual_rms",
    "reliable",
)
#: The columns of TRACK_COLUMNS that come from the parameters (x, y, Fz, Fx, Fy order).
_PARAM_COLUMNS = {"x_mm": 0, "y_mm": 1, "Fz_N": 2, "Fx_N": 3, "Fy_N": 4}


@dataclass(frozen=True)
class Track:
    """Every contact's position and load vector through a stream of frames.

    Attributes
    ----------
    frames : tuple of TrackedFrame
        One per frame solved, in stream order.
    summary : dict
        What ``summary.json`` holds.
    sensor : CalibratedSensor or None
        The calibrated sensor the frames were read with: ``frames`` are in the image's
        axes, :meth:`table` in the sheet's.

    Examples
    --------
    See :func:`track`; the table's columns are those of ``loads.csv``:

    >>> import fringekit
    >>> fringekit.tracking.TRACK_COLUMNS[:4]
    ('frame', 'time_s', 'id', 'x_mm')
    """

    frames: tuple
    summary: dict = field(repr=False)
    sensor: CalibratedSensor | None = field(default=None, repr=False)

    def table(self) -> dict[str, np.ndarray]:
        """The loads as columns named :data:`TRACK_COLUMNS`, one row per contact per frame
        (mm, N, s)."""
        rows = [f for f in self.frames for _ in f.ids]
        n = len(rows)
        if not n:
            return {k: np.zeros(0) for k in TRACK_COLUMNS}
        p = np.concatenate([f.params for f in self.frames if len(f.ids)])
        s = np.concatenate([f.sd for f in self.frames if len(f.ids)])
        if self.sensor is not None:
            p, s = self.sensor.to_sheet(p), self.sensor.to_sheet(s, sd=True)
        out = {
            "frame": np.array([f.index for f in rows], int),
            "time_s": np.array([f.time_s for f in rows], float),
            "id": np.concatenate([f.ids for f in self.frames]).astype(int),
        }
        for k, j in _PARAM_COLUMNS.items():
            out[k] = p[:, j]
            out["s" + k] = s[:, j]
        out["residual_rms"] = np.concatenate([f.residual_rms for f in self.frames])
        out["reliable"] = np.concatenate([f.reliable for f in self.frames]).astype(bool)
        return {k: out[k] for k in TRACK_COLUMNS}

    def write(self, folder: str | os.PathLike) -> Path:
        """Write ``loads.csv``, ``summary.json`` and ``loads.png`` into ``folder``
        (created if missing; files of those names are replaced); return it."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        table = self.table()
        with open(out / "loads.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(TRACK_COLUMNS)
            for row in zip(*(table[k] for k in TRACK_COLUMNS), strict=True):
                w.writerow([_cell(x) for x in row])
        loads_figure(out / "loads.png", table)
        return self.write_summary(out)

    def write_summary(self, folder: str | os.PathLike) -> Path:
        """(Re)write ``summary.json`` in ``folder`` (whole or not at all); return the
        folder."""
        atomic_write(Path(folder) / "summary.json", json.dumps(self.summary, indent=2))
        return Path(folder)


def _cell(x) -> str:
    if isinstance(x, (bool, np.bool_)):
        return "true" if x else "false"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    return f"{float(x):.6g}"


def _method(method: str | None, raw: np.ndarray) -> str:
    """``--method``: rgb, mono or phase (given, never the default); default rgb for colour
    frames, mono for grey ones."""
    if method not in (None, "rgb", "mono", "phase"):
        raise ConfigError(f"--method {method!r} is not allowed; give rgb, mono or phase")
    if method is not None:
        return method
    return "mono" if grey(raw).ndim == 2 else "rgb"


def _sensor(lib: Library, cal: CalibratedSensor | None) -> tuple[dict, str]:
    """The stream's sensor config: the sensor file's (checked against the library's),
    else the library's own."""
    if cal is not None:
        check_sensor(lib, cal.config, "--sensor")
        return cal.config, "the sensor file"
    return load_config(lib.folder / "config.toml"), str(lib.folder / "config.toml")


def _times(frames: list[TrackedFrame]) -> dict:
    """Per-stage seconds summed over the frames, and the warm frames' median and 95th
    percentile."""
    out: dict = {}
    for f in frames:
        for k, v in f.times_s.items():
            out[k] = out.get(k, 0.0) + v
    warm = [f.times_s["frame_s"] for f in frames if not f.events and len(f.ids)]
    if warm:
        out["warm_frame_median_s"] = float(np.median(warm))
        out["warm_frame_p95_s"] = float(np.percentile(warm, 95))
    return out


def track(
    source: str | os.PathLike | FrameSource,
    library: Library | str | os.PathLike,
    *,
    pixel_mm: float | None = None,
    origin_px: tuple[float, float] | None = None,
    method: str | None = None,
    sensor: str | os.PathLike | CalibratedSensor | None = None,
    reference=None,
    residual_steps=None,
    stride: int = TRACK_STRIDE,
    fps: float | None = None,
    max_frames: int | None = None,
    progress: bool = False,
    on_frame=None,
) -> Track:
    """Every contact's position and load vector through a stream of frames.

    The first frame with fringes is solved quickly on every ``stride``-th pixel
    (:func:`~fringekit.inversion.quick.quick_start`), or as ``invert`` solves an image when
    that does not explain it to the camera's noise; every later frame starts from the one
    before (:class:`~fringekit.tracking.tracker.Tracker`).

    Parameters
    ----------
    source : path, str or FrameSource
        A folder of images (name order), a video file (.mp4, .avi, .mkv, .mov) or
        ``camera:N`` (:func:`~fringekit.tracking.source.open_source`).
    library : Library or path
        A response library of the sensor (``fringekit library build``).
    pixel_mm : float
        The pixel pitch on the sheet (mm); required unless ``sensor`` is calibrated.
    origin_px : (row, col), optional
        The pixel of the sensor origin; default the image centre (or the calibrated
        sensor's).
    method : {"rgb", "mono", "phase"}, optional
        Default rgb for colour frames, mono for grey ones. ``phase``: every six frames in a
        row are one load state's phase steps (in
        :data:`~fringekit.analysis.SIX_STEP_ORDER`), solved as one; not from a camera
        (a dropped frame would mix two states), nor with ``reference``.
    sensor : path or CalibratedSensor, optional
        A sensor file (``.json`` of ``fringekit sensor calibrate`` or ``sensor init``),
        applied as ``invert`` applies it; default the library's own config.
    reference : path or sequence of paths, optional
        Frames of the sensor at rest in the stream's light (``--reference``): their light,
        averaged and smoothed, is taken off every frame
        (:class:`~fringekit.inversion.rest.RestFrames`; with a calibrated ``sensor``, in
        place of its rest map). For ``phase``, the six steps of the rest (or of several,
        six each): the sheet's residual retarder, read from them, is in the model.
    residual_steps : sequence of paths, optional
        For rgb and mono (``--residual-steps``): the six phase steps of the sensor at rest
        (or 6n), taken once with the plates stepped; the sheet's residual retarder, read
        from them, is in the model (:func:`fringekit.invert`'s ``residual_steps``). Not
        with ``reference``.
    stride : int
        Every ``stride``-th pixel in both directions is fitted per frame (default 4).
    fps : float, optional
        The frame rate of a folder of frames (their ``time_s``), or one that replaces a
        video's.
    max_frames : int, optional
        Stop after this many frames (phase: load states, of six frames each).
    progress : bool
        A progress bar (frames of a file source; the rate of a camera's).
    on_frame : callable, optional
        Called with (TrackedFrame, decoded image) after every frame (a live view); the
        TrackedFrame is None for a frame the library cannot explain (left out).

    Returns
    -------
    Track
        Nothing is written. A stream that stops at a bad frame (another size, an
        unreadable file) or at Ctrl-C returns the frames solved before it, with
        ``summary["stopped"]`` saying why.

    Raises
    ------
    ConfigError, LibraryError, SourceError
        A bad option, library or source, before the first frame.

    Examples
    --------
    Two frames of a library-synthesised contact, 4 N then 4.4 N, tracked back (the
    library of :func:`~fringekit.library.build.build_library`'s example, whose solves the
    cache holds once either has run):

    >>> import tempfile, numpy as np, fringekit
    >>> from fringekit.tracking import library_frames
    >>> lib = fringekit.build_library("small", tempfile.mkdtemp() + "/lib",
    ...                               loads=[4, 8, 12], ratios=[0, 0.4], progress=False)
    >>> folder = tempfile.mkdtemp()
    >>> truth = [[(0.5, -0.3, 4.0, 0.0, 0.0)], [(0.5, -0.3, 4.4, 0.0, 0.0)]]
    >>> library_frames(lib, truth, folder, pixels=64, pixel_mm=0.2)
    2
    >>> t = fringekit.tracking.track(folder, lib, pixel_mm=0.2)
    >>> np.round(t.table()["Fz_N"], 2).tolist()
    [4.0, 4.4]
    """
    lib = library if isinstance(library, Library) else load_library(library)
    cal = as_calibrated(sensor)
    if cal is not None:
        cal.check(lib, method=method)
        pixel_mm, origin_px = cal.grid_options(pixel_mm, origin_px)
    if pixel_mm is None:
        raise ConfigError(
            "--pixel-mm is required: the pixel pitch on the sheet (mm), or --sensor SENSOR.json"
        )
    if not (np.isfinite(pixel_mm) and pixel_mm > 0):
        raise ConfigError(
            f"--pixel-mm {pixel_mm} is not allowed; give the pitch on the sheet (mm, > 0)"
        )
    if int(stride) != stride or not 1 <= stride <= 16:
        raise ConfigError(f"--stride {stride} is not allowed; give a whole number 1-16")
    cfg, where = _sensor(lib, cal)
    optics = optics_setup(cfg)
    rest = rest_frames(reference, residual_steps)
    check_rest_method(rest, method, cal)
    if method == "phase" and rest is not None:
        rest.check_steps()  # before the first frame is read
    live = (
        source.live
        if isinstance(source, FrameSource)
        else str(source).lower().startswith("camera:")
    )
    if method == "phase" and live:
        raise ConfigError(
            f"--method phase with SOURCE {getattr(source, 'spec', source)}: a camera drops "
            "frames, which would mix the six steps of two load states; record the steps to "
            "a folder or a video"
        )
    src = source if isinstance(source, FrameSource) else open_source(str(source), fps=fps)
    run = _Run(lib, cfg, optics, src, pixel_mm, origin_px, method, int(stride), on_frame, cal, rest)
    with src:
        run.loop(max_frames, progress)
    summary = run.summary(where)
    if cal is not None:
        summary["calibrated_sensor"] = cal.summary(None if cal is sensor else str(sensor))
    return Track(tuple(run.frames), summary, cal)


class _Run:
    """One pass over a source: the tracker made at the first frame, the frames solved,
    the notes, and why it stopped."""

    def __init__(
        self, lib, cfg, optics, src, pixel_mm, origin_px, method, stride, on_frame, cal, rest
    ):
        self.lib, self.cfg, self.optics, self.src, self.cal = lib, cfg, optics, src, cal
        self.rest = rest  # its light is made at the first frame, when the method is known
        self.pixel_mm, self.origin_px, self.method = pixel_mm, origin_px, method
        self.stride, self.on_frame = stride, on_frame
        self.tracker: Tracker | None = None
        self.frames: list[TrackedFrame] = []
        self.read = 0
        self.notes: list[str] = []
        self.stopped: dict | None = None
        self.refused: list[dict] = []
        self.t_loop = 0.0
        self.rest_light: np.ndarray | None = None
        self.rest_unknown: np.ndarray | None = None  # (P,) pixels it is not known at
        self.rest_ab: np.ndarray | None = None  # (P, 2) the rest steps' residual retarder
        self.rest_info: dict | None = None  # the summary of a sensor file's residual
        self.rest_channel: int | None = None  # the colour channel it was read in
        self.channel = MonoChannel()  # the channel a mono stream's colour frames are read in
        self.partial = 0  # phase steps at the end that made no whole state

    def _states(self):
        """Every load state of the source: a frame, or (phase) six frames in a row, as
        one RawFrame (the state's number, the first step's time and name, the last
        step's image) and its images; counts the frames read."""
        steps: list[RawFrame] = []
        for raw in self.src:
            self.read += 1
            if self.method != "phase":
                yield raw, (raw,)
                continue
            steps.append(raw)
            self.partial = len(steps)
            if len(steps) == PHASE_STEPS:
                k = (self.read - 1) // PHASE_STEPS
                state, steps, self.partial = tuple(steps), [], 0
                yield RawFrame(k, state[0].time_s, raw.image, state[0].name), state

    def loop(self, max_frames, progress: bool) -> None:
        bar = None
        t0 = time.perf_counter()
        try:
            for raw, steps in self._states():
                if self.tracker is None:  # a bad option is refused before the bar starts
                    self._setup(raw.image, raw.name)
                if bar is None:
                    bar = tqdm(
                        total=self._total(),
                        unit="state" if len(steps) > 1 else "frame",
                        desc="track",
                        disable=not progress,
                    )
                solved = None
                try:
                    solved = self._solve(raw, steps)
                    self.frames.append(solved)
                except InvertError as exc:  # this frame only: the next one starts afresh
                    self.refused.append({"frame": raw.index, "reason": str(exc)})
                    self.tracker.reset()
                bar.update(1)
                if self.on_frame is not None:  # a refused frame: its image, no contacts
                    self.on_frame(solved, raw.image)
                if max_frames is not None and len(self.frames) + len(self.refused) >= max_frames:
                    break
        except SourceError as exc:
            self.stopped = {"after_frames": len(self.frames), "reason": str(exc)}
        except KeyboardInterrupt:
            self.stopped = {"after_frames": len(self.frames), "reason": "interrupted (Ctrl-C)"}
        finally:
            if bar is not None:
                bar.close()
            self.t_loop = time.perf_counter() - t0

    def _setup(self, img: np.ndarray, name: str) -> None:
        """The tracker of frames like ``img`` (the first): the method, the sensor's model
        and the rest light; a bad option is refused in one line."""
        self.method = _method(self.method, img)
        lib, optics, shape = self.lib, self.optics, img.shape[:2]
        if self.cal is not None:
            lib, optics = self.cal.model_inputs(lib, optics, shape, self.method)
        check_rest_method(self.rest, self.method, self.cal)
        if self.rest is not None and self.rest.are_steps(self.method):
            self.rest_ab, self.rest_unknown = self.rest.retarder(shape, optics.law, self.cal)
        elif self.rest is None:  # a sensor file's residual retarder, if it has one
            self.rest_ab, self.rest_info = sensor_residual(self.cal, shape, optics.law)
            self.rest_unknown = np.zeros(shape[0] * shape[1], bool)
        elif self.rest is not None:
            if self.method == "mono" and grey(img).ndim == 3:
                self.channel(normalise(grey(img), source=name).data, name)
            self._rest_in(self.channel.index, shape)
        blank = blank_model(
            lib, self.cfg, shape, self.pixel_mm, self.method, self.origin_px, optics
        )
        self.tracker = Tracker(replace(blank, residual_ab=self.rest_ab), self.stride)

    def _rest_in(self, channel: int | None, shape) -> None:
        """The rest light, read in the stream's colour channel (again when a frame with
        a light pattern chose another than a featureless first frame's)."""
        if self.rest_light is None or channel != self.rest_channel:
            cam = self.optics.camera.sensitivities
            self.rest_light, self.rest_unknown = self.rest.light(
                shape, self.method, cam, self.cal, channel
            )
            self.rest_channel = channel

    def _residual_fringes(self) -> np.ndarray | None:
        """(P,) the rest steps' residual retardation (fringes, the double pass), or None."""
        if self.rest_ab is None:
            return None
        return residual_fringes(self.rest_ab, self.tracker.blank.law)

    def _total(self) -> int | None:
        """The progress bar's length: the source's frames, or its whole phase states."""
        n = self.src.n_frames
        return n // PHASE_STEPS if n is not None and self.method == "phase" else n

    def _solve(self, raw, steps) -> TrackedFrame:
        if self.method == "phase":
            measured, usable, nodata, note = steps_linear(
                [s.image for s in steps], [s.name for s in steps], self.cal
            )
            censored = None  # (a grey model never goes below zero)
        else:
            camera = self.optics.camera.sensitivities
            measured, usable, nodata, note = frame_linear(
                raw.image, self.method, camera, raw.name, self.cal, self.channel
            )
            image = np.asarray(raw.image)
            censored = censored_channels(image.reshape(*image.shape[:2], -1), self.method)
            if self.channel.switched:  # the noise was measured in another channel
                self.tracker.noise, self.channel.switched = None, False
        if self.rest_ab is not None:  # phase: the residual is in the model
            usable = usable & ~self.rest_unknown
        elif self.rest is not None:
            self._rest_in(self.channel.index, raw.image.shape[:2])
            measured, usable = measured - self.rest_light, usable & ~self.rest_unknown
        if note and note not in self.notes:
            self.notes.append(note)
        return self.tracker.step(measured, usable, nodata, raw.index, raw.time_s, censored)

    def summary(self, where: str) -> dict:
        solved = len(self.frames)
        events = [{"frame": f.index, "events": list(f.events)} for f in self.frames if f.events]
        unreliable = int(sum(int(np.sum(~f.reliable)) for f in self.frames))
        warnings = [self.channel.note, *self.notes] if self.channel.note else list(self.notes)
        where = "every state" if self.method == "phase" else "every frame"
        warnings += unknown_warning(self.rest_unknown, self.rest_ab is not None, where)
        warnings += bright_rest_warning(self.rest_light)
        if self.refused:
            warnings.append(
                f"{len(self.refused)} frame(s) the library cannot explain were left out "
                f"(the first, frame {self.refused[0]['frame']}: {self.refused[0]['reason']})"
            )
        if self.src.dropped:
            warnings.append(
                f"{int(self.src.dropped)} camera frame(s) were dropped while earlier ones were "
                "solved (the newest frame is always the one solved): see frames_dropped"
            )
        if self.partial:
            warnings.append(
                f"the last {self.partial} frame(s) of the source made no whole six-step "
                "state and were not solved"
            )
        if unreliable:
            warnings.append(
                f"{unreliable} contact-frame(s) are flagged not reliable (their residual "
                "near the contact is above invert's warning level): see loads.csv"
            )
        return {
            "source": {"kind": self.src.kind, "spec": self.src.spec, "fps": self.src.fps},
            "library": str(self.lib.folder),
            "sensor_config": where,
            "method": self.method,
            "pixel_mm": self.pixel_mm,
            "origin_px": list(self.origin_px) if self.origin_px is not None else None,
            "stride": self.stride,
            "frames_per_state": PHASE_STEPS if self.method == "phase" else 1,
            "reference": rest_summary(
                self.rest, self.rest_light, self.rest_unknown, self._residual_fringes()
            )
            or self.rest_info,
            "frames_read": self.read,
            "frames_solved": solved,
            "frames_dropped": int(self.src.dropped),
            "fps_achieved": solved / self.t_loop if self.t_loop > 0 else None,
            "contacts": sorted({int(i) for f in self.frames for i in f.ids}),
            "noise_sd": self.tracker.noise if self.tracker is not None else None,
            "events": events,
            "frames_refused": self.refused,
            "warnings": warnings,
            "stopped": self.stopped,
            "times_s": {**_times(self.frames), "total_s": self.t_loop},
        }
