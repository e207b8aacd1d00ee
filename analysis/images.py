"""Reading fringe images: 8/16-bit PNG, TIFF, JPEG, grey or colour, and six-step stacks.

Images are returned as float arrays scaled to [0, 1] by the full scale of their integer type
(255 or 65535), so that calibration tables and measurements made at different bit depths
compare directly. Nothing here knows how an image was made (camera or optics).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import png
import tifffile
from scipy import ndimage

__all__ = [
    "Frame",
    "load_image",
    "load_six_step",
    "image_noise_sd",
    "normalise",
    "read_pixels",
    "SIX_STEP_ORDER",
]

#: The arrangement of a six-step set (the table of ``docs/theory.md``, Ramesh 2000): image k is
#: taken with quarter-wave plates (xi, eta) and analyser beta of row k, polariser at pi/2.
SIX_STEP_ORDER = (
    "1: xi=3pi/4 eta=pi/4 beta=pi/2  I ~ 1 + cos d",
    "2: xi=3pi/4 eta=pi/4 beta=0     I ~ 1 - cos d",
    "3: xi=3pi/4 eta=0    beta=0     I ~ 1 - sin 2t sin d",
    "4: xi=3pi/4 eta=pi/4 beta=pi/4  I ~ 1 + cos 2t sin d",
    "5: xi=pi/4  eta=0    beta=0     I ~ 1 + sin 2t sin d",
    "6: xi=pi/4  eta=3pi/4 beta=pi/4 I ~ 1 - cos 2t sin d",
)


@dataclass(frozen=True)
class Frame:
    """One image as floats in [0, 1] (made by :func:`load_image` and :func:`normalise`).

    Parameters
    ----------
    data : (rows, cols) or (rows, cols, 3) float64 array
        Grey or colour values in [0, 1].
    saturated : (rows, cols) bool array
        Any channel at the top of its integer range.
    bit_depth : int
        8 or 16 (0 for float input).
    source : str
        File name or "array".

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import normalise
    >>> frame = normalise(np.zeros((4, 6, 3), np.uint8))
    >>> frame.shape, frame.data.shape, frame.bit_depth
    ((4, 6), (4, 6, 3), 8)
    """

    data: np.ndarray
    saturated: np.ndarray
    bit_depth: int
    source: str = "array"

    @property
    def shape(self) -> tuple[int, int]:
        return self.data.shape[:2]


def normalise(image, *, source: str = "array") -> Frame:
    """Scale an integer or float image to [0, 1] and find its saturated pixels.

    Parameters
    ----------
    image : (rows, cols), (rows, cols, 2) or (rows, cols, 3|4) array
        uint8, uint16 or float in [0, 1]: grey, grey + alpha, colour, colour + alpha. An
        alpha channel is dropped.
    source : str
        Name used in error messages.

    Returns
    -------
    Frame

    Raises
    ------
    ValueError
        Another shape or dtype, fewer than 2 pixels a side, or floats outside [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import normalise
    >>> frame = normalise(np.array([[0, 51], [255, 102]], np.uint8))
    >>> frame.data.tolist(), frame.saturated.tolist(), frame.bit_depth
    ([[0.0, 0.2], [1.0, 0.4]], [[False, False], [True, False]], 8)
    """
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] in (2, 4):  # grey or colour with alpha: alpha dropped
        img = img[..., 0] if img.shape[2] == 2 else img[..., :3]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise ValueError(
            f"{source}: image shape {img.shape} is not allowed; use (rows, cols) grey or "
            "(rows, cols, 3) colour"
        )
    if min(img.shape[:2]) < 2:
        raise ValueError(f"{source}: image shape {img.shape} has fewer than 2 pixels a side")
    if img.dtype == np.uint8 or img.dtype == np.uint16:
        top = float(np.iinfo(img.dtype).max)
        bits = 8 if img.dtype == np.uint8 else 16
        sat = img >= top
        data = img.astype(np.float64) / top
    elif np.issubdtype(img.dtype, np.floating):
        data = img.astype(np.float64)
        finite = data[np.isfinite(data)]
        if finite.size and (finite.min() < -1e-9 or finite.max() > 1 + 1e-9):
            raise ValueError(
                f"{source}: float image values span [{finite.min():.3g}, {finite.max():.3g}]; "
                "float images must lie in [0, 1]"
            )
        bits, sat = 0, data >= 1.0
    else:
        raise ValueError(f"{source}: image dtype {img.dtype} is not allowed; use uint8/16 or float")
    if sat.ndim == 3:
        sat = sat.any(axis=2)
    return Frame(data=data, saturated=sat, bit_depth=bits, source=source)


def load_image(path, *, dark=None) -> Frame:
    """Read one PNG/TIFF/JPEG image (8 or 16 bit, grey or colour) as a :class:`Frame`.

    Parameters
    ----------
    path : str or Path
    dark : str, Path, array or Frame, optional
        Dark/background frame subtracted before use (same shape); the result is clipped
        at zero.

    Returns
    -------
    Frame
        Values in [0, 1] of the file's full scale.

    Raises
    ------
    FileNotFoundError, ValueError
        Missing file, unreadable format, a multi-page file (use :func:`load_six_step`),
        an empty (all-equal) image, or a dark frame of another shape.

    Examples
    --------
    >>> import tempfile
    >>> import imageio.v3 as iio
    >>> import numpy as np
    >>> from fringekit.analysis import load_image
    >>> with tempfile.TemporaryDirectory() as d:
    ...     iio.imwrite(f"{d}/fringes.png", np.array([[0, 128], [255, 64]], np.uint8))
    ...     frame = load_image(f"{d}/fringes.png", dark=np.full((2, 2), 10, np.uint8))
    >>> frame.data.round(3).tolist(), frame.bit_depth
    ([[0.0, 0.463], [0.961, 0.212]], 8)
    """
    return _subtract_dark(_read_frame(path), dark)


def _is_16_bit_png(path: Path) -> bool:
    """Whether ``path`` is a PNG of 16 bits per sample (its IHDR's bit depth byte)."""
    with open(path, "rb") as fh:
        head = fh.read(26)
    return head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR" and head[24] == 16


def _read_16_bit_png(path: Path) -> np.ndarray:
    """A 16-bit PNG at its full depth, (rows, cols) or (rows, cols, planes) uint16: Pillow,
    which imageio reads PNGs with, keeps 16-bit grey but cuts 16-bit colour to 8 bits.
    pypng decodes every PNG variant (filters, interlacing, alpha); the EXIF orientation
    is not applied here (16-bit PNGs come from processing software, not cameras)."""
    width, height, rows, info = png.Reader(filename=str(path)).asDirect()
    img = np.vstack([np.asarray(row, np.uint16) for row in rows])
    planes = info["planes"]
    return img.reshape(height, width, planes) if planes > 1 else img.reshape(height, width)


def read_pixels(path) -> np.ndarray:
    """The pixels of one PNG/TIFF/JPEG file as stored, unscaled: what :func:`load_image`
    reads before it scales them to [0, 1].

    16-bit colour PNGs keep their full depth (Pillow would cut them to 8 bits); JPEG and
    PNG photographs are turned by the camera's EXIF orientation, as a viewer shows them.

    Parameters
    ----------
    path : str or Path
        An image file.

    Returns
    -------
    numpy.ndarray
        (rows, cols) grey or (rows, cols, channels) with 2 (grey and alpha), 3 (RGB) or 4
        (RGBA) channels, of the file's type (uint8, uint16, or float for a float TIFF); a
        multi-page TIFF gives (pages, rows, cols).

    Raises
    ------
    FileNotFoundError, ValueError
        A missing file, a folder, or a file that is not a readable image (one line naming
        the file).

    Examples
    --------
    >>> import tempfile
    >>> import imageio.v3 as iio
    >>> import numpy as np
    >>> from fringekit.analysis import read_pixels
    >>> with tempfile.TemporaryDirectory() as d:
    ...     iio.imwrite(f"{d}/deep.png", np.array([[0, 1000], [65535, 7]], np.uint16))
    ...     pixels = read_pixels(f"{d}/deep.png")
    >>> pixels.dtype, pixels.tolist()
    (dtype('uint16'), [[0, 1000], [65535, 7]])
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give an image file (PNG, TIFF or JPEG)")
    if not path.is_file():
        raise FileNotFoundError(f"image file {str(path)!r} does not exist")
    try:
        # The plugins are named (the ones imageio picks for these files): left to choose,
        # imageio tries a file Pillow cannot read as a video when PyAV is installed, and
        # reports that attempt's failure instead.
        if _is_16_bit_png(path):
            img = _read_16_bit_png(path)
        elif path.suffix.lower() in (".tif", ".tiff"):
            img = iio.imread(path, plugin="tifffile")
        else:  # the camera's EXIF orientation, as a viewer shows the photograph (JPEG, PNG)
            img = iio.imread(path, plugin="pillow", rotate=True)
    except Exception as exc:  # imageio raises many types (and multi-line advice)
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:120]
        raise ValueError(f"{path}: not a readable PNG/TIFF/JPEG image ({first})") from None
    return img


def _read_frame(path) -> Frame:
    """One image file as a Frame, without the emptiness check (a dark frame may be flat)."""
    img = read_pixels(path)
    if img.ndim == 3 and img.shape[2] not in (2, 3, 4) and img.shape[0] > 1:
        raise ValueError(
            f"{path}: holds {img.shape[0]} pages, a stack where one image is expected (six "
            "phase-stepped images go to the phase method)"
        )
    return normalise(img, source=str(path))


#: A dark frame brighter than the image by more than DARK_MARGIN of full scale (5 levels
#: of 8 bits, beyond a camera's read noise at its black level) on more than this share of
#: the pixels is not one: it would erase the image it is subtracted from.
MAX_DARK_BRIGHTER = 0.5
DARK_MARGIN = 0.02


def _subtract_dark(frame: Frame, dark) -> Frame:
    """``frame`` minus the dark frame (clipped at 0); a uniform dark frame is valid, an
    empty (all-equal) result is not."""
    if dark is None:
        d = None
    elif isinstance(dark, Frame):
        d = dark
    elif isinstance(dark, str | Path):
        d = _read_frame(dark)
    else:
        d = normalise(dark, source="dark")
    if d is not None:
        if d.data.shape != frame.data.shape:
            raise ValueError(
                f"dark frame shape {d.data.shape} does not match image {frame.source} shape "
                f"{frame.data.shape}"
            )
        brighter = float(np.mean(d.data > frame.data + DARK_MARGIN))
        if brighter > MAX_DARK_BRIGHTER:
            raise ValueError(
                f"dark frame {d.source} is brighter than the image {frame.source} on "
                f"{100 * brighter:.0f} % of the pixels (median {np.nanmedian(d.data):.3g} against "
                f"{np.nanmedian(frame.data):.3g} of full scale); allowed: a frame taken with the "
                "light off, darker than the image almost everywhere"
            )
        frame = Frame(
            np.clip(frame.data - d.data, 0.0, None), frame.saturated, frame.bit_depth, frame.source
        )
    if not np.isfinite(frame.data).any():
        raise ValueError(f"{frame.source}: the image holds no finite value (every pixel is NaN)")
    if np.nanmax(frame.data) == np.nanmin(frame.data):
        raise ValueError(
            f"{frame.source}: the image is empty (every pixel equals {np.nanmin(frame.data):.4g})"
        )
    return frame


def load_six_step(images, *, dark=None) -> list[Frame]:
    """Read a six-step set: six files or arrays, or one multi-page TIFF with six pages.

    The order of the images is :data:`SIX_STEP_ORDER`. Colour images are converted to
    grey (mean of the channels: each step of a monochrome method must use one band).

    Parameters
    ----------
    images : sequence of six paths or arrays, or one path to a 6-page TIFF
    dark : str, Path or array, optional
        Dark frame subtracted from each image.

    Returns
    -------
    list of 6 Frame
        Grey frames in [0, 1].

    Raises
    ------
    FileNotFoundError, ValueError
        Missing files, not six images, mismatched sizes, empty images.

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> import tifffile
    >>> from fringekit.analysis import load_six_step
    >>> stack = np.arange(6 * 3 * 4, dtype=np.uint16).reshape(6, 3, 4) * 100
    >>> with tempfile.TemporaryDirectory() as d:
    ...     tifffile.imwrite(f"{d}/six.tif", stack)
    ...     frames = load_six_step(f"{d}/six.tif")
    >>> len(frames), frames[0].shape, frames[0].bit_depth
    (6, (3, 4), 16)
    """
    if isinstance(images, str | Path):
        path = Path(images)
        if not path.is_file():
            raise FileNotFoundError(f"image file {str(path)!r} does not exist")
        try:
            stack = tifffile.imread(path)
        except Exception as exc:
            raise ValueError(f"{path}: not a readable multi-page TIFF ({exc})") from None
        if stack.ndim < 3:
            raise ValueError(f"{path}: holds 1 page; a six-step stack needs 6 pages")
        frames = [
            _subtract_dark(normalise(p, source=f"{path}[page {k}]"), dark)
            for k, p in enumerate(stack)
        ]
    else:
        items = list(images)
        frames = [
            load_image(p, dark=dark)
            if isinstance(p, str | Path)
            else _subtract_dark(normalise(p, source=f"image {k + 1}"), dark)
            for k, p in enumerate(items)
        ]
    if len(frames) != 6:
        raise ValueError(
            f"a six-step set needs exactly 6 images (got {len(frames)}); order: "
            + "; ".join(SIX_STEP_ORDER)
        )
    shapes = {f.data.shape[:2] for f in frames}
    if len(shapes) != 1:
        raise ValueError(
            "the six images differ in size: "
            + ", ".join(f"{f.source} {f.data.shape[:2]}" for f in frames)
        )
    out = []
    for f in frames:
        data = f.data.mean(axis=2) if f.data.ndim == 3 else f.data
        out.append(Frame(data, f.saturated, f.bit_depth, f.source))
    return out


def image_noise_sd(image: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Per-pixel noise standard deviation of a grey image.

    Immerkaer's operator (J. Immerkaer, "Fast noise variance estimation", Comput. Vis.
    Image Underst. 64, 1996): the difference of two Laplacians cancels intensity varying
    linearly or quadratically, and its response to white noise has sd 6 sigma; here
    through the median absolute response, robust to fringe edges.

    Parameters
    ----------
    image : (rows, cols) float array
    mask : (rows, cols) bool array, optional
        Pixels used (eroded by one pixel).

    Returns
    -------
    float
        Noise sd in the image's units (0 when no pixel is left).

    Examples
    --------
    Noise of sd 0.01 on a smooth ramp:

    >>> import numpy as np
    >>> from fringekit.analysis import image_noise_sd
    >>> ramp = np.linspace(0, 1, 128)[None, :] * np.ones((128, 1))
    >>> noisy = ramp + np.random.default_rng(0).normal(0, 0.01, ramp.shape)
    >>> round(image_noise_sd(noisy), 2)
    0.01
    """
    kernel = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
    resp = ndimage.convolve(np.asarray(image, float), kernel, mode="reflect")
    if mask is not None:
        resp = resp[ndimage.binary_erosion(mask)]
    return 1.4826 * float(np.median(np.abs(resp))) / 6.0 if resp.size else 0.0
