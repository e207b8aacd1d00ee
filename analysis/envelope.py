"""Normalising one monochrome fringe photograph: intensity -> sin^2 of the retardation.

Behind a circular polariscope in monochromatic light the dark-field intensity is
I = I_b + I_0 sin^2(pi N) and the bright-field one I = I_b + I_0 cos^2(pi N) (Dally and
Riley, *Experimental Stress Analysis*, 4th ed., ch. 6). ``I_0`` carries the illumination
(vignetting, uneven lighting) and ``I_b`` the background (glare, stray light); both vary
slowly over a photograph, and fringe contrast ``I_0`` fades where the light is weak. The
normalised intensity u = (I - I_b) / I_0 = sin^2(pi N) (dark field) is what the order
follows from.

Two ways to get I_b and I_0 (:func:`normalised_intensity`):

- a **flat field**: an image of the same light without the specimen's retardation (a
  bright-field image of the unloaded specimen, or the sum of the dark- and bright-field
  images) gives I_0 pixel by pixel;
- the **envelope** of the fringes themselves, the usual way when only one photograph
  exists (Ramesh, *Digital Photoelasticity*, Springer 2000, ch. 4: fringe-centre intensities
  as local extremes): the intensity on the centre lines of dark fringes samples I_b, on
  bright fringes I_b + I_0, and a smooth surface through each set (uniform light,
  a tilt and the radial fall-off of vignetting) gives both everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage.morphology import remove_small_holes, remove_small_objects

__all__ = [
    "Envelope",
    "band_labels",
    "band_neighbours",
    "fit_envelope",
    "flat_field_envelope",
    "smooth_surface",
    "unresolved",
]


@dataclass(frozen=True)
class Envelope:
    """Background and fringe amplitude of a photograph.

    Attributes
    ----------
    low : (rows, cols) float - I_b, the intensity of a whole-order dark fringe (0-1 scale)
    high : (rows, cols) float - I_b + I_0, the intensity of a half-order bright fringe
    method : str - "flat field", "fringe envelope" or "percentiles" (too few fringes)
    samples : int - fringe-centre pixels the envelope was fitted to (0 for a flat field)
    residual : float - RMS misfit of the fringe-centre intensities to the surfaces,
        relative to the amplitude (0 for a flat field)
    reach : (rows, cols) float or None - distance to the nearest fringe-centre sample
        over the half diagonal of the image: where the surfaces extrapolate
    sampled : tuple of "low", "high" - which surfaces came from fringe centres (the
        others are percentiles of the image; a flat field gives both)
    """

    low: np.ndarray
    high: np.ndarray
    method: str
    samples: int = 0
    residual: float = 0.0
    reach: np.ndarray | None = None
    sampled: tuple = ()

    def sd(self) -> np.ndarray | float:
        """1-sigma error of u from the envelope: the misfit at the samples, growing
        linearly to 5 times that at half the image diagonal from the nearest sample."""
        if self.reach is None:
            return self.residual
        return self.residual * (1.0 + 8.0 * self.reach)

    def normalise(self, image: np.ndarray) -> np.ndarray:
        """u = (I - low) / (high - low), clipped to [0, 1]; NaN where the amplitude is 0."""
        amp = self.high - self.low
        with np.errstate(invalid="ignore", divide="ignore"):
            u = (image - self.low) / np.where(amp > 0, amp, np.nan)
        return np.clip(u, 0.0, 1.0)


#: Largest bright or dark island (px) removed as noise: one 8 x 8 JPEG block (on
#: photographs of camera size, noise and compression make islands of that size where
#: the order stays near a quarter fringe from a centre).
MIN_BAND_PX = 64


def band_labels(u: np.ndarray, mask: np.ndarray, min_px: int = MIN_BAND_PX, cut_dense: bool = True):
    """Bright (u > 0.5) and dark bands of a normalised image, islands < ``min_px`` removed,
    and (``cut_dense``) the fringes too dense to resolve cut out.

    Returns (labels (rows, cols) int, 0 outside ``mask`` and on unresolved fringes; bright
    (n_bands + 1,) bool per label, index 0 unused). Dark bands are 4-connected and bright
    bands 8-connected (the usual pairing of digital topology), so two bands that meet are
    always one bright and one dark. Where three bands meet within 3 x 3 pixels (a fringe
    narrower than about two pixels: the fringes converge on a singular point such as a
    crack tip or a load point) the pixels, and :data:`DENSE_MARGIN` px about them, belong
    to no band: there every fringe touches every other one, and bands that are orders
    apart would join into one.
    """
    bright = np.nan_to_num(u, nan=0.0) > 0.5
    bright = remove_small_objects(bright & mask, max_size=min_px) | (bright & ~mask)
    bright = remove_small_holes(bright | ~mask, max_size=min_px) & mask
    labels, is_bright = _label(bright, mask)
    if not cut_dense:
        return labels, is_bright
    dense = unresolved(labels) | _thin(bright, mask)
    if dense.any():
        labels, is_bright = _label(bright, mask & ~dense)
    return labels, is_bright


#: Margin (px) about unresolved fringes that belongs to no band either.
DENSE_MARGIN = 2


def _label(bright, mask):
    lab_b, nb = ndimage.label(bright & mask, structure=np.ones((3, 3)))
    lab_d, nd = ndimage.label(mask & ~bright)
    labels = np.where(bright & mask, lab_b + nd, lab_d)
    is_bright = np.zeros(nb + nd + 1, bool)
    is_bright[nd + 1 :] = True
    return labels, is_bright


def _thin(bright, mask):
    """Pixels within 3 x 3 of which every pixel touches the other kind (bright / dark):
    bands at most two pixels wide on both sides, a fringe period of about four pixels."""
    dt = np.where(
        bright,
        ndimage.distance_transform_edt(~(mask & ~bright)),
        ndimage.distance_transform_edt(~(mask & bright)),
    )
    thin = ndimage.maximum_filter(np.where(mask, dt, 0), size=3) <= 1.0
    thin &= mask
    if thin.any():
        thin = ndimage.binary_dilation(thin, iterations=DENSE_MARGIN)
    return thin & mask


def unresolved(labels: np.ndarray) -> np.ndarray:
    """Pixels whose 3 x 3 neighbourhood holds three or more bands (label > 0), grown by
    :data:`DENSE_MARGIN` px: fringes denser than the pixels.

    Parameters
    ----------
    labels : (rows, cols) int array
        Band labels, 0 for no band (:func:`band_labels`).

    Returns
    -------
    (rows, cols) bool array

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis.envelope import unresolved
    >>> bands = np.repeat([[1, 1, 1, 2, 3, 3, 3, 3, 3, 3]], 3, axis=0)  # band 2: 1 px wide
    >>> unresolved(bands)[1].astype(int).tolist()
    [0, 1, 1, 1, 1, 1, 0, 0, 0, 0]
    """
    padded = np.pad(labels, 1)
    rows, cols = labels.shape
    win = np.stack(
        [padded[i : i + rows, j : j + cols] for i in range(3) for j in range(3)], axis=-1
    )
    win.sort(axis=-1)
    distinct = (win[..., 0] > 0).astype(int) + np.sum(
        (win[..., 1:] != win[..., :-1]) & (win[..., 1:] > 0), axis=-1
    )
    dense = distinct >= 3
    if DENSE_MARGIN and dense.any():
        dense = ndimage.binary_dilation(dense, iterations=DENSE_MARGIN)
    return dense & (labels > 0)


def band_neighbours(labels: np.ndarray) -> np.ndarray:
    """(k, 2) int: the distinct pairs (a < b) of labels that touch (4-neighbours)."""
    pairs = []
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1, :], labels[1:, :])):
        touch = (a != b) & (a > 0) & (b > 0)
        pairs.append(np.stack([np.minimum(a, b)[touch], np.maximum(a, b)[touch]], -1))
    p = np.concatenate(pairs)
    return np.unique(p, axis=0) if len(p) else np.zeros((0, 2), int)


def smooth_surface(rows, cols, values, shape, degree: int = 2) -> tuple[np.ndarray, float]:
    """Least-squares illumination surface through scattered samples.

    ``degree`` 2: a + b x + c y + e (x^2 + y^2) about the image centre - uniform light, a
    tilt, and the radial fall-off of vignetting (the leading term of the cos^4 law); a
    general quadratic ran away where it extrapolated beyond the fringe centres, which
    often cluster about the load. ``degree`` 0: a constant. Two passes: samples more than
    3 robust standard deviations off the first fit (a fringe centre mislocated by noise)
    are dropped. Returns (surface (rows, cols), RMS residual of the kept samples)."""
    h, w = shape
    scale = max(h, w) / 2

    def design(r, c):
        y, x = (np.asarray(r, float) - h / 2) / scale, (np.asarray(c, float) - w / 2) / scale
        if degree == 0:
            return np.ones((x.size, 1))
        return np.stack([np.ones_like(x), x, y, x * x + y * y], -1)

    A, v = design(rows, cols), np.asarray(values, float)
    keep = np.ones(len(v), bool)
    for _ in range(2):
        coef = np.linalg.lstsq(A[keep], v[keep], rcond=None)[0]
        res = v - A @ coef
        mad = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep]))) + 1e-12
        near = np.abs(res) <= 3 * mad
        # noise-free samples (synthetic images) tie: over half of them equal, the MAD is
        # 0 and the cut about the fit could keep too few to fit (none, in a 48 px indent)
        if near.sum() >= A.shape[1]:
            keep = near
    rr, cc = np.mgrid[:h, :w]
    surface = (design(rr.ravel(), cc.ravel()) @ coef).reshape(h, w)
    return surface, float(np.sqrt(np.mean(res[keep] ** 2)))


#: A band's pixels within this share of its intensity range from its extreme sample
#: its fringe centre.
CENTRE_SHARE = 0.1
#: At most this many samples per band (evenly thinned).
SAMPLES_PER_BAND = 2000


def _centre_samples(image, labels, is_bright, selected):
    """(rows, cols, values) of the fringe-centre pixels of the ``selected`` bands: the
    pixels within :data:`CENTRE_SHARE` of the band's intensity range from its extreme
    (the brightest of a bright band, the darkest of a dark one), each valued at the
    3 x 3 local extreme. The band's own pixels say where its centre runs; a medial axis
    does not (a far-field band is wide where its order is nowhere near the centre)."""
    out = {True: ([], [], []), False: ([], [], [])}
    hi = ndimage.maximum_filter(image, 3)
    lo = ndimage.minimum_filter(image, 3)
    for lab, sl in enumerate(ndimage.find_objects(labels), start=1):
        if sl is None or not selected[lab]:
            continue
        band = labels[sl] == lab
        v = image[sl][band]
        b = bool(is_bright[lab])
        top, bottom = v.max(), v.min()
        near = band & (
            (image[sl] >= top - CENTRE_SHARE * (top - bottom))
            if b
            else (image[sl] <= bottom + CENTRE_SHARE * (top - bottom))
        )
        r, c = np.nonzero(near)
        step = max(1, len(r) // SAMPLES_PER_BAND)
        r, c = r[::step], c[::step]
        out[b][0].append(r + sl[0].start)
        out[b][1].append(c + sl[1].start)
        out[b][2].append((hi if b else lo)[sl][r, c])
    return {k: tuple(np.concatenate(x) if x else np.zeros(0) for x in v) for k, v in out.items()}


def fit_envelope(image: np.ndarray, mask: np.ndarray, *, select, passes: int = 2):
    """The fringe envelope of a dark-field-like image (see module doc).

    Bands come from a first normalisation between the 1st and 99th percentiles;
    ``select(labels, is_bright, pairs)`` says which bands hold a whole fringe centre
    (:func:`analysis.mono_order` passes the bands its count puts between a lower and a
    higher neighbour; merely touching two others is not enough - a far-field band
    touching a few vignetted blobs does and holds no centre), and their most extreme pixels
    sample the envelope. With samples from at least three bands of a kind the surface is the
    illumination model, else constant; with none of a kind the percentile stays.
    """
    vals = image[mask]
    low0, high0 = np.percentile(vals, [1.0, 99.0])
    env = Envelope(np.full(image.shape, low0), np.full(image.shape, high0), "percentiles")
    for _ in range(passes):
        labels, is_bright = band_labels(env.normalise(image), mask)
        pairs = band_neighbours(labels)
        samples = _centre_samples(image, labels, is_bright, select(labels, is_bright, pairs))
        surfaces, n, res = {}, 0, []
        seen = np.zeros(image.shape, bool)
        for kind, (rr, cc, v) in samples.items():
            seen[rr.astype(int), cc.astype(int)] = True
            if len(v) == 0:
                continue
            bands = len(np.unique(labels[rr.astype(int), cc.astype(int)]))
            surf, r = smooth_surface(rr, cc, v, image.shape, degree=2 if bands >= 3 else 0)
            surfaces[kind], n = surf, n + len(v)
            res.append(r)
        if not surfaces:
            return env
        low = np.clip(surfaces.get(False, env.low), 0.0, None)  # no light below black
        high = surfaces.get(True, env.high)
        amp = float(np.median((high - low)[mask]))
        reach = ndimage.distance_transform_edt(~seen) / (0.5 * np.hypot(*image.shape))
        rel = max(res) / amp if amp > 0 else np.inf
        kinds = tuple(k for k, b in (("low", False), ("high", True)) if b in surfaces)
        env = Envelope(low, high, "fringe envelope", n, rel, reach, kinds)
    return env


def flat_field_envelope(flat: np.ndarray) -> Envelope:
    """Envelope from a flat-field image of the light (I_0 everywhere; the background is
    taken as the dark frame's, already subtracted)."""
    flat = np.asarray(flat, float)
    high = ndimage.gaussian_filter(flat, 2.0)
    return Envelope(np.zeros_like(flat), high, "flat field", sampled=("low", "high"))
