"""``fringekit track``: :func:`~fringekit.tracking.stream.track`, then its folder.

The folder holds the files of :meth:`~fringekit.tracking.stream.Track.write`, and
``track.mp4`` (each frame with its overlay) when asked: the frames are kept on disk
while the stream runs (:class:`FrameSpool`: one save a frame in the solve loop) and
painted when it ends, so memory does not grow with the stream and the solver does not
paint (``--show`` draws in a process of its own:
:class:`~fringekit.tracking.display.LiveDisplay`). The folder is written beside
``--out`` and swapped in when the run ends; a stream stopped by a bad frame or Ctrl-C still writes
the frames solved before it (``summary.json`` says where and why it stopped). The tables
are written before the video is painted, and a video that fails (a full disk while the
frames are saved, Ctrl-C or an error while they are painted) is given up, not the run.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from fringekit.library.calibrated import as_calibrated
from fringekit.output.folders import as_paths, claim_output
from fringekit.tracking.display import LiveDisplay, marks
from fringekit.tracking.figure import OverlayPainter, sheet_to_pixel
from fringekit.tracking.stream import track
from fringekit.tracking.tracker import TRACK_STRIDE
from fringekit.tracking.write import write_video

__all__ = ["FrameSpool", "run_track"]


def run_track(
    source,
    library,
    out,
    *,
    pixel_mm: float | None = None,
    origin_px=None,
    method=None,
    sensor=None,
    reference=None,
    residual_steps=None,
    stride: int = TRACK_STRIDE,
    fps=None,
    max_frames=None,
    video: bool = False,
    show: bool = False,
    progress: bool = True,
) -> dict:
    """Track ``source``; write ``out``; return the summary. ``show`` opens the live
    window (:class:`~fringekit.tracking.display.LiveDisplay`); the other arguments are
    :func:`~fringekit.tracking.stream.track`'s."""
    cal = as_calibrated(sensor)
    if cal is not None:  # the overlay's pixels are the calibration's
        pixel_mm, origin_px = cal.grid_options(pixel_mm, origin_px)
    inputs = [
        source if os.path.exists(str(source)) else None,
        getattr(library, "folder", library),
        sensor,
        *as_paths(reference),
        *as_paths(residual_steps),
    ]
    with claim_output(out, command="track", inputs=inputs) as work:
        spool = FrameSpool(work / ".frames") if video else None
        view = LiveDisplay(pixel_mm, origin_px) if show else None

        def on_frame(f, img):
            for cb in (spool, view):
                if cb is not None:
                    cb(f, img)

        try:
            t = track(
                source,
                library,
                pixel_mm=pixel_mm,
                origin_px=origin_px,
                method=method,
                sensor=sensor,
                reference=reference,
                residual_steps=residual_steps,
                stride=stride,
                fps=fps,
                max_frames=max_frames,
                progress=progress,
                on_frame=None if spool is None and view is None else on_frame,
            )
        finally:
            if view is not None:
                view.close()
        if view is not None:
            t.summary["show"] = _show_summary(view)
            if view.error is not None:
                t.summary["warnings"].append(
                    f"--show: the window failed ({view.error}); the stream was tracked without it"
                )
        t.write(work)  # the tables first: whatever befalls the video, they are kept
        if spool is not None:
            # a frame of the video per state: phase states are six of the source's frames
            fps = (t.summary["source"]["fps"] or 25.0) / t.summary["frames_per_state"]
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


def _show_summary(view: LiveDisplay) -> dict:
    """``summary["show"]``: frames sent to the window, display updates skipped (frames
    not drawn; every frame's loads reach the rolling plot) and why the window failed
    (None when it did not)."""
    return {"frames_sent": view.sent, "updates_skipped": view.skipped, "error": view.error}


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
            painter = OverlayPainter(shape, sheet_to_pixel(shape, pixel_mm, origin_px))
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
