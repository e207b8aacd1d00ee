"""``fringekit track``: :func:`~fringekit.tracking.stream.track`, then its folder.

The folder holds the files of :meth:`~fringekit.tracking.stream.Track.write`, and
``track.mp4`` (each frame with its overlay) when asked: the frames are kept on disk
while the stream runs (:class:`FrameSpool`: one save a frame in the solve loop) and
painted when it ends, so memory does not grow with the stream and the solver does not
paint. It is written beside ``--out``
and swapped in when the run ends; a stream stopped by a bad frame or Ctrl-C still writes
the frames solved before it (``summary.json`` says where and why it stopped). The tables
are written before the video is painted, and a video that fails (a full disk while the
frames are saved, Ctrl-C or an error while they are painted) is given up, not the run.
"""

from __future__ import annotations

import os
import shutil
import time
from collections import deque
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from fringekit.library.calibrated import as_calibrated
from fringekit.output.folders import claim_output
from fringekit.tracking.figure import OverlayPainter
from fringekit.tracking.stream import track
from fringekit.tracking.tracker import TRACK_STRIDE
from fringekit.tracking.write import write_video

__all__ = ["FrameSpool", "LiveView", "marks", "rolling_loads", "run_track"]


class LiveView:
    """A frame callback that shows the newest frame with its overlay and a rolling plot
    of every contact's loads, redrawn at most every ``interval_s`` (display updates are
    skipped, never data frames: every solved frame enters the rolling plot).

    Parameters
    ----------
    show : callable
        Takes an RGB uint8 image (rows, cols, 3) and the rolling loads
        (:func:`rolling_loads`), and displays them.
    painter_factory : callable
        (rows, cols) -> an object with ``paint(image, params, ids)``.
    interval_s : float
        The least time between two displayed frames (s).
    clock : callable
        Seconds (a test's fake clock).
    history : int
        Frames the rolling plot holds (the oldest are dropped: bounded memory).

    Examples
    --------
    Ten frames in 0.09 s against a 0.2 s interval: one is drawn, all ten are kept.

    >>> import numpy as np
    >>> from fringekit.tracking.frame import TrackedFrame
    >>> shown, t = [], iter(np.arange(10) * 0.01)
    >>> class Painter:
    ...     def paint(self, image, params, ids): return image
    >>> view = LiveView(lambda rgb, loads: shown.append(rgb), lambda shape: Painter(), 0.2,
    ...                 clock=lambda: next(t))
    >>> f = TrackedFrame(0, 0.0, np.zeros(0, int), *[np.zeros((0, 5))] * 2, *[np.zeros(0)] * 2)
    >>> for _ in range(10):
    ...     view(f, np.zeros((4, 4, 3), np.uint8))
    >>> len(shown), view.skipped, len(view.history)
    (1, 9, 10)
    """

    def __init__(
        self, show, painter_factory, interval_s: float = 0.2, clock=time.monotonic, history=500
    ):
        self.show, self.factory, self.interval, self.clock = (
            show,
            painter_factory,
            interval_s,
            clock,
        )
        self.painter = None
        self.last = -float("inf")
        self.skipped = 0
        self.history: deque = deque(maxlen=int(history))

    def __call__(self, frame, image) -> None:
        if frame is not None:
            self.history.append((frame.time_s, tuple(int(i) for i in frame.ids), frame.params))
        now = self.clock()
        if now - self.last < self.interval:
            self.skipped += 1
            return
        if self.painter is None:
            self.painter = self.factory(image.shape[:2])
        self.show(self.painter.paint(image, *marks(frame)), rolling_loads(self.history))
        self.last = now


def rolling_loads(history) -> dict:
    """Each contact's loads through ``history``, a sequence of (time_s, ids (n,), params
    (n, 5)) as :class:`LiveView` keeps them: {id: (time (k,) s, Fz (k,) N, tangential
    magnitude (k,) N)}, in the order of the frames.

    Examples
    --------
    >>> import numpy as np
    >>> h = [(0.0, (1,), np.array([[0, 0, 2.0, 0.3, 0.4]])),
    ...      (0.1, (1, 2), np.array([[0, 0, 2.5, 0.6, 0.8], [3, 3, 1.0, 0, 0]]))]
    >>> loads = rolling_loads(h)
    >>> sorted(loads), loads[1][1].tolist(), loads[1][2].tolist(), loads[2][0].tolist()
    ([1, 2], [2.0, 2.5], [0.5, 1.0], [0.1])
    """
    rows: dict = {}
    for t, ids, params in history:  # a few hundred frames of a handful of contacts
        p = np.reshape(params, (-1, 5))
        for i, (fz, fx, fy) in zip(ids, p[:, 2:], strict=True):
            rows.setdefault(i, []).append((t, fz, float(np.hypot(fx, fy))))
    return {i: tuple(np.array(col) for col in zip(*r, strict=True)) for i, r in rows.items()}


def marks(frame) -> tuple[np.ndarray, tuple]:
    """The overlay's (params (n, 5), ids) of a tracked frame; none for a frame left out
    (None: the library could not explain it).

    Examples
    --------
    >>> params, ids = marks(None)
    >>> params.shape, ids
    ((0, 5), ())
    """
    if frame is None:
        return np.zeros((0, 5)), ()
    return frame.params, tuple(frame.ids)


def _window():
    """A matplotlib window: the newest frame with its overlay, and the rolling loads
    (Fz solid, tangential dashed, one colour per contact id) (the ``--show`` view)."""
    import matplotlib.pyplot as plt  # lazy: a window only when --show asks for one

    fig, (ax, ax_load) = plt.subplots(1, 2, figsize=(10, 4.5))
    ax.set_axis_off()
    holder: dict = {}

    def show(rgb, loads) -> None:
        if "im" not in holder:
            holder["im"] = ax.imshow(rgb)
        else:
            holder["im"].set_data(rgb)
        ax_load.clear()
        for i, (t, fz, ft) in sorted(loads.items()):  # a handful of contacts
            colour = f"C{i % 10}"
            ax_load.plot(t, fz, color=colour, label=f"{i}")
            ax_load.plot(t, ft, color=colour, linestyle="--")
        ax_load.set_xlabel("time (s)")
        ax_load.set_ylabel("Fz (solid), tangential (dashed) (N)")
        if loads:
            ax_load.legend(title="id", loc="upper left", fontsize="small")
        plt.pause(0.001)

    return show


def run_track(
    source,
    library,
    out,
    *,
    pixel_mm: float | None = None,
    origin_px=None,
    method=None,
    sensor=None,
    stride: int = TRACK_STRIDE,
    fps=None,
    max_frames=None,
    video: bool = False,
    show: bool = False,
    progress: bool = True,
) -> dict:
    """Track ``source``; write ``out``; return the summary."""
    cal = as_calibrated(sensor)
    if cal is not None:  # the overlay's pixels are the calibration's
        pixel_mm, origin_px = cal.grid_options(pixel_mm, origin_px)
    inputs = [
        source if os.path.exists(str(source)) else None,
        getattr(library, "folder", library),
        sensor,
    ]
    view = (
        LiveView(_window(), lambda shape: OverlayPainter(shape, _to_rc(shape, pixel_mm, origin_px)))
        if show
        else None
    )
    with claim_output(out, command="track", inputs=inputs) as work:
        spool = FrameSpool(work / ".frames") if video else None

        def on_frame(f, img):
            for cb in (spool, view):
                if cb is not None:
                    cb(f, img)

        t = track(
            source,
            library,
            pixel_mm=pixel_mm,
            origin_px=origin_px,
            method=method,
            sensor=sensor,
            stride=stride,
            fps=fps,
            max_frames=max_frames,
            progress=progress,
            on_frame=None if spool is None and view is None else on_frame,
        )
        t.write(work)  # the tables first: whatever befalls the video, they are kept
        if spool is not None:
            fps = t.summary["source"]["fps"] or 25.0
            t.summary["video"] = _paint_video(work, spool, pixel_mm, origin_px, fps, progress)
            if t.summary["video"]["error"] is not None:
                t.summary["warnings"].append(
                    f"track.mp4 was not written ({t.summary['video']['error']}); the tables "
                    "are complete"
                )
            t.write_summary(work)
    return t.summary


class FrameSpool:
    """The frames of a stream kept on disk as they come, for the overlay video made when
    the run ends: one ``.npy`` file a frame (its own dtype and channels) in ``folder``,
    so that memory stays bounded however long a camera runs (disk takes rows x cols x
    channels x bytes a frame: 0.4 MB at 256 x 256 16-bit colour). Called as an
    ``on_frame`` callback; iterating gives (overlay marks, image) in frame order.

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> spool = FrameSpool(Path(tempfile.mkdtemp()) / "spool")
    >>> spool(None, np.full((2, 3), 7, np.uint16))
    >>> [(len(params), image.dtype.name, int(image[0, 0])) for (params, ids), image in spool]
    [(0, 'uint16', 7)]
    >>> spool.remove(); spool.folder.exists()
    False
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self.folder.mkdir()
        self.marks: list = []
        self.error: str | None = None

    def __call__(self, frame, image) -> None:
        if self.error is not None:
            return
        try:
            np.save(self.folder / f"{len(self.marks):07d}.npy", np.asarray(image))
        except OSError as exc:  # a full disk: give the video up, free its space, go on
            self.error = f"its frames could not be saved at frame {len(self.marks)}: {exc}"
            self.marks.clear()
            self.remove()
            return
        self.marks.append(marks(frame))

    def __len__(self) -> int:
        return len(self.marks)

    def __iter__(self):
        for k, m in enumerate(self.marks):  # one frame in memory at a time
            yield m, np.load(self.folder / f"{k:07d}.npy")

    def remove(self) -> None:
        """Delete the spool's folder, which fringekit made inside its own work folder and
        which holds only its frames (with, after a Ctrl-C during a save, one not yet
        counted)."""
        shutil.rmtree(self.folder, ignore_errors=True)


def _to_rc(shape, pixel_mm: float, origin_px):
    """(x_mm, y_mm) -> (row, col) of the frames' pixel grid (x right, y up)."""
    rows, cols = shape
    r0, c0 = origin_px if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    return lambda x, y: (r0 - y / pixel_mm, c0 + x / pixel_mm)


def _paint_video(work: Path, spool: FrameSpool, pixel_mm, origin_px, fps: float, progress):
    """Paint the spooled frames into ``work/track.mp4`` at ``fps`` (with a progress bar) and remove
    the spool; return ``summary["video"]``: the file (None when not written), the frames
    painted and the error (None, or why the video was given up: the spool's own failure,
    Ctrl-C or an error while painting, after which a partial file is removed)."""
    path, painted = work / "track.mp4", [0]
    error = spool.error
    try:
        if error is None and len(spool):
            shape = next(iter(spool))[1].shape[:2]
            painter = OverlayPainter(shape, _to_rc(shape, pixel_mm, origin_px))
            bar = tqdm(total=len(spool), unit="frame", desc="track.mp4", disable=not progress)

            def frames():
                for m, img in spool:
                    yield painter.paint(img, *m)
                    painted[0] += 1
                    bar.update(1)

            try:
                write_video(path, frames(), fps)
            finally:
                bar.close()
    except KeyboardInterrupt:
        error = f"interrupted (Ctrl-C) after {painted[0]} of {len(spool)} frame(s)"
    except Exception as exc:  # the tables are written: a failed video must not lose them
        error = f"{type(exc).__name__} after {painted[0]} of {len(spool)} frame(s): {exc}"
    finally:
        spool.remove()
    if error is not None:
        path.unlink(missing_ok=True)
    written = error is None and path.is_file()
    return {"file": path.name if written else None, "frames": painted[0], "error": error}
