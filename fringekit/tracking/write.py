"""Writing frames to a video file with PyAV: h264 in an .mp4 (the overlay ``fringekit
track`` can write) or, with ``lossless=True``, FFV1 in an .mkv or .avi that reads back
pixel for pixel through :func:`fringekit.tracking.source.open_source`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from fractions import Fraction
from pathlib import Path

import av
import numpy as np

from fringekit.errors import InputError
from fringekit.tracking.source import VIDEO_SUFFIXES

__all__ = ["CODECS", "WRITE_SUFFIXES", "write_video"]

#: The codec, pixel format and encoder options of each kind of video :func:`write_video`
#: makes: FFV1 keeps every pixel (``bgr0`` holds 8-bit RGB exactly), h264 in 4:2:0 plays
#: everywhere.
CODECS = {
    True: ("ffv1", "bgr0", {}),
    False: ("h264", "yuv420p", {"crf": "18"}),
}

#: The suffixes :func:`write_video` accepts, lossless and lossy.
WRITE_SUFFIXES = {True: (".mkv", ".avi"), False: VIDEO_SUFFIXES}


def write_video(path, frames: Iterable[np.ndarray], fps: float, *, lossless: bool = False) -> Path:
    """Write 8-bit frames to a video file with PyAV.

    The frames are taken one at a time (a generator is not held in memory). A lossy video
    (h264, 4:2:0 colour) has an even width and height: a frame of odd size gains a copy of
    its last row or column. If ``frames`` raises or a frame is refused, the file keeps the
    frames written before it (none: no file) and the error is raised.

    Parameters
    ----------
    path : str or Path
        The file to write: .mp4 .avi .mkv .mov, or .mkv .avi when ``lossless``.
    frames : iterable of numpy.ndarray
        (rows, cols, 3) RGB or (rows, cols) grey (written as RGB) uint8 images, all of the
        first one's size.
    fps : float
        Frames per second (> 0).
    lossless : bool
        FFV1, which reads back pixel for pixel (:func:`open_source`), instead of h264.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        Another suffix, an fps that is not > 0, no frame, a frame that is not uint8
        (rows, cols) or (rows, cols, 3), or one of another size than the first.

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from fringekit.tracking import open_source, write_video
    >>> frames = [np.full((4, 6, 3), 40 * k, np.uint8) for k in range(3)]
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_video(f"{d}/exact.mkv", frames, 10, lossless=True)
    ...     with open_source(str(path)) as source:
    ...         back = [frame.image for frame in source]
    >>> path.name, all(np.array_equal(a, b) for a, b in zip(frames, back))
    ('exact.mkv', True)
    """
    path = Path(path)
    lossless = bool(lossless)
    if path.suffix.lower() not in WRITE_SUFFIXES[lossless]:
        kind = "a lossless" if lossless else "a"
        raise InputError(
            f"video file {path.name} is not allowed for {kind} video; allowed suffixes: "
            + " ".join(WRITE_SUFFIXES[lossless])
        )
    rate = _rate(fps)
    container = stream = first = None
    try:
        for k, image in enumerate(frames):
            rgb = _video_rgb(image, k, first, lossless)
            if container is None:
                first = np.asarray(image).shape[:2]
                container, stream = _open_writer(path, rgb.shape, rate, lossless)
            for packet in stream.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")):
                container.mux(packet)
        if container is None:
            raise InputError(f"video file {path.name}: no frame to write; give at least one")
    finally:
        if container is not None:
            for packet in stream.encode():  # flush the encoder: every frame given is kept
                container.mux(packet)
            container.close()
    return path


def _video_rgb(image, k: int, first: tuple | None, lossless: bool) -> np.ndarray:
    """Frame ``k`` as a contiguous RGB uint8 array of even size for a lossy video."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 3)):
        raise InputError(
            f"write_video: frame {k} is {img.dtype} of shape {img.shape}; allowed: uint8 "
            "(rows, cols, 3) RGB or (rows, cols) grey"
        )
    if first is not None and img.shape[:2] != first:
        raise InputError(
            f"write_video: frame {k} is {img.shape[0]} x {img.shape[1]} pixels but the first "
            f"frame is {first[0]} x {first[1]} (rows x cols); every frame must have its size"
        )
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if not lossless:  # 4:2:0 colour needs an even width and height
        img = np.pad(img, ((0, img.shape[0] % 2), (0, img.shape[1] % 2), (0, 0)), mode="edge")
    return np.ascontiguousarray(img)


def _open_writer(path: Path, shape: tuple, rate: Fraction, lossless: bool):
    """The output container and its video stream for frames of ``shape``."""
    codec, pix_fmt, options = CODECS[lossless]
    container = av.open(str(path), mode="w")
    try:
        stream = container.add_stream(codec, rate=rate)
        stream.height, stream.width = shape[:2]
        stream.pix_fmt = pix_fmt
        stream.options = dict(options)
    except Exception:
        container.close()
        raise
    return container, stream


def _rate(fps) -> Fraction:
    """The frame rate as the fraction a stream takes; an InputError if it is not > 0."""
    try:
        number = float(fps)
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and number > 0) or isinstance(fps, bool):
        raise InputError(f"fps {fps} is not allowed; allowed: a number of frames per second > 0")
    return Fraction(number).limit_denominator(1001)
