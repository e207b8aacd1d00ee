"""Light sources, cameras and image formation (monochrome and white light).

White light (``docs/theory.md``, "White light"): channel value
I_c = sum S(lam) Q_c(lam) T(lam) w(lam) / sum S(lam) Q_c(lam) w(lam), with T the
polariscope transmittance from the Jones matrix at each wavelength and w the width of
the wavelength cell each sample stands for (:attr:`Spectrum.weights`). Spectra, colour-matching
functions and camera sensitivities come from colour-science datasets.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import imageio.v3 as iio
import numpy as np

from .jones import retarder
from .polariscope import Arrangement, dark_field_circular, intensity
from .stressoptic import StressOpticLaw

__all__ = [
    "Spectrum",
    "light_source",
    "Camera",
    "white_light_image",
    "white_light_matrix",
    "monochrome_image",
    "colour_chart",
    "write_image",
]

_SOURCES = {
    "D65": ("illuminant", "D65"),
    "A": ("illuminant", "A"),
    "LED": ("illuminant", "LED-B3"),
}


@dataclass(frozen=True)
class Spectrum:
    """Relative spectral power of a light source, sampled at wavelengths.

    Parameters
    ----------
    wavelengths : (W,) float array
        Sample wavelengths (m), ascending.
    power : (W,) float array
        Relative spectral power S (any unit: images are normalised by the source white).
    name : str
        Label for reports.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import Spectrum
    >>> flat = Spectrum(np.array([500e-9, 550e-9, 600e-9]), np.ones(3), "flat")
    >>> (flat.weights * 1e9).round(6).tolist()  # quadrature weights, nm
    [50.0, 50.0, 50.0]
    """

    wavelengths: np.ndarray
    power: np.ndarray
    name: str = ""

    @property
    def weights(self) -> np.ndarray:
        """(W,) quadrature weights (m) for sums over wavelength: the width of the cell
        each sample stands for (half-way to its neighbours; the end cells as wide as
        their only neighbour gap). Equal on an even grid, so sums there are unchanged;
        on a wavenumber grid (optics.stressoptic.wavenumber_grid) they grow with lam."""
        lam = np.asarray(self.wavelengths, float)
        if lam.size < 2:
            return np.ones_like(lam)
        gap = np.diff(lam)
        return 0.5 * (np.concatenate([gap[:1], gap]) + np.concatenate([gap, gap[-1:]]))


def light_source(name: str = "LED", wavelengths=None) -> Spectrum:
    """A colour-science light source resampled to ``wavelengths``.

    Parameters
    ----------
    name : {"D65", "A", "LED"}
        ``"D65"`` (daylight), ``"A"`` (halogen/tungsten, CIE A) or ``"LED"`` (CIE LED-B3,
        a phosphor-converted white LED, CIE 15:2018).
    wavelengths : (W,) float array, optional
        Wavelengths (m); default 31 samples 400..700 nm.

    Returns
    -------
    Spectrum

    Raises
    ------
    ValueError
        An unknown source name.

    Examples
    --------
    >>> from fringekit.optics import light_source
    >>> led = light_source("LED")
    >>> led.name, led.wavelengths.shape, round(float(led.wavelengths[0]) * 1e9)
    ('LED', (31,), 400)
    """
    import colour  # lazy: colour-science takes ~0.7 s to load; only white light needs it

    if name not in _SOURCES:
        raise ValueError(f"light source {name!r} is not allowed; use one of {sorted(_SOURCES)}")
    lam = np.linspace(400e-9, 700e-9, 31) if wavelengths is None else np.asarray(wavelengths)
    sd = colour.SDS_ILLUMINANTS[_SOURCES[name][1]]
    return Spectrum(lam, np.asarray(sd[lam * 1e9], float), name)


@dataclass(frozen=True)
class Camera:
    """Camera response: spectral sensitivities, exposure, noise and encoding.

    Parameters
    ----------
    sensitivities : str
        ``"CIE1931"`` (CIE 1931 2-degree observer, then XYZ -> sRGB, with the source
        white mapped to sRGB white) or the name of a camera in
        ``colour.MSDS_CAMERA_SENSITIVITIES`` (raw RGB, white-balanced on the source).
    exposure : float
        Scale from transmittance to full scale (1 = a fully transmitting pixel saturates).
        Default 0.9: the brightest fringes stay below saturation, as an experimenter
        exposes.
    gamma : float
        Encoding exponent applied to linear values (1 = linear); ignored for sRGB,
        which uses the sRGB transfer function.
    full_well : float
        Electrons at full scale (shot noise); 0 disables shot noise.
    read_noise : float
        Read noise, electrons RMS.
    bit_depth : {8, 16}
        Bits per channel of the encoded image.

    Raises
    ------
    ValueError
        A bit depth other than 8 or 16, an exposure that is not > 0, or read noise
        without a full well.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import Camera
    >>> cam = Camera(sensitivities="mono", bit_depth=8)
    >>> cam.encode(np.array([0.0, 0.5, 1.0])).tolist()  # exposure 0.9
    [0, 115, 230]
    >>> Camera(full_well=2e4, read_noise=10.0).encode(np.full(3, 0.5), seed=1).dtype
    dtype('uint8')
    """

    sensitivities: str = "CIE1931"
    exposure: float = 0.9
    gamma: float = 1.0
    full_well: float = 0.0
    read_noise: float = 0.0
    bit_depth: int = 8

    def __post_init__(self) -> None:
        if self.bit_depth not in (8, 16):
            raise ValueError(f"bit_depth = {self.bit_depth!r} is not allowed; use 8 or 16")
        if not self.exposure > 0:
            raise ValueError(f"exposure = {self.exposure!r} is not allowed; it must be > 0")
        if self.read_noise > 0 and not self.full_well > 0:
            raise ValueError(
                f"read_noise = {self.read_noise!r} e- needs full_well > 0 (electrons at full "
                f"scale) to be converted to grey levels; got full_well = {self.full_well!r}"
            )

    def responses(self, wavelengths) -> np.ndarray:
        """(W, 3) channel sensitivities at wavelengths (m)."""
        import colour  # lazy: colour-science takes ~0.7 s to load; only white light needs it

        nm = np.asarray(wavelengths) * 1e9
        if self.sensitivities == "CIE1931":
            msds = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
        elif self.sensitivities in colour.MSDS_CAMERA_SENSITIVITIES:
            msds = colour.MSDS_CAMERA_SENSITIVITIES[self.sensitivities]
        else:
            raise ValueError(
                f"camera sensitivities {self.sensitivities!r} not known; use 'CIE1931' or one "
                f"of {sorted(colour.MSDS_CAMERA_SENSITIVITIES)}"
            )
        lo, hi = msds.wavelengths[0], msds.wavelengths[-1]
        vals = msds[np.clip(nm, lo, hi)]
        return np.where(((nm >= lo) & (nm <= hi))[:, None], vals, 0.0)

    def encode(self, linear: np.ndarray, seed: int | None = 0) -> np.ndarray:
        """Exposure, noise, transfer function and quantisation of linear values."""
        v = np.asarray(linear, float) * self.exposure
        rng = np.random.default_rng(seed)
        if self.full_well > 0:
            e = rng.poisson(np.clip(v, 0, None) * self.full_well).astype(float)
            v = e / self.full_well
        if self.read_noise > 0:
            v = v + rng.normal(0.0, self.read_noise / self.full_well, v.shape)
        v = np.clip(v, 0.0, 1.0)
        if self.sensitivities == "CIE1931" and v.ndim >= 1 and v.shape[-1] == 3:
            import colour  # lazy: colour-science takes ~0.7 s to load; only white light needs it

            v = np.clip(colour.cctf_encoding(v, function="sRGB"), 0, 1)
        elif self.gamma != 1.0:
            v = v ** (1.0 / self.gamma)
        top = 2**self.bit_depth - 1
        return np.round(v * top).astype(np.uint8 if self.bit_depth == 8 else np.uint16)


def _to_rgb_linear(channels: np.ndarray, spectrum: Spectrum, camera: Camera) -> np.ndarray:
    """Map normalised channel values to linear RGB (sRGB primaries for the CIE observer)."""
    if camera.sensitivities != "CIE1931":
        return channels
    import colour  # lazy: colour-science takes ~0.7 s to load; only white light needs it

    q = camera.responses(spectrum.wavelengths)
    white = ((spectrum.power * spectrum.weights)[:, None] * q).sum(0)
    xyz = channels * white / white[1]  # XYZ with the source white at Y = 1
    xy_w = colour.XYZ_to_xy(white / white[1])
    return colour.XYZ_to_RGB(
        xyz,
        colour.RGB_COLOURSPACES["sRGB"],
        illuminant=xy_w,
        chromatic_adaptation_transform="CAT02",
        apply_cctf_encoding=False,
    )


def white_light_image(
    q: np.ndarray,
    spectrum: Spectrum,
    camera: Camera,
    arrangement: Arrangement | None = None,
    *,
    seed: int | None = 0,
    linear: bool = False,
) -> np.ndarray:
    """RGB image of a specimen in white light.

    Parameters
    ----------
    q : (rows, cols, W, 4) float array
        Path quaternions at ``spectrum.wavelengths``.
    spectrum : Spectrum
    camera : Camera
    arrangement : Arrangement, optional
        Default: the dark-field circular polariscope.
    seed : int or None
        Seed of the camera noise.
    linear : bool
        Return linear floats instead of encoded integers.

    Returns
    -------
    (rows, cols, 3) array
        Encoded integers (``camera.bit_depth``), or linear floats when ``linear``.

    Examples
    --------
    Zero and one fringe at 575 nm in white light: black, and a colour:

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, light_source, retarder
    >>> from fringekit.optics import white_light_image
    >>> led = light_source("LED")
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)  # (31,)
    >>> q = retarder(2 * np.pi * np.array([[0.0], [1.0]])[None] * k, np.pi / 8)  # (1, 2, 31, 4)
    >>> white_light_image(q, led, Camera()).tolist()
    [[[0, 0, 0], [47, 35, 196]]]
    """
    arrangement = arrangement or dark_field_circular()
    t = intensity(q, arrangement)  # (rows, cols, W)
    m = white_light_matrix(spectrum, camera)
    rgb = (t.reshape(-1, t.shape[-1]) @ m).reshape(t.shape[:-1] + (3,))
    return rgb if linear else camera.encode(rgb, seed)


def white_light_matrix(spectrum: Spectrum, camera: Camera) -> np.ndarray:
    """(W, 3): linear RGB = (per-wavelength transmitted intensity, W) @ this matrix.

    The source spectrum and quadrature weights times the channel sensitivities, each
    channel normalised to 1 for full transmission, then (for the CIE observer) the linear
    map to sRGB primaries under the source white (applied to the unit channel vectors).

    Parameters
    ----------
    spectrum : Spectrum
    camera : Camera

    Returns
    -------
    (W, 3) float array

    Examples
    --------
    Full transmission at every wavelength is white:

    >>> from fringekit.optics import Camera, light_source, white_light_matrix
    >>> m = white_light_matrix(light_source("D65"), Camera())
    >>> m.shape, m.sum(axis=0).round(3).tolist()
    ((31, 3), [1.0, 1.0, 1.0])
    """
    qc = camera.responses(spectrum.wavelengths)  # (W, 3)
    wq = (spectrum.power * spectrum.weights)[:, None] * qc
    return (wq / wq.sum(0)) @ _to_rgb_linear(np.eye(3), spectrum, camera)


def monochrome_image(
    q: np.ndarray, arrangement: Arrangement, camera: Camera, *, seed: int | None = 0
) -> np.ndarray:
    """Grey image of a specimen at one wavelength.

    Parameters
    ----------
    q : (rows, cols, 4) float array
        Path quaternions.
    arrangement : Arrangement
    camera : Camera
        Its exposure, noise, gamma and bit depth apply (not the sRGB curve).
    seed : int or None
        Seed of the camera noise.

    Returns
    -------
    (rows, cols) uint8 or uint16 array

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import Camera, dark_field_circular, monochrome_image, retarder
    >>> q = retarder(np.array([[0.0, np.pi]]), 0.0)  # zero and half a fringe
    >>> monochrome_image(q, dark_field_circular(), Camera()).tolist()
    [[0, 230]]
    """
    # any name but "CIE1931" encodes with ``gamma`` instead of the sRGB curve
    return replace(camera, sensitivities="mono").encode(intensity(q, arrangement), seed)


def colour_chart(
    law: StressOpticLaw,
    spectrum: Spectrum,
    camera: Camera,
    *,
    max_order: float = 4.0,
    n: int = 401,
    arrangement: Arrangement | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Synthetic RGB calibration table: colour of a uniform retarder vs fringe order.

    Fringe order N at the law's reference wavelength; at wavelength lam the retardation
    is 2 pi N (k(lam) / k(lam_ref)) with k = 2 pi C / lam (dispersion included).

    Parameters
    ----------
    law : StressOpticLaw
    spectrum : Spectrum
    camera : Camera
    max_order : float
        Highest order of the table.
    n : int
        Rows.
    arrangement : Arrangement, optional
        Default: the dark-field circular polariscope.

    Returns
    -------
    orders : (n,) float array
        Fringe orders 0..max_order.
    rgb : (n, 3) float array
        Linear RGB in [0, 1] (no noise, no quantisation).

    Examples
    --------
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source
    >>> orders, rgb = colour_chart(PSM4_ASSUMED, light_source("LED"), Camera(), max_order=2.0, n=5)
    >>> orders.tolist()
    [0.0, 0.5, 1.0, 1.5, 2.0]
    >>> rgb.round(2).tolist()[:3]  # black, white, the violet of the first order
    [[0.0, 0.0, 0.0], [0.99, 1.0, 0.81], [0.03, 0.02, 0.61]]
    """
    orders = np.linspace(0.0, max_order, n)
    delta = 2 * np.pi * orders[:, None] * law.relative_retardation(spectrum.wavelengths)[None, :]
    q = retarder(delta, np.full_like(delta, np.pi / 8))
    rgb = white_light_image(q, spectrum, camera, arrangement, linear=True)
    return orders, np.clip(rgb, 0, 1)


def write_image(path, image: np.ndarray) -> None:
    """Write an 8/16-bit grey or RGB image as PNG or TIFF (by suffix).

    Parameters
    ----------
    path : str or os.PathLike
        ``.png``, ``.tif`` or ``.tiff``.
    image : (rows, cols) or (rows, cols, 3) uint8 or uint16 array

    Returns
    -------
    None

    Raises
    ------
    ValueError
        Another dtype, or a 16-bit RGB PNG (write a TIFF).

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from fringekit.analysis import load_image
    >>> from fringekit.optics import write_image
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_image(f"{d}/grey.png", np.array([[0, 65535], [1000, 2000]], np.uint16))
    ...     frame = load_image(f"{d}/grey.png")
    >>> frame.bit_depth, float(frame.data.max())
    (16, 1.0)
    """
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"image dtype {img.dtype} is not allowed; use uint8 or uint16")
    if str(path).lower().endswith(".png") and img.dtype == np.uint16 and img.ndim == 3:
        raise ValueError(
            f"{path}: 16-bit RGB PNG is not supported by the PNG writer; use a .tif path "
            "(16-bit grey PNG and 8-bit RGB PNG are fine)"
        )
    iio.imwrite(path, img)
