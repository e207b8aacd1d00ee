"""Frame sources for ``fringekit track``: a folder of images, a video file or a live camera,
read one frame at a time as :class:`RawFrame` objects.

:func:`open_source` turns the SOURCE a user gives into a :class:`FrameSource`:

- a folder: its image files (.png .tif .tiff .jpg .jpeg, any case; hidden files and other
  files are ignored) in natural name order, so ``frame2.png`` comes before ``frame10.png``;
  read as stored (8 or 16 bit, by :func:`fringekit.analysis.read_pixels`);
- a video file (.mp4 .avi .mkv .mov), decoded by PyAV to 8-bit RGB;
- ``camera:N``, camera number N through OpenCV (``pip install opencv-python-headless``). A
  background thread reads the camera without pause and keeps the newest frame only (a
  slot of one frame, never a queue): a consumer slower than the camera gets the newest
  frame each time it asks, and the frames it missed are counted in ``dropped``.

Every source yields frames of one size and type: a frame whose size, channel count or
pixel type differs from the first frame's raises :class:`~fringekit.errors.SourceError` at
that frame, after the earlier frames were yielded, so a caller keeps what it made of them.
An unreadable file of a folder and a video that stops decoding are raised the same way.

:func:`fringekit.tracking.write.write_video` writes frames to a video file.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import av
import numpy as np

from fringekit.analysis import read_pixels
from fringekit.errors import SourceError
from fringekit.inversion.rest import checked_pixels

__all__ = [
    "IMAGE_SUFFIXES",
    "VIDEO_SUFFIXES",
    "CameraSource",
    "FolderSource",
    "FrameSource",
    "RawFrame",
    "VideoSource",
    "open_source",
]

#: The image files a folder source reads (compared in lower case).
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg")

#: The video files a video source reads (compared in lower case).
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov")

#: What a SOURCE may be, for the messages.
ALLOWED = (
    "a folder of images (.png .tif .tiff .jpg .jpeg), a video (.mp4 .avi .mkv .mov) or "
    "camera:N (N = 0, 1, ...)"
)

#: OpenCV's property number of a capture's frame rate (``cv2.CAP_PROP_FPS``), fixed so that
#: a capture made by a ``capture_factory`` needs no OpenCV.
CAP_PROP_FPS = 5

#: Seconds :meth:`CameraSource.close` waits for the reading thread to return from a read.
CLOSE_WAIT_S = 5.0


@dataclass(frozen=True)
class RawFrame:
    """One frame of a source, as decoded.

    Parameters
    ----------
    index : int
        0-based position in the stream; for a camera the count of frames read, so a gap
        between two yielded frames shows the frames dropped.
    time_s : float
        Seconds from the start of the stream: index / fps for a folder (NaN without a
        frame rate), the frame's presentation time for a video (the first frame at 0), the
        monotonic time since the camera was opened for a camera.
    image : numpy.ndarray
        (rows, cols) grey or (rows, cols, 3) RGB, uint8 or uint16 (a video and a camera
        give uint8 RGB; an alpha channel is dropped).
    name : str
        The file name for a folder, ``"{file name}#{index}"`` for a video,
        ``"camera:{N}#{index}"`` for a camera.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.tracking import RawFrame
    >>> frame = RawFrame(0, 0.0, np.zeros((2, 3), np.uint8), "frame0.png")
    >>> frame.image.shape, frame.name
    ((2, 3), 'frame0.png')
    """

    index: int
    time_s: float
    image: np.ndarray
    name: str


class FrameSource:
    """A stream of :class:`RawFrame` objects; made by :func:`open_source`.

    Iterate over it for the frames; close it when done (or use it in a ``with`` block).
    A folder or a video can be iterated again from the start; a camera once.

    Attributes
    ----------
    kind : str
        ``"folder"``, ``"video"`` or ``"camera"``.
    spec : str
        The SOURCE as the user gave it.
    n_frames : int or None
        The number of frames when known: a folder's images, a video's count when its
        container states one; None for a camera.
    fps : float or None
        Frames per second: the ``fps`` given to :func:`open_source`, else a video's or a
        camera's own rate when it states one.
    live : bool
        True for a camera (frames arrive whether or not they are taken).
    dropped : int
        Frames read from a camera but replaced by a newer one before they were taken
        (0 for a folder or a video).

    Examples
    --------
    >>> import tempfile
    >>> import imageio.v3 as iio
    >>> import numpy as np
    >>> from fringekit.tracking import open_source
    >>> with tempfile.TemporaryDirectory() as d:
    ...     for k in (1, 2, 10):
    ...         iio.imwrite(f"{d}/frame{k}.png", np.full((4, 6), k, np.uint8))
    ...     with open_source(d, fps=10) as source:
    ...         frames = list(source)
    >>> source.kind, source.n_frames, [(f.name, f.time_s) for f in frames]
    ('folder', 3, [('frame1.png', 0.0), ('frame2.png', 0.1), ('frame10.png', 0.2)])
    """

    kind: str = ""
    spec: str = ""
    n_frames: int | None = None
    fps: float | None = None
    live: bool = False
    dropped: int = 0
    _closed: bool = False

    def __iter__(self) -> Iterator[RawFrame]:
        if self._closed:
            return
        frames = self._frames()
        first = None
        try:
            for frame in frames:
                if self._closed:
                    break
                if first is None:
                    first = frame
                elif _layout(frame.image) != _layout(first.image):
                    raise SourceError(
                        f"SOURCE {self.spec}: frame {frame.index} ({frame.name}) is "
                        f"{_describe(frame.image)} but the first frame ({first.name}) is "
                        f"{_describe(first.image)}; every frame must have the first one's size, "
                        "channels and bit depth"
                    )
                yield frame
        finally:
            frames.close()

    def _frames(self) -> Iterator[RawFrame]:  # pragma: no cover (each source has its own)
        raise NotImplementedError

    def close(self) -> None:
        """Release the file or the camera; the source yields no more frames (call it
        from the thread that iterates, except for a camera).

        Returns
        -------
        None
        """
        self._closed = True

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.spec}>"


def _layout(image: np.ndarray) -> tuple:
    return image.shape, image.dtype


def _describe(image: np.ndarray) -> str:
    rows, cols = image.shape[:2]
    colour = "RGB" if image.ndim == 3 else "grey"
    return f"{rows} x {cols} pixels (rows x cols) {colour} {image.dtype.itemsize * 8}-bit"


def _rgb_from_bgr(image) -> np.ndarray:
    """An OpenCV image as a frame's image: BGR(A) to RGB, (rows, cols, 1) to grey."""
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] >= 3:
        image = image[..., 2::-1]
    elif image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    return np.ascontiguousarray(image)


def _positive(value, option: str) -> float:
    """``value`` as a finite number > 0, or a SourceError naming ``option``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and number > 0) or isinstance(value, bool):
        raise SourceError(
            f"{option} {value} is not allowed; allowed: a number of frames per second > 0"
        )
    return number


def _reason(exc: BaseException) -> str:
    """The first line of an exception's message, without FFmpeg's errno prefix."""
    text = getattr(exc, "strerror", None) or str(exc).strip() or type(exc).__name__
    return text.splitlines()[0][:120]


def _natural_key(path: Path) -> tuple:
    """Sort key of natural order: digit runs compare as numbers (frame2 < frame10)."""
    parts = re.split(r"(\d+)", path.name.lower())
    return tuple(int(p) if k % 2 else p for k, p in enumerate(parts)), path.name


class FolderSource(FrameSource):
    """The image files of a folder in natural name order; made by :func:`open_source`.

    Parameters
    ----------
    folder : Path
        The folder (it holds at least one image file).
    spec : str
        The SOURCE as given.
    fps : float or None
        Frames per second, for the frames' ``time_s`` (NaN without).

    Examples
    --------
    >>> import tempfile
    >>> import imageio.v3 as iio
    >>> import numpy as np
    >>> from fringekit.tracking import open_source
    >>> with tempfile.TemporaryDirectory() as d:
    ...     iio.imwrite(f"{d}/b.png", np.zeros((4, 6, 3), np.uint8))
    ...     iio.imwrite(f"{d}/a.png", np.zeros((4, 6, 3), np.uint8))
    ...     source = open_source(d)
    ...     names = [frame.name for frame in source]
    >>> type(source).__name__, names, source.fps
    ('FolderSource', ['a.png', 'b.png'], None)
    """

    kind = "folder"

    def __init__(self, folder: Path, spec: str, fps: float | None = None):
        self.spec, self.folder, self.fps = spec, Path(folder), fps
        files = [
            p
            for p in self.folder.iterdir()
            if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file()
        ]
        if not files:
            raise SourceError(
                f"SOURCE {spec}: the folder holds no image file; allowed: a folder of "
                ".png .tif .tiff .jpg .jpeg images (one frame each), a video or camera:N"
            )
        self.files = tuple(sorted(files, key=_natural_key))
        self.n_frames = len(self.files)

    def _frames(self) -> Iterator[RawFrame]:
        for index, path in enumerate(self.files):
            where = f"SOURCE {self.spec}: frame {index} ({path.name})"
            try:
                img = read_pixels(path)
            except (OSError, ValueError) as exc:  # one line that names the file
                raise SourceError(f"SOURCE {self.spec}: frame {index}: {exc}") from None
            t = index / self.fps if self.fps else math.nan
            yield RawFrame(index, t, checked_pixels(img, where), path.name)


class VideoSource(FrameSource):
    """The frames of a video file, decoded by PyAV to 8-bit RGB; made by
    :func:`open_source`.

    Parameters
    ----------
    path : Path
        The video file (.mp4 .avi .mkv .mov).
    spec : str
        The SOURCE as given.
    fps : float or None
        Frames per second that replaces the video's own rate: the frames' ``time_s`` is
        then index / fps (a slow-motion recording played back at another rate).

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from fringekit.tracking import open_source, write_video
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_video(f"{d}/clip.mkv", [np.zeros((4, 6, 3), np.uint8)] * 3, 25,
    ...                        lossless=True)
    ...     with open_source(str(path)) as source:
    ...         frames = list(source)
    >>> source.kind, source.fps, [(f.name, f.time_s) for f in frames]
    ('video', 25.0, [('clip.mkv#0', 0.0), ('clip.mkv#1', 0.04), ('clip.mkv#2', 0.08)])
    """

    kind = "video"

    def __init__(self, path: Path, spec: str, fps: float | None = None):
        self.spec, self.path, self._fps_given = spec, Path(path), fps is not None
        self._container = None
        container = self._open()
        try:
            stream = container.streams.video[0]
            rate = stream.average_rate or stream.guessed_rate
            self.n_frames = int(stream.frames) or None
        finally:
            container.close()
        self.fps = fps if fps is not None else (float(rate) if rate else None)

    def _open(self):
        try:
            container = av.open(str(self.path))
        except (av.FFmpegError, OSError, ValueError) as exc:
            raise SourceError(
                f"SOURCE {self.spec}: not a readable video ({_reason(exc)}); allowed: {ALLOWED}"
            ) from None
        if not container.streams.video:
            container.close()
            raise SourceError(f"SOURCE {self.spec}: the file holds no video stream")
        return container

    def _frames(self) -> Iterator[RawFrame]:
        container = self._container = self._open()
        try:
            decoded = container.decode(container.streams.video[0])
            index, start = 0, None
            while not self._closed:
                try:
                    frame = next(decoded)
                except StopIteration:
                    break
                except (av.FFmpegError, OSError, ValueError) as exc:
                    raise SourceError(
                        f"SOURCE {self.spec}: frame {index} does not decode ({_reason(exc)}); "
                        f"the video ends after {index} readable frames"
                    ) from None
                if self._fps_given or frame.time is None:
                    t = index / self.fps if self.fps else math.nan
                else:
                    start = frame.time if start is None else start
                    t = frame.time - start
                image = np.ascontiguousarray(frame.to_ndarray(format="rgb24"))
                yield RawFrame(index, t, image, f"{self.path.name}#{index}")
                index += 1
            if index == 0 and not self._closed:
                raise SourceError(f"SOURCE {self.spec}: the video holds no frame")
        finally:
            container.close()
            self._container = None

    def close(self) -> None:
        """Close the video file (a running iteration stops).

        Returns
        -------
        None
        """
        super().close()
        if self._container is not None:
            self._container.close()
            self._container = None


class CameraSource(FrameSource):
    """A live camera: a thread reads it continuously into a slot of one frame, and each
    frame taken is the newest; made by :func:`open_source`.

    The slot never holds more than one frame: a frame replaced before it was taken is
    counted in :attr:`dropped`, so frames read = frames yielded + ``dropped`` at the end.
    The stream ends when the camera fails to read (the frame in the slot is yielded
    first) or when :meth:`close` is called; the camera is released by the reading thread
    when it stops.

    Parameters
    ----------
    number : int
        The camera's index N (``camera:N``).
    capture : object
        An opened capture: ``read() -> (ok, BGR or grey array)``, ``get(prop)``,
        ``release()`` (a ``cv2.VideoCapture`` or a stand-in).
    spec : str
        The SOURCE as given.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.tracking import open_source
    >>> class Capture:  # a stand-in for cv2.VideoCapture: three frames, then no more
    ...     n = 0
    ...     def isOpened(self): return True
    ...     def get(self, prop): return 30.0
    ...     def release(self): pass
    ...     def read(self):
    ...         self.n += 1
    ...         return self.n <= 3, np.zeros((4, 6, 3), np.uint8)
    >>> with open_source("camera:0", capture_factory=lambda n: Capture()) as camera:
    ...     frames = list(camera)
    >>> camera.live, camera.fps, len(frames) + camera.dropped, frames[-1].name
    (True, 30.0, 3, 'camera:0#2')
    """

    kind = "camera"
    live = True

    def __init__(self, number: int, capture, spec: str):
        self.spec, self.number, self._capture = spec, number, capture
        rate = capture.get(CAP_PROP_FPS)
        self.fps = float(rate) if rate and rate > 0 else None
        self._opened = time.monotonic()
        self._slot: RawFrame | None = None
        self._ended = self._stop = False
        self._error: str | None = None
        self._ready = threading.Condition()
        self._thread: threading.Thread | None = None

    def _read_loop(self) -> None:
        """The reading thread: every frame into the slot, replacing the one not taken."""
        index = 0
        try:
            while not self._stop:
                ok, image = self._capture.read()
                t = time.monotonic() - self._opened
                if not ok or image is None:
                    break
                frame = RawFrame(index, t, _rgb_from_bgr(image), f"{self.spec}#{index}")
                with self._ready:
                    if self._slot is not None or self._stop:  # replaced, or never taken
                        self.dropped += 1
                    self._slot = None if self._stop else frame
                    self._ready.notify_all()
                index += 1
        except Exception as exc:  # a capture may raise anything; the consumer is told
            self._error = f"{type(exc).__name__}: {_reason(exc)}"
        finally:
            with self._ready:
                self._ended = True
                self._ready.notify_all()
            self._release()

    def _release(self) -> None:
        with self._ready:
            capture, self._capture = self._capture, None
        if capture is not None:
            capture.release()

    def _frames(self) -> Iterator[RawFrame]:
        with self._ready:
            if self._thread is None and not self._stop:
                name = f"fringekit-camera-{self.number}"
                self._thread = threading.Thread(target=self._read_loop, name=name, daemon=True)
                self._thread.start()
        while True:
            with self._ready:
                self._ready.wait_for(lambda: self._slot is not None or self._ended or self._stop)
                frame, self._slot = self._slot, None
            if frame is None:
                break
            yield frame
        if self._error and not self._stop:
            raise SourceError(f"SOURCE {self.spec}: the camera stopped ({self._error})")

    def close(self) -> None:
        """Stop the reading thread (waiting for its read to return, at most
        :data:`CLOSE_WAIT_S`) and release the camera; a frame not taken counts as dropped.

        Returns
        -------
        None
        """
        super().close()
        with self._ready:
            self._stop = True
            if self._slot is not None:
                self.dropped += 1
                self._slot = None
            self._ready.notify_all()
            thread = self._thread
        if thread is None:  # never read: no thread to stop (and none will start)
            self._release()
        else:
            thread.join(CLOSE_WAIT_S)  # the thread releases the camera when it stops


def _camera(spec: str, number: str, capture_factory: Callable | None) -> CameraSource:
    """Open ``camera:N`` through ``capture_factory`` or OpenCV."""
    if capture_factory is None:
        try:
            import cv2  # lazy: OpenCV is the optional extra fringekit[camera]
        except ImportError:
            raise SourceError(
                f"SOURCE {spec} needs OpenCV, which is not installed; pip install "
                "opencv-python-headless (or fringekit[camera]), or give a folder or video"
            ) from None
        capture_factory = cv2.VideoCapture
    capture = capture_factory(int(number))
    if not capture.isOpened():
        capture.release()
        raise SourceError(
            f"SOURCE {spec}: camera:{int(number)} did not open (no camera with that index, "
            "or one in use by another program); check the camera index, or give a folder "
            "or video"
        )
    return CameraSource(int(number), capture, spec)


def open_source(
    spec: str, *, fps: float | None = None, capture_factory: Callable | None = None
) -> FrameSource:
    """Open the SOURCE of ``fringekit track``: a folder of images, a video or a camera.

    Parameters
    ----------
    spec : str
        A folder of images (.png .tif .tiff .jpg .jpeg, any case), a video file (.mp4 .avi
        .mkv .mov) or ``camera:N`` with N the camera's index (0, 1, ...).
    fps : float, optional
        Frames per second of a folder (each frame's ``time_s`` = index / fps; NaN without)
        or of a video instead of its own rate; not allowed for a camera, whose frames
        carry the clock's time.
    capture_factory : callable, optional
        ``N -> capture`` for a camera, with ``isOpened()``, ``read() -> (ok, BGR array)``,
        ``get(prop)`` and ``release()``; OpenCV's ``cv2.VideoCapture`` when not given
        (OpenCV is then imported, and only then).

    Returns
    -------
    FrameSource
        A :class:`FolderSource`, :class:`VideoSource` or :class:`CameraSource`.

    Raises
    ------
    SourceError
        A SOURCE of none of these kinds, a path that does not exist, a folder without
        images, a video that does not open, ``camera:N`` with N not a number, a camera
        that does not open, OpenCV not installed, or an fps that is not a positive number.

    Examples
    --------
    >>> import tempfile
    >>> import imageio.v3 as iio
    >>> import numpy as np
    >>> from fringekit.tracking import open_source
    >>> with tempfile.TemporaryDirectory() as d:
    ...     iio.imwrite(f"{d}/frame2.png", np.zeros((4, 6), np.uint16))
    ...     iio.imwrite(f"{d}/frame10.png", np.full((4, 6), 4000, np.uint16))
    ...     with open_source(d, fps=5) as source:
    ...         frames = list(source)
    >>> [(f.index, f.time_s, f.name, f.image.dtype.name) for f in frames]
    [(0, 0.0, 'frame2.png', 'uint16'), (1, 0.2, 'frame10.png', 'uint16')]
    >>> open_source("notes.txt")
    Traceback (most recent call last):
    ...
    fringekit.errors.SourceError: SOURCE notes.txt does not exist; allowed: a folder of ...
    """
    spec = str(spec)
    if fps is not None:
        fps = _positive(fps, "--fps")
    if spec.lower().startswith("camera:"):
        number = spec.split(":", 1)[1]
        if not re.fullmatch(r"[0-9]+", number):
            raise SourceError(
                f"SOURCE {spec} is not allowed; a camera is camera:N with N its index "
                "(0, 1, ...), e.g. camera:0"
            )
        if fps is not None:
            raise SourceError(
                f"--fps {fps} is not allowed with SOURCE {spec}: a camera's frames carry the "
                "time they were read; give --fps for a folder or a video"
            )
        return _camera(spec, number, capture_factory)
    path = Path(spec).expanduser()
    if not path.exists():
        raise SourceError(f"SOURCE {spec} does not exist; allowed: {ALLOWED}")
    if path.is_dir():
        return FolderSource(path, spec, fps)
    if path.suffix.lower() in VIDEO_SUFFIXES:
        return VideoSource(path, spec, fps)
    kind = f"a {path.suffix} file" if path.suffix else "a file without suffix"
    raise SourceError(f"SOURCE {spec} is not allowed ({kind}); allowed: {ALLOWED}")
