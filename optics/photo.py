"""What a real photograph adds to an ideal polariscope image, for tests with known truth.

A :class:`PhotoModel` turns the Jones quaternions of a specimen into camera images that
look like laboratory photographs:

- **residual birefringence**: a smooth random retarder (frozen-in stress of the sheet or
  the polariscope's optics) in series with the specimen, so it adds to the retardation
  vectorially, as it does in the light path;
- **vignetting**: a radial fall-off of the illumination, ``1 - v (r / r_corner)^2`` (the
  leading term of the cos^4 law, Ray, *Applied Photographic Optics*, 3rd ed., ch. 7);
- **veiling glare**: a uniform fraction of full scale added to every pixel;
- the camera's exposure, shot and read noise, saturation and quantisation
  (:meth:`optics.camera.Camera.encode`);
- a **Bayer mosaic** (RGGB) demosaiced by bilinear interpolation, for colour images;
- **JPEG** compression at a given quality (imageio, in memory).

Every effect is seeded: one model and seed give the same image bit for bit.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace

import imageio.v3 as iio
import numpy as np
from scipy.ndimage import convolve, gaussian_filter, zoom

from .camera import Camera, Spectrum, white_light_image
from .jones import qmul, retarder
from .polariscope import Arrangement, intensity

__all__ = [
    "PhotoModel",
    "crack_tip_field",
    "indent_field",
    "residual_birefringence",
    "photograph",
    "white_light_photograph",
]


@dataclass(frozen=True)
class PhotoModel:
    """Imperfections of a photograph (all off by default).

    Parameters
    ----------
    residual_rms_rad : float
        RMS of the residual retardation field (rad); its axis angle is random and smooth
        too.
    residual_scale : float
        Correlation length of the residual field, as a fraction of the image width.
    vignetting : float
        Relative illumination lost at the image corners (0 = none, 0.3 = 30 %).
    glare : float
        Veiling glare, fraction of full scale added everywhere.
    bayer : bool
        Colour images go through an RGGB mosaic and bilinear demosaicing.
    jpeg_quality : int or None
        JPEG quality 1-100; None writes no JPEG.
    seed : int
        Seed of the residual field (noise uses the ``seed`` of :func:`photograph`).

    Raises
    ------
    ValueError
        A value outside its range.

    Examples
    --------
    >>> from fringekit.optics import PhotoModel
    >>> lab = PhotoModel(residual_rms_rad=0.05, vignetting=0.3, glare=0.02, jpeg_quality=90)
    >>> lab.bayer, lab.seed
    (False, 0)
    """

    residual_rms_rad: float = 0.0
    residual_scale: float = 0.25
    vignetting: float = 0.0
    glare: float = 0.0
    bayer: bool = False
    jpeg_quality: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        checks = {
            "residual_rms_rad": self.residual_rms_rad >= 0,
            "residual_scale": self.residual_scale > 0,
            "vignetting": 0 <= self.vignetting < 1,
            "glare": 0 <= self.glare < 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"PhotoModel.{name} = {getattr(self, name)!r} is not allowed")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            raise ValueError(
                f"PhotoModel.jpeg_quality = {self.jpeg_quality!r} is not allowed; use 1-100"
            )


def _smooth_field(shape, scale_px: float, rng) -> np.ndarray:
    """Zero-mean, unit-RMS Gaussian random field with correlation length ``scale_px``.

    Smoothed on a grid 4 points per correlation length and interpolated (cubic) to the
    image: the field holds nothing finer, and a full-resolution Gaussian filter of a
    3000-pixel-wide image with a 750-pixel length took minutes."""
    step = max(scale_px / 4, 1.0)
    coarse = tuple(max(int(np.ceil(n / step)) + 1, 2) for n in shape)
    f = gaussian_filter(rng.standard_normal(coarse), scale_px / step, mode="wrap")
    f = zoom(f, [n / m for n, m in zip(shape, coarse, strict=True)], order=3)[
        : shape[0], : shape[1]
    ]
    return (f - f.mean()) / (f.std() or 1.0)


def residual_birefringence(shape, model: PhotoModel) -> np.ndarray:
    """Quaternions of the smooth random residual retarder of ``model``.

    Parameters
    ----------
    shape : (rows, cols)
    model : PhotoModel
        Its ``residual_rms_rad``, ``residual_scale`` and ``seed`` set the field.

    Returns
    -------
    (rows, cols, 4) float array

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PhotoModel, characteristic, residual_birefringence
    >>> q = residual_birefringence((32, 32), PhotoModel(residual_rms_rad=0.1, seed=3))
    >>> delta = characteristic(q)[0]
    >>> q.shape, round(float(np.sqrt(np.mean(delta**2))), 2)  # rad RMS
    ((32, 32, 4), 0.1)
    """
    rng = np.random.default_rng(model.seed)
    scale = model.residual_scale * shape[1]
    delta = model.residual_rms_rad * _smooth_field(shape, scale, rng)
    theta = np.pi * _smooth_field(shape, scale, rng)
    return retarder(delta, theta)


def _vignetting(shape, v: float) -> np.ndarray:
    rows, cols = shape
    r, c = np.mgrid[:rows, :cols]
    y, x = r - (rows - 1) / 2, c - (cols - 1) / 2
    rel = (x * x + y * y) / ((rows - 1) ** 2 / 4 + (cols - 1) ** 2 / 4)
    return 1.0 - v * rel


def _bayer(rgb: np.ndarray) -> np.ndarray:
    """RGGB mosaic of a float (rows, cols, 3) image, demosaiced bilinearly."""
    rows, cols, _ = rgb.shape
    r, c = np.mgrid[:rows, :cols]
    sites = [(r % 2 == 0) & (c % 2 == 0), (r + c) % 2 == 1, (r % 2 == 1) & (c % 2 == 1)]
    kernel = np.array([[0.25, 0.5, 0.25], [0.5, 1.0, 0.5], [0.25, 0.5, 0.25]])
    out = np.empty_like(rgb)
    for k, site in enumerate(sites):
        raw = np.where(site, rgb[..., k], 0.0)
        weight = convolve(site.astype(float), kernel, mode="mirror")
        out[..., k] = convolve(raw, kernel, mode="mirror") / weight
    return out


def _jpeg(img: np.ndarray, quality: int) -> np.ndarray:
    buf = io.BytesIO()
    iio.imwrite(buf, img, extension=".jpg", quality=quality)
    return iio.imread(buf.getvalue(), extension=".jpg")


def photograph(
    q: np.ndarray,
    arrangement: Arrangement,
    camera: Camera,
    model: PhotoModel,
    *,
    seed: int | None = 0,
    tint=None,
) -> np.ndarray:
    """A monochrome-light photograph (8/16-bit) of specimen quaternions.

    Residual birefringence, vignetting, glare, the camera's noise, a Bayer mosaic and
    JPEG compression as ``model`` sets them; seeded, so the same inputs give the same
    image bit for bit.

    Parameters
    ----------
    q : (rows, cols, 4) float array
        Specimen path quaternions.
    arrangement : Arrangement
    camera : Camera
    model : PhotoModel
    seed : int or None
        Seed of the camera noise.
    tint : (3,) float array, optional
        Renders the monochrome light as a colour image (e.g. green light on a colour
        camera: (0.1, 1.0, 0.2)); the Bayer mosaic then applies.

    Returns
    -------
    (rows, cols) or (rows, cols, 3) uint8 or uint16 array

    Examples
    --------
    >>> from fringekit.optics import Camera, PhotoModel, dark_field_circular, indent_field
    >>> from fringekit.optics import photograph
    >>> order, q, mask = indent_field(16, 16)
    >>> model = PhotoModel(residual_rms_rad=0.05, vignetting=0.2, jpeg_quality=90, seed=1)
    >>> img = photograph(q, dark_field_circular(), Camera(), model)
    >>> img.dtype.name, img.shape
    ('uint8', (16, 16))
    >>> green = (0.1, 1.0, 0.2)  # green light on a colour camera
    >>> photograph(q, dark_field_circular(), Camera(), PhotoModel(bayer=True), tint=green).shape
    (16, 16, 3)
    """
    q = np.asarray(q, float)
    if model.residual_rms_rad > 0:
        q = qmul(q, residual_birefringence(q.shape[:2], model))
    linear = intensity(q, arrangement) * _vignetting(q.shape[:2], model.vignetting)
    linear = linear + model.glare
    if tint is not None:
        linear = linear[..., None] * np.asarray(tint, float)
        if model.bayer:
            linear = _bayer(linear)
    img = replace(camera, sensitivities="mono").encode(linear, seed)
    if model.jpeg_quality is not None:
        img = _jpeg(
            img if img.dtype == np.uint8 else (img // 257).astype(np.uint8), model.jpeg_quality
        )
    return img


def white_light_photograph(
    q: np.ndarray,
    spectrum: Spectrum,
    camera: Camera,
    model: PhotoModel,
    *,
    seed: int | None = 0,
    white_balance=(1.0, 1.0, 1.0),
    tone_gamma: float = 1.0,
    arrangement: Arrangement | None = None,
) -> np.ndarray:
    """A white-light colour photograph (8/16-bit) of specimen quaternions.

    :func:`optics.camera.white_light_image` in linear RGB, then what a laboratory camera
    adds (the same effects and order as :func:`photograph`): residual birefringence,
    vignetting, glare, a white balance that is not the light's, a tone curve that is not
    the camera's nominal one, shot and read noise, the encoding (sRGB for the CIE
    observer), quantisation, a Bayer mosaic and JPEG. Seeded: the same inputs give the
    same image bit for bit.

    Parameters
    ----------
    q : (rows, cols, W, 4) float array
        Path quaternions at ``spectrum.wavelengths``.
    spectrum : Spectrum
    camera : Camera
    model : PhotoModel
        Its residual birefringence (added at every wavelength as a retarder of the same
        retardation in rad), vignetting, glare, Bayer mosaic and JPEG quality.
    seed : int or None
        Seed of the camera noise.
    white_balance : (3,) floats
        Gains of the linear R, G, B channels (1, 1, 1: balanced on the light).
    tone_gamma : float
        Linear values are raised to 1 / ``tone_gamma`` before the encoding (1: the
        camera's nominal curve; 1.2: a brighter, flatter tone curve).
    arrangement : Arrangement, optional
        Default: the dark-field circular polariscope.

    Returns
    -------
    (rows, cols, 3) uint8 or uint16 array

    Raises
    ------
    ValueError
        ``tone_gamma`` not > 0, or a white balance that is not three gains > 0.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, PhotoModel, light_source
    >>> from fringekit.optics import retarder, white_light_photograph
    >>> led = light_source("LED")
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * np.linspace(0, 5, 64)[None, :, None] * k, np.pi / 8)
    >>> lab = PhotoModel(vignetting=0.2, jpeg_quality=90)
    >>> cam = Camera(full_well=2e4)
    >>> img = white_light_photograph(q, led, cam, lab, white_balance=(1.1, 1, 0.9))
    >>> img.dtype.name, img.shape
    ('uint8', (1, 64, 3))
    """
    gains = np.asarray(white_balance, float)
    if gains.shape != (3,) or not np.all(gains > 0):
        raise ValueError(f"white_balance = {white_balance!r} is not allowed; give 3 gains > 0")
    if not tone_gamma > 0:
        raise ValueError(f"tone_gamma = {tone_gamma!r} is not allowed; it must be > 0")
    q = np.asarray(q, float)
    if model.residual_rms_rad > 0:
        q = qmul(q, residual_birefringence(q.shape[:2], model)[:, :, None, :])
    linear = white_light_image(q, spectrum, camera, arrangement, linear=True)
    linear = linear * _vignetting(q.shape[:2], model.vignetting)[..., None] * gains + model.glare
    linear = np.clip(linear, 0.0, None) ** (1.0 / tone_gamma)
    if model.bayer:
        linear = _bayer(linear)
    img = camera.encode(linear, seed)
    if model.jpeg_quality is not None:
        img = _jpeg(
            img if img.dtype == np.uint8 else (img // 257).astype(np.uint8), model.jpeg_quality
        )
    return img


def indent_field(rows: int, cols: int, core: float = 0.06):
    """A specimen of known order for photograph tests and benchmarks.

    A smooth indent-like field, N = 0.3 + 2.6 exp(-(r / 0.3)^2) with r the distance from
    the image centre over the shorter side (0.3 at the border, 2.9 in the middle),
    principal axes radial. At camera size the order changes by 0.002-0.005 fringe per
    pixel in the far field.

    Parameters
    ----------
    rows, cols : int
        Image shape (px).
    core : float
        Radius of the contact zone without data, as a fraction of the shorter side.

    Returns
    -------
    order : (rows, cols) float array
        Fringe order.
    q : (rows, cols, 4) float array
        Quaternions of the retarder of each pixel.
    mask : (rows, cols) bool array
        r > ``core``.

    Examples
    --------
    >>> from fringekit.optics import indent_field
    >>> order, q, mask = indent_field(64, 64)
    >>> round(float(order.max()), 2), round(float(order[0, 0]), 2), q.shape, int((~mask).sum())
    (2.9, 0.31, (64, 64, 4), 52)
    """
    r, c = np.mgrid[:rows, :cols].astype(float)
    s = min(rows, cols)
    x, y = (c - (cols - 1) / 2) / s, ((rows - 1) / 2 - r) / s
    rad = np.hypot(x, y)
    order = 0.3 + 2.6 * np.exp(-((rad / 0.3) ** 2))
    return order, retarder(2 * np.pi * order, np.arctan2(y, x)), rad > core


def crack_tip_field(rows: int, cols: int, k: float, far_order: float, tip_rc):
    """A mode-I crack tip in a plate in tension, of known order, for photograph tests.

    The near-tip field of Westergaard (*J. Appl. Mech.* 6, 1939) in Irwin's form (*J.
    Appl. Mech.* 24, 1957) with Irwin's remote stress sigma_0x (Dally and Riley,
    *Experimental Stress Analysis*, 4th ed., ch. 7, the two-parameter method): with
    A = K_I / sqrt(2 pi r),

        sigma_y - sigma_x = A sin(theta) sin(3 theta / 2) - sigma_0x,
        2 tau_xy = A sin(theta) cos(3 theta / 2),

    so sigma_1 - sigma_2 = K_I sin(theta) / sqrt(2 pi r) near the tip and |sigma_0x| far
    from it. Here in fringe units, sigma_0x = -``far_order`` (a plate pulled across the
    crack): dark-field fringes close in two loops on each side of the tip, one order per
    loop inwards, and fall to the far-field order ahead of the tip and along the crack.

    Parameters
    ----------
    rows, cols : int
        Image shape (px).
    k : float
        K_I t / (f_sigma sqrt(2 pi)) in fringe sqrt(px): the order is k sin(theta) /
        sqrt(r) near the tip (r in px).
    far_order : float
        Far-field order |sigma_0x| t / f_sigma (fringe).
    tip_rc : (row, col)
        The crack tip (px); the crack runs from it to the left (decreasing col).

    Returns
    -------
    order : (rows, cols) float array
        Fringe order (very large at the tip pixel).
    q : (rows, cols, 4) float array
        Quaternions of the retarder of each pixel.

    Examples
    --------
    >>> from fringekit.optics import crack_tip_field
    >>> order, q = crack_tip_field(64, 64, 5.0, 0.5, (32, 32))
    >>> round(float(order[32, 60]), 3), round(float(order[22, 32]), 2)  # ahead; above the tip
    (0.5, 1.97)
    """
    r, c = np.mgrid[:rows, :cols].astype(float)
    x, y = c - tip_rc[1], tip_rc[0] - r
    rad = np.maximum(np.hypot(x, y), 0.5)
    th = np.arctan2(y, x)
    amp = k / np.sqrt(rad)
    diff = amp * np.sin(th) * np.sin(1.5 * th) + far_order  # sigma_y - sigma_x, fringe
    shear = amp * np.sin(th) * np.cos(1.5 * th)  # 2 tau_xy, fringe
    order = np.hypot(diff, shear)
    return order, retarder(2 * np.pi * order, 0.5 * np.arctan2(shear, -diff))
