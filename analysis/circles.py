"""Circular specimens (calibration discs) found in a photograph.

The outline of a disc is a circle of strong intensity edges. Edges come from Canny's
detector and circles from the circular Hough transform (scikit-image, ``canny``,
``hough_circle``, ``hough_circle_peaks``) on a copy of the photo reduced to at most
:data:`WORK_PX` a side; each circle found is then refined at full resolution by a
least-squares circle (``skimage.measure.CircleModel``) through the edge pixels within a
thin annulus about it. Fringes make edges too, and closed fringes make circles: of
circles whose centres lie inside one another the best supported is kept. The score of
each circle is the fraction of its circumference with an edge within 2 % of its radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage.feature import canny
from skimage.measure import CircleModel
from skimage.transform import hough_circle, hough_circle_peaks, rescale

from .channels import grey_channel

__all__ = [
    "Circle",
    "MIN_OUTLINE_SUPPORT",
    "WORK_PX",
    "disc_by_symmetry",
    "find_disc",
    "find_discs",
]

#: Longest side (px) of the reduced image the Hough transform runs on.
WORK_PX = 400

#: Minimum share of the circumference with edge support for a circle to count.
MIN_SUPPORT = 0.35

#: Edge support an outline needs to be trusted as THE specimen (:func:`find_disc`).
MIN_OUTLINE_SUPPORT = 0.6


@dataclass(frozen=True)
class Circle:
    """A circle in pixel coordinates (found by :func:`find_discs`).

    Parameters
    ----------
    row, col : float
        Centre (px).
    radius : float
        Radius (px).
    support : float
        Share of the circumference with an edge (0-1).

    Examples
    --------
    >>> from fringekit.analysis import Circle
    >>> Circle(row=60.0, col=80.0, radius=40.0, support=0.9).radius
    40.0
    """

    row: float
    col: float
    radius: float
    support: float


def _support(rr: np.ndarray, cc: np.ndarray, row: float, col: float, radius: float) -> float:
    """Fraction of 360 angular bins with an edge pixel (rr, cc) within 2 % of ``radius``."""
    near = np.abs(np.hypot(rr - row, cc - col) - radius) <= max(0.02 * radius, 1.5)
    if not near.any():
        return 0.0
    ang = np.arctan2(rr[near] - row, cc[near] - col)
    bins = np.unique(((ang + np.pi) / (2 * np.pi) * 360).astype(int) % 360)
    return len(bins) / 360.0


def _refine(rr: np.ndarray, cc: np.ndarray, guess: Circle) -> Circle:
    """Least-squares circle through the edge pixels (rr, cc) within 4 % of the guess's
    radius (support left to the caller)."""
    near = np.abs(np.hypot(rr - guess.row, cc - guess.col) - guess.radius) <= max(
        0.04 * guess.radius, 2.0
    )
    if near.sum() < 20:
        return guess
    model = CircleModel.from_estimate(np.column_stack([cc[near], rr[near]]).astype(float))
    if not model:
        return guess
    (xc, yc), r = model.center, model.radius
    if not (abs(r / guess.radius - 1) < 0.1 and np.hypot(yc - guess.row, xc - guess.col) < 0.1 * r):
        return guess
    return Circle(float(yc), float(xc), float(r), 0.0)


def find_discs(
    image: np.ndarray,
    *,
    radius_px: tuple[float, float] | None = None,
    count: int = 1,
    sigma: float = 2.0,
) -> list[Circle]:
    """Up to ``count`` disc outlines in ``image``, best supported first.

    Canny edges and a circular Hough transform on a copy reduced to at most
    :data:`WORK_PX` a side, each circle refined at full resolution (module docstring).

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, 3) float array in [0, 1]
    radius_px : (min, max), optional
        Radius range (px, full resolution); default 10 % to 50 % of the shorter side.
    count : int
        Circles to return (overlapping ones are suppressed).
    sigma : float
        Canny smoothing (px of the reduced image).

    Returns
    -------
    list of Circle
        With support of at least :data:`MIN_SUPPORT` (may be empty).

    Raises
    ------
    ValueError
        A radius range that is not 0 < min <= max.

    Examples
    --------
    >>> from fringekit.analysis import circle_mask, find_discs
    >>> photo = 0.8 * circle_mask((120, 160), (60, 80), 40)  # a grey disc on black
    >>> [(c.row, c.col, round(c.radius, 1)) for c in find_discs(photo)]
    [(60.0, 80.0, 40.0)]
    """
    img = grey_channel(np.asarray(image, float))
    lo_i, hi_i = np.percentile(img, [1.0, 99.0])  # dim photographs: stretch first
    img = np.clip((img - lo_i) / max(hi_i - lo_i, 1e-12), 0.0, 1.0)
    rows, cols = img.shape
    lo, hi = radius_px if radius_px is not None else (0.1 * min(rows, cols), 0.5 * min(rows, cols))
    if not (0 < lo <= hi):
        raise ValueError(f"radius_px = ({lo}, {hi}) is not allowed; need 0 < min <= max")
    scale = min(1.0, WORK_PX / max(rows, cols))
    small = rescale(img, scale, anti_aliasing=True) if scale < 1 else img
    # thresholds as quantiles of the gradient: the strongest 10 % of edges, whatever the
    # exposure
    edges_small = canny(
        small, sigma=sigma, low_threshold=0.8, high_threshold=0.9, use_quantiles=True
    )
    radii = np.arange(max(3, int(lo * scale)), int(np.ceil(hi * scale)) + 1)
    acc = hough_circle(edges_small, radii)
    spacing = max(3, int(lo * scale))
    peaks = {"min_xdistance": spacing, "min_ydistance": spacing, "total_num_peaks": 8 * count}
    _, cx, cy, rad = hough_circle_peaks(acc, radii, **peaks)
    edges = canny(
        img,
        sigma=max(1.0, sigma / scale / 2),
        low_threshold=0.8,
        high_threshold=0.9,
        use_quantiles=True,
    )
    rr, cc = np.nonzero(edges)
    candidates = []
    for x, y, r in zip(cx, cy, rad, strict=True):
        c = _refine(rr, cc, Circle(y / scale, x / scale, r / scale, 0.0))
        c = Circle(c.row, c.col, c.radius, _support(rr, cc, c.row, c.col, c.radius))
        if c.support >= MIN_SUPPORT:
            candidates.append(c)
    # a closed fringe inside a disc is a circle too, and Hough finds circles through
    # parts of neighbouring discs: of circles whose centres lie inside one another the
    # best supported is kept
    found: list[Circle] = []
    for c in sorted(candidates, key=lambda c: -c.support):
        if not any(np.hypot(c.row - o.row, c.col - o.col) < max(c.radius, o.radius) for o in found):
            found.append(c)
    found.sort(key=lambda c: -c.support)
    return found[:count]


def disc_by_symmetry(image: np.ndarray) -> Circle:
    """Centre and radius of the one disc of a diametral-compression photograph.

    From the symmetry of its fringes rather than its outline. Frocht's field is
    symmetric about both diameters, so the centroid of the image's departure from the
    background, |I - I_bg|, is the disc's centre whatever the load and whether the field
    is dark or bright; the fringes crowd at the load points on the rim, so the departure
    along the load axis (the column through the centre) reaches the rim. I_bg is the
    median of the image border and the departure counts where it exceeds 5 robust
    standard deviations of the border. For a dark-field photograph whose outline does not
    show (its horizontal ends are as dark as the background).

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, 3) float array in [0, 1]

    Returns
    -------
    Circle
        Its support is the share of the column's departure inside the circle (1 for a
        clean photo).

    Raises
    ------
    ValueError
        No departure from the background.

    Examples
    --------
    A 20 mm disc under 20 N in dark field at 0.5 mm per pixel, its centre 2 px left of
    the image's:

    >>> import numpy as np
    >>> from fringekit.analysis import disc_by_symmetry
    >>> from fringekit.optics import PSM4_ASSUMED, DiametralDisc, PixelGrid, dark_field_circular
    >>> from fringekit.optics import intensity, optical_map
    >>> grid = PixelGrid((60, 80), 0.5e-3, center=(1e-3, 0.0))
    >>> omap = optical_map(DiametralDisc(P=20.0, D=20e-3, t=5e-3), grid, PSM4_ASSUMED)
    >>> photo = np.where(omap.mask, intensity(omap.q[:, :, 0], dark_field_circular()), 0.0)
    >>> c = disc_by_symmetry(photo)
    >>> round(c.row, 1), round(c.col, 1), c.radius  # the radius is 20 px
    (29.5, 37.5, 22.0)
    """
    img = ndimage.gaussian_filter(grey_channel(np.asarray(image, float)), 1.0)
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = float(np.median(border))
    noise = 1.4826 * float(np.median(np.abs(border - bg))) + 1e-3
    dep = np.abs(img - bg)
    w = np.where(dep > 5 * noise, dep, 0.0)
    if not w.any():
        raise ValueError("the image holds nothing brighter or darker than its border")
    rr, cc = np.mgrid[: img.shape[0], : img.shape[1]]
    row, col = float((w * rr).sum() / w.sum()), float((w * cc).sum() / w.sum())
    c0 = int(round(col))
    band = (w[:, max(c0 - 2, 0) : c0 + 3] > 0).any(axis=1)
    lit = np.flatnonzero(band)
    radius = 0.5 * float(lit[-1] - lit[0] + 1)
    inside = np.abs(lit - row) <= radius
    return Circle(row, col, radius, float(inside.mean()))


def find_disc(image: np.ndarray) -> tuple[Circle, str]:
    """The one circular specimen of a photograph.

    Its outline when :data:`MIN_OUTLINE_SUPPORT` of it is seen (:func:`find_discs`), else
    the symmetry of its fringes (:func:`disc_by_symmetry`).

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, 3) float array in [0, 1]

    Returns
    -------
    circle : Circle
    how : str
        How it was found, for reports.

    Raises
    ------
    ValueError
        Neither finds a disc.

    Examples
    --------
    >>> from fringekit.analysis import circle_mask, find_disc
    >>> circle, how = find_disc(0.8 * circle_mask((120, 160), (60, 80), 40))
    >>> (circle.row, circle.col), how
    ((60.0, 80.0), 'outline (73 % of it found)')
    """
    found = find_discs(image, count=1)
    if found and found[0].support >= MIN_OUTLINE_SUPPORT:
        return found[0], f"outline ({100 * found[0].support:.0f} % of it found)"
    return disc_by_symmetry(image), "symmetry of the fringes (outline not found)"
