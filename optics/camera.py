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
    """Relative spectral power S (W,) sampled at wavelengths (W,) (m)."""

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
    """A colour-science light source resampled to ``wavelengths`` (m).

    ``name``: ``"D65"`` (daylight), ``"A"`` (halogen/tungsten, CIE A) or ``"LED"``
    (CIE LED-B3, a phosphor-converted white LED, CIE 15:2018). Default wavelengths:
    31 samples 400..700 nm.
    """
    import colour  # lazy: colour-science takes ~0.7 s to load; only white light needs it

    if name not in _SOURCES:
        raise ValueError(f"light source {name!r} is not allowed; use one of {sorted(_SOURCES)}")
    lam = np.linspace(400e-9, 700e-9, 31) if wavelengths is None else np.asarray(wavelengths)
    sd = colour.SDS_ILLUMINANTS[_SOURCES[name][1]]
    return Spectrum(lam, np.asarray(sd[lam * 1e9], float), name)


@dataclass(frozen=True)
class Camera:
    """Camera response.

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
    """RGB image (rows, cols, 3) of quaternions q (rows, cols, W, 4) at spectrum.wavelengths.

    Returns encoded integers (``camera.bit_depth``), or linear floats when ``linear``.
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
    map to sRGB primaries under the source white (``_to_rgb_linear``, linear in its input,
    applied here to the unit channel vectors)."""
    qc = camera.responses(spectrum.wavelengths)  # (W, 3)
    wq = (spectrum.power * spectrum.weights)[:, None] * qc
    return (wq / wq.sum(0)) @ _to_rgb_linear(np.eye(3), spectrum, camera)


def monochrome_image(
    q: np.ndarray, arrangement: Arrangement, camera: Camera, *, seed: int | None = 0
) -> np.ndarray:
    """Grey image (rows, cols) for quaternions at one wavelength (rows, cols, 4)."""
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

    Returns
    -------
    orders : (n,) fringe orders 0..max_order
    rgb : (n, 3) linear RGB in [0, 1] (no noise, no quantisation)
    """
    orders = np.linspace(0.0, max_order, n)
    delta = 2 * np.pi * orders[:, None] * law.relative_retardation(spectrum.wavelengths)[None, :]
    q = retarder(delta, np.full_like(delta, np.pi / 8))
    rgb = white_light_image(q, spectrum, camera, arrangement, linear=True)
    return orders, np.clip(rgb, 0, 1)


def write_image(path, image: np.ndarray) -> None:
    """Write an 8/16-bit grey or RGB image as PNG or TIFF (by suffix)."""
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"image dtype {img.dtype} is not allowed; use uint8 or uint16")
    if str(path).lower().endswith(".png") and img.dtype == np.uint16 and img.ndim == 3:
        raise ValueError(
            f"{path}: 16-bit RGB PNG is not supported by the PNG writer; use a .tif path "
            "(16-bit grey PNG and 8-bit RGB PNG are fine)"
        )
    iio.imwrite(path, img)
