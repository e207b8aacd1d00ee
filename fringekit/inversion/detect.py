"""Where the indenters of an image are, before any fit (``fringekit invert``, step 1).

A no-data disc (the contact zone ``predict`` marks with the no-data level) is an
indenter. Elsewhere fringes crowd about each indenter: the local energy of the image
gradient, smoothed over 0.6 mm, peaks there. Peaks count when above a noise floor
(``DETECT_SNR`` times the gradient energy of the image noise, Immerkaer's estimate) and
``DETECT_REL`` of the strongest, and when the energy dips by ``DETECT_DIP`` between them
and every stronger one (one indenter's ridge is not a second indenter).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.feature import peak_local_max

from fringekit._memory import gaussian_bytes
from fringekit.analysis import image_noise_sd as image_noise
from fringekit.inversion.model import ImageModel

__all__ = [
    "DETECT_DIP",
    "DETECT_REL",
    "DETECT_SNR",
    "MIN_SEPARATION_MM",
    "SMOOTH_MM",
    "axis_separation_mm",
    "detect",
    "detection_bytes",
    "far_from",
    "noise_sd",
]

DETECT_SNR = 30.0
DETECT_REL = 0.04
#: Two peaks are two indenters when the energy between them dips by this fraction.
DETECT_DIP = 0.2
#: Candidates closer than this (mm) are one (discs; a fringe-energy peak must also be a
#: sphere diameter from every disc and stronger peak: two spheres' axes cannot be closer).
MIN_SEPARATION_MM = 2.0
#: The gradient energy is smoothed over this distance (mm, the Gaussian's sd).
SMOOTH_MM = 0.6


def _energy(model: ImageModel, smooth_px: float) -> np.ndarray:
    """Smoothed gradient energy (rows, cols) of the measured image, no-data discs filled
    with their rim's energy."""
    rows, cols = model.grid.shape
    img = model.measured.reshape(rows, cols, -1)
    use = model.usable.reshape(rows, cols)
    e = np.zeros((rows, cols))
    for c in range(img.shape[-1]):  # channels (1, 3 or 6)
        gy, gx = np.gradient(img[..., c])
        e += gx**2 + gy**2
    good = ndimage.binary_erosion(use, iterations=2)
    e = np.where(good, e, 0.0)
    holes = ~use
    if holes.any():
        rim = ndimage.grey_dilation(e, size=5)
        lab, n = ndimage.label(holes)
        top = ndimage.maximum(rim, lab, np.arange(1, n + 1)) if n else []
        e = np.where(holes, np.concatenate([[0.0], top])[lab], e)
    w = ndimage.gaussian_filter(np.where(good | holes, 1.0, 0.0), smooth_px)
    return ndimage.gaussian_filter(e, smooth_px) / np.maximum(w, 1e-6)


def detection_bytes(shape: tuple[int, int], pixel_mm: float) -> float:
    """Memory (bytes) of :func:`detect` on every 2nd pixel of an image of ``shape`` at
    ``pixel_mm``: the Gaussian smoothing of the gradient energy over SMOOTH_MM
    (:func:`fringekit._memory.gaussian_bytes`) and 8 float64 images (the energy, its two
    gradients, the weights and their smoothed copies)."""
    n = (shape[0] // 2 + 1) * (shape[1] // 2 + 1)
    return gaussian_bytes(SMOOTH_MM / (2 * pixel_mm), n) + 8 * 8 * n


def noise_sd(model: ImageModel) -> float:
    """Noise sd of the measured image (Immerkaer's estimator, the channels' median), at
    least the quantisation noise of 8 bits; a channel's censored pixels (clipped at
    black, without noise) are left out of its estimate."""
    rows, cols = model.grid.shape
    img = model.measured.reshape(rows, cols, -1)
    use = np.broadcast_to(model.usable[:, None], model.measured.shape)
    if model.censored is not None:
        use = use & ~model.censored
    use = use.reshape(img.shape)
    sig = [image_noise(img[..., c], use[..., c]) for c in range(img.shape[-1])]
    return float(max(np.median(sig), 1.0 / (255 * np.sqrt(12))))


def _separated(e: np.ndarray, peaks: np.ndarray, min_px: float) -> list[int]:
    """Peaks (strongest first) kept when at least ``min_px`` from every kept one and the
    energy dips by DETECT_DIP of the weaker peak on the straight line between them (one
    indenter's ridge is not a second indenter)."""
    kept: list[int] = []
    t = np.linspace(0.0, 1.0, 64)[:, None]
    for i, p in enumerate(peaks):
        ok = True
        for j in kept:
            q = peaks[j]
            if np.hypot(*(p - q)) < min_px:
                ok = False
                break
            line = np.rint(p[None] * (1 - t) + q[None] * t).astype(int)
            if e[line[:, 0], line[:, 1]].min() > (1 - DETECT_DIP) * e[p[0], p[1]]:
                ok = False
                break
        if ok:
            kept.append(i)
    return kept


def detect(model: ImageModel, noise: float, exclude=()) -> np.ndarray:
    """Candidate indenter positions (k, 2) (mm), strongest first; ``exclude`` (m, 2) mm
    positions already taken (discs within MIN_SEPARATION_MM of them, and fringe-energy
    peaks within a sphere diameter, are dropped)."""
    px = model.grid.pixel_size * 1e3
    taken = np.reshape(np.asarray(exclude, float), (-1, 2))
    discs = far_from(_discs(model), taken)
    taken = np.concatenate([taken, discs])
    e = _energy(model, smooth_px=SMOOTH_MM / px)
    floor = DETECT_SNR * noise**2 * model.measured.shape[1]
    peaks = peak_local_max(
        e,
        min_distance=max(1, int(0.5 * MIN_SEPARATION_MM / px)),
        threshold_abs=floor,
        threshold_rel=DETECT_REL,
        exclude_border=False,
    )
    apart = axis_separation_mm(model.lib)
    peaks = peaks[_separated(e, peaks, apart / px)]
    x, y = model.grid.pixel_to_xy(peaks[:, 0], peaks[:, 1])
    pos = np.column_stack([x, y]) * 1e3
    return np.concatenate([discs, far_from(pos, taken, apart)])


def axis_separation_mm(lib) -> float:
    """The closest two indenter axes can be (mm): a sphere diameter of the library, at
    least MIN_SEPARATION_MM (two spheres cannot overlap)."""
    return max(MIN_SEPARATION_MM, min(lib.diameters_mm))


def far_from(pos, taken, apart: float = MIN_SEPARATION_MM) -> np.ndarray:
    """The positions (k, 2) (mm) at least ``apart`` (mm) from every taken one (m, 2) (mm).

    Examples
    --------
    >>> far_from([[0.0, 0.0], [5.0, 0.0]], [[1.0, 0.0]], apart=3.5).tolist()
    [[5.0, 0.0]]
    """
    pos = np.reshape(np.asarray(pos, float), (-1, 2))
    taken = np.reshape(np.asarray(taken, float), (-1, 2))
    if not len(taken) or not len(pos):
        return pos
    d = np.hypot(*(pos[:, None, :] - taken[None]).transpose(2, 0, 1))
    return pos[d.min(axis=1) >= apart]


def _discs(model: ImageModel) -> np.ndarray:
    """Centres (k, 2) (mm) of the no-data discs of the image (pixels at the no-data fill
    level: where ``predict`` marks an indenter's contact), at least 12 pixels each."""
    marked = ~model.usable if model.nodata is None else model.nodata
    holes = marked.reshape(model.grid.shape)
    lab, n = ndimage.label(holes)
    if not n:
        return np.zeros((0, 2))
    idx = np.arange(1, n + 1)
    big = idx[ndimage.sum(holes, lab, idx) >= 12]
    if not len(big):
        return np.zeros((0, 2))
    rc = np.array(ndimage.center_of_mass(holes, lab, big))
    x, y = model.grid.pixel_to_xy(rc[:, 0], rc[:, 1])
    return np.column_stack([x, y]) * 1e3
