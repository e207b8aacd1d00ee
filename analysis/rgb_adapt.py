"""Three-fringe photoelasticity beyond three fringes: colour adaptation and reach.

- :func:`fit_adaptation` maps a calibration table's colours onto a specimen's through an
  affine colour transform (3x3 matrix and offset) fitted to the specimen's own pixels of
  known order: colour adaptation (Madhu, Prasath and Ramesh, "Colour adaptation in
  three fringe photoelasticity", *Experimental Mechanics* 47, 2007). A camera, light
  level, white balance or tone curve other than the table's is removed; a light of
  another spectrum is not (its colours follow another sequence beyond order 3).
- :func:`colour_reach` is the order beyond which the table's colours wash out: where
  its colour speed |dC/dN| (averaged over one fringe) falls below ``min_speed``, an
  image's colour noise sigma_C becomes an order noise sigma_N = sigma_C / |dC/dN| larger
  than the method's resolution.
- :func:`search_adapted` chains them with fringe-order continuity (refined TFP: Ramesh
  and Deshmukh, *Optics and Lasers in Engineering* 24, 1996; Madhu and Ramesh, "Noise
  removal in three-fringe photoelasticity by adaptive colour difference estimation",
  *Optics and Lasers in Engineering* 45, 2007): the continuity search
  (:func:`analysis.rgb.search_refined`), a fit of the table to the pixels it solved
  where colours do not repeat (N <= 3), and the search again on the adapted table;
  pixels beyond the reach are unreliable, and so are the regions whose colours say they
  lie beyond it, whatever order the search gave them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import (
    binary_dilation,
    binary_fill_holes,
    distance_transform_edt,
    median_filter,
    uniform_filter,
    uniform_filter1d,
)
from scipy.spatial import cKDTree

from .masks import check_mask
from .rgb import MAX_COLOUR_ERROR, CalibrationTable, RGBResult, search_refined

__all__ = [
    "ADAPT_MAX_ORDER",
    "AdaptedRGBResult",
    "ColourAdaptation",
    "MIN_COLOUR_SPEED",
    "colour_reach",
    "fit_adaptation",
    "search_adapted",
]

#: Smallest colour speed |dC/dN| (colour distance on the [0, 1] scale per fringe,
#: averaged over one fringe) of the orders the method stands behind. Colour noise of
#: 0.02-0.04 (8-bit JPEG photographs) is then an order noise of 0.03-0.05 fringe.
#: fringekit's default table (an LED on PSM-4, sRGB) falls to it at N = 6.6 (4.5 per
#: fringe at N = 1, 2.3 at N = 4.5, 1.1 at N = 6); adapted to a dimmer photograph, lower.
MIN_COLOUR_SPEED = 0.8

#: Highest order of the first continuity pass that the colour adaptation is fitted to:
#: below it white-light colours do not repeat and the search follows them on an
#: unadapted table (measured 0.02-0.07 fringe RMS with white balance, exposure and tone
#: curve off).
ADAPT_MAX_ORDER = 3.0

#: Share of the known pixels (smallest colour distance first) the adaptation keeps.
_KEEP = 0.8
#: Weight pulling the adaptation towards the identity, per pixel fitted.
_RIDGE = 1e-3
#: Side (px) of the square over which pixels vote on whether their colours lie beyond
#: the reach; the region found is widened by half of it.
_VOTE_PX = 7


@dataclass(frozen=True)
class ColourAdaptation:
    """An affine colour transform from a table's colours to a specimen's.

    Parameters
    ----------
    coefficients : (4, 3) float array
        Specimen colour = [1, R, G, B] @ coefficients, with R, G, B the table's colour.
    pixels : int
        Pixels the transform was fitted to (0: the identity).
    residual : float
        RMS colour distance of those pixels to the adapted table ([0, 1] scale).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable, ColourAdaptation
    >>> table = CalibrationTable(np.array([0.0, 1.0]), np.array([[0, 0, 0], [0.5, 0.5, 0.5]]))
    >>> gains = np.vstack([np.zeros(3), np.diag([1.2, 1.0, 0.8])])
    >>> ColourAdaptation(gains, 10, 0.0).apply(table).rgb[1].tolist()
    [0.6, 0.5, 0.4]
    >>> ColourAdaptation.identity().apply(table).rgb[1].tolist()
    [0.5, 0.5, 0.5]
    """

    coefficients: np.ndarray
    pixels: int
    residual: float

    @classmethod
    def identity(cls) -> ColourAdaptation:
        """The transform that leaves a table as it is."""
        return cls(np.vstack([np.zeros(3), np.eye(3)]), 0, float("nan"))

    def apply(self, table: CalibrationTable) -> CalibrationTable:
        """The table with its colours transformed (clipped to [0, 1])."""
        rgb = np.clip(_design(table.rgb) @ self.coefficients, 0.0, 1.0)
        return CalibrationTable(table.orders, rgb, f"{table.source} (colour-adapted)")


def _design(rgb: np.ndarray) -> np.ndarray:
    return np.column_stack([np.ones(len(rgb)), rgb])


def _rows(table: CalibrationTable, order: np.ndarray) -> np.ndarray:
    """The table rows nearest to ``order`` (interpolated colours)."""
    return np.column_stack([np.interp(order, table.orders, table.rgb[:, k]) for k in range(3)])


def fit_adaptation(image, table: CalibrationTable, known, *, mask=None) -> ColourAdaptation:
    """Colour adaptation of a table to a specimen's pixels of known order.

    Least squares of C_image = [1, C_table(N)] A over the pixels of known order N, in two
    rounds: the second keeps the 80 % of pixels closest to the first round's transform
    (a pixel whose order is wrong, clipped or on a JPEG edge does not pull the fit). A
    small ridge pulls A towards the identity, so pixels of a single order (a no-load
    region, black in a dark field) set the offset and leave the rest of the table be.

    Parameters
    ----------
    image : (rows, cols, 3) float array
        The specimen's colours on the [0, 1] scale.
    table : CalibrationTable
    known : (rows, cols) float array
        Fringe order of the pixels it is known at; NaN elsewhere.
    mask : (rows, cols) bool array, optional
        Pixels that may be used (default all).

    Returns
    -------
    ColourAdaptation
        The identity when fewer than 12 pixels are known.

    Raises
    ------
    ValueError
        A grey image, or a ``known`` map or mask of another shape.

    Examples
    --------
    A table made with one camera setting, the specimen photographed with another (a 20 %
    brighter red, a 15 % dimmer blue): the adaptation finds the gains.

    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable, fit_adaptation
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, light_source("LED"),
    ...                                                   Camera(), max_order=4, n=401))
    >>> order = np.linspace(0, 3, 64)[None, :].repeat(4, axis=0)  # (4, 64) known orders
    >>> image = np.stack([np.interp(order, table.orders, table.rgb[:, k]) for k in range(3)], -1)
    >>> image = np.clip(image * [0.96, 0.8, 0.68], 0, 1)
    >>> a = fit_adaptation(image, table, order)
    >>> np.diag(a.coefficients[1:]).round(2).tolist(), a.pixels
    ([0.96, 0.8, 0.68], 208)
    """
    img = np.asarray(image, float)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image shape {img.shape} is not allowed; colour adaptation needs colour")
    known = np.asarray(known, float)
    if known.shape != img.shape[:2]:
        raise ValueError(f"known orders of shape {known.shape} do not match the image")
    m = check_mask(mask, img.shape) & np.isfinite(known)
    if m.sum() < 12:
        return ColourAdaptation.identity()
    x, y = _design(_rows(table, known[m])), img[m]
    keep = np.ones(len(y), bool)
    ident = ColourAdaptation.identity().coefficients
    for _ in range(2):
        lam = _RIDGE * keep.sum()
        a = np.linalg.solve(
            x[keep].T @ x[keep] + lam * np.eye(4), x[keep].T @ y[keep] + lam * ident
        )
        res = np.linalg.norm(x @ a - y, axis=1)
        keep = res <= np.quantile(res, _KEEP)
    return ColourAdaptation(a, int(keep.sum()), float(np.sqrt(np.mean(res[keep] ** 2))))


def colour_reach(table: CalibrationTable, *, min_speed: float = MIN_COLOUR_SPEED) -> float:
    """The fringe order up to which a table's colours tell orders apart.

    The colour speed |dC/dN| of the table (colour distance per fringe, [0, 1] scale),
    averaged over one fringe; the reach is the lowest order above 1 where it falls below
    ``min_speed`` (the table's last order if it never does). White-light colours wash
    out towards grey as the orders of the wavelengths drift apart (the speed of an LED
    on PSM-4 falls from 4.5 per fringe at N = 1 to 1.1 at N = 6 and 0.4 at N = 9).

    Parameters
    ----------
    table : CalibrationTable
    min_speed : float
        Smallest colour speed that counts (:data:`MIN_COLOUR_SPEED`).

    Returns
    -------
    float
        Fringe order.

    Raises
    ------
    ValueError
        ``min_speed`` not > 0.

    Examples
    --------
    >>> from fringekit.analysis import CalibrationTable, colour_reach
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source
    >>> chart = colour_chart(PSM4_ASSUMED, light_source("LED"), Camera(), max_order=10, n=2001)
    >>> round(colour_reach(CalibrationTable.from_chart(*chart)), 1)  # linear RGB
    8.8
    """
    if not min_speed > 0:
        raise ValueError(f"min_speed = {min_speed!r} is not allowed; must be > 0")
    o = table.orders
    speed = np.linalg.norm(np.gradient(table.rgb, o, axis=0), axis=1)
    speed = np.interp(np.arange(o[0], o[-1], 0.01), o, speed)  # uniform in order
    avg = uniform_filter1d(speed, size=101, mode="nearest")  # one fringe
    grid = np.arange(o[0], o[-1], 0.01)
    low = np.nonzero((avg < min_speed) & (grid > 1.0))[0]
    return float(grid[low[0]]) if low.size else float(o[-1])


@dataclass(frozen=True)
class AdaptedRGBResult(RGBResult):
    """Fringe order from colour with continuity and colour adaptation.

    Parameters
    ----------
    order, error, reliable : (rows, cols) arrays
        As :class:`RGBResult`; ``reliable`` is also False above ``reach``.
    reach : float
        Fringe order beyond which the colours do not tell orders apart: the table's
        :func:`colour_reach`, lowered to ``window`` below the table's end.
    adaptation : ColourAdaptation
        The transform applied to the table (the identity without adaptation).
    table : CalibrationTable
        The table searched (adapted).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import AdaptedRGBResult, ColourAdaptation, CalibrationTable
    >>> t = CalibrationTable(np.array([0.0, 1.0]), np.zeros((2, 3)))
    >>> r = AdaptedRGBResult(np.zeros((2, 2)), np.zeros((2, 2)), np.ones((2, 2), bool),
    ...                      6.4, ColourAdaptation.identity(), t)
    >>> r.reach, int(r.reliable.sum())
    (6.4, 4)
    """

    reach: float
    adaptation: ColourAdaptation
    table: CalibrationTable


def _rough(order: np.ndarray, window: float) -> np.ndarray:
    """Pixels whose order is more than half the window from the median of the 5x5 pixels
    about them (an isolated wrong step of the continuity search); NaN pixels take the
    value of the nearest solved one first."""
    bad = ~np.isfinite(order)
    if bad.all():
        return np.zeros(order.shape, bool)
    idx = distance_transform_edt(bad, return_distances=False, return_indices=True)
    filled = order[tuple(idx)]
    return np.abs(filled - median_filter(filled, size=5, mode="nearest")) > window / 2


def _beyond_reach(img, res, tab: CalibrationTable, reach: float, mask) -> np.ndarray:
    """Pixels whose colours say their order is beyond the reach, and every pixel enclosed
    by them or within half the vote of them (see :func:`search_adapted`, step 4)."""
    m = np.isfinite(res.order) if mask is None else np.asarray(mask, bool)
    m = m & np.all(np.isfinite(img), axis=-1)
    above = np.zeros(m.shape, bool)
    if m.any():
        d_above = cKDTree(tab.rgb[tab.orders >= reach]).query(img[m])[0]
        above[m] = d_above < np.nan_to_num(res.error[m], nan=np.inf)
    above |= np.nan_to_num(res.order, nan=-np.inf) > reach
    votes = uniform_filter(above.astype(float), _VOTE_PX)
    share = votes / np.maximum(uniform_filter(m.astype(float), _VOTE_PX), 1e-12)
    region = binary_fill_holes((share > 0.5) & m)
    half = _VOTE_PX // 2
    return binary_dilation(region, np.ones((2 * half + 1,) * 2, bool)) & m


def search_adapted(
    image,
    table: CalibrationTable,
    seeds,
    *,
    mask=None,
    window: float = 0.25,
    adapt: str = "auto",
    max_error: float = MAX_COLOUR_ERROR,
    min_speed: float = MIN_COLOUR_SPEED,
) -> AdaptedRGBResult:
    """Continuity search on a table adapted to the specimen's colours, up to its reach.

    1. :func:`analysis.rgb.search_refined` from the seeds on ``table``;
    2. ``adapt="auto"``: :func:`fit_adaptation` to the seeds and the pixels it solved at
       orders up to :data:`ADAPT_MAX_ORDER`, the search again, then the fit to every
       pixel solved below the reach and the search a last time; ``adapt="seeds"``: the
       fit to the seed pixels only (a no-load region, points of known order), then the
       search; ``adapt="off"``: the table as given;
    3. the reach (:func:`colour_reach` of the searched table, ``window`` below its
       end): the search does not grow from pixels above it, which are unreliable, as
       are those farther than ``max_error`` from every table colour and those more
       than ``window / 2`` off the median order of the 5x5 pixels about them (a wrong
       step of the search);
    4. a check of the search by the colours alone, for a region whose orders rise
       beyond the reach: there the search can slip onto a lower branch whose colours
       are as washed out (a hill to order 8.5 read as 4.4-4.5 inside), and the
       colours no longer say which order is right. A pixel votes "beyond" when its
       colour is nearer to a table colour above the reach than to the colour of the
       order it was given (or that order is above the reach); where more than half of
       the 7 x 7 pixels about it vote so, it lies in a region beyond the reach. Every
       pixel of that region, every pixel it encloses (the true order is continuous,
       so the search reached them only through orders it cannot tell apart: the
       continuity argument of refined TFP, Ramesh and Deshmukh 1996, turned round)
       and every pixel within 3 px of it (the vote places the region's edge only to
       within half its width) is unreliable. A read that is right does not vote so:
       its colour is nearest the order it was given.

    Parameters
    ----------
    image : (rows, cols, 3) float array
        Colours on the [0, 1] scale.
    table : CalibrationTable
        Should run past the highest order of the image by ``window`` or more.
    seeds : sequence of ((row, col), order), or (rows, cols) float array
        Pixels of known order (:func:`analysis.rgb.search_refined`).
    mask : (rows, cols) bool array, optional
    window : float
        Half-width of the order window about the solved neighbours (fringe).
    adapt : {"auto", "seeds", "off"}
        What the colour adaptation is fitted to.
    max_error : float
        Largest colour distance of a reliable pixel (:data:`MAX_COLOUR_ERROR`).
    min_speed : float
        Smallest colour speed within the reach (:data:`MIN_COLOUR_SPEED`).

    Returns
    -------
    AdaptedRGBResult

    Raises
    ------
    ValueError
        An ``adapt`` not listed, and as :func:`analysis.rgb.search_refined`.

    Examples
    --------
    A specimen to order 5.5, photographed with a white balance and exposure other than
    the table's:

    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable, search_adapted
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, PhotoModel, colour_chart
    >>> from fringekit.optics import light_source, retarder, white_light_photograph
    >>> led = light_source("LED")
    >>> cam = Camera(sensitivities="Nikon 5100 (NPL)", full_well=2e4)
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, led, cam, max_order=7))
    >>> order = np.linspace(0, 5.5, 96)[None, :].repeat(8, axis=0)
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * order[..., None] * k, np.pi / 8)
    >>> img = white_light_photograph(q, led, cam, PhotoModel(), white_balance=(1.15, 1, 0.8))
    >>> res = search_adapted(img / 255, table, [((0, 0), 0.0)])
    >>> round(float(np.sqrt(np.mean((res.order - order) ** 2))), 2), bool(res.reliable.all())
    (0.01, True)
    """
    if adapt not in ("auto", "seeds", "off"):
        raise ValueError(f"adapt = {adapt!r} is not allowed; use 'auto', 'seeds' or 'off'")
    img = np.asarray(image, float)
    kw = {"mask": mask, "window": window, "max_error": max_error}

    def reach_of(t: CalibrationTable) -> float:
        return min(colour_reach(t, min_speed=min_speed), t.orders[-1] - window)

    res = search_refined(img, table, seeds, stop_above=reach_of(table), **kw)
    adaptation, tab = ColourAdaptation.identity(), table
    if adapt != "off":
        seed_map = _seed_map(seeds, img.shape[:2])
        fits = [seed_map] if adapt == "seeds" else [None, None, None]
        for limit in fits:
            if limit is None:  # the pixels solved so far, within the range trusted
                top = ADAPT_MAX_ORDER if tab is table else reach_of(tab)
                limit = np.where(res.order <= top, res.order, np.nan)
                limit = np.where(np.isfinite(seed_map), seed_map, limit)
            adaptation = fit_adaptation(img, table, limit, mask=mask)
            tab = adaptation.apply(table)
            res = search_refined(img, tab, seeds, stop_above=reach_of(tab), **kw)
    reach = reach_of(tab)
    reliable = res.reliable & (np.nan_to_num(res.order, nan=np.inf) <= reach)
    reliable &= ~_rough(res.order, window)
    reliable &= ~_beyond_reach(img, res, tab, reach, mask)
    return AdaptedRGBResult(res.order, res.error, reliable, reach, adaptation, tab)


def _seed_map(seeds, shape) -> np.ndarray:
    """The seeds as a (rows, cols) map of orders, NaN off them."""
    if isinstance(seeds, np.ndarray) and seeds.shape == tuple(shape):
        return np.asarray(seeds, float)
    out = np.full(shape, np.nan)
    pts = list(seeds)
    if pts:
        rc = np.round(np.array([p for p, _ in pts], float)).astype(np.int64)
        out[rc[:, 0], rc[:, 1]] = [float(v) for _, v in pts]
    return out
