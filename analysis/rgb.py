"""RGB (three-fringe) photoelasticity: calibration tables and fringe-order search.

Seed paper eq. 1 (Ajovalasit, Barone & Petrucci, J. Strain Anal. 30, 1995; Ramesh,
*Digital Photoelasticity*, 2000, ch. 7): the fringe order of a pixel is the order of the
table row whose colour is nearest, e = (R - R_t)^2 + (G - G_t)^2 + (B - B_t)^2.

- :func:`search` is the plain global search (a KD-tree over the table colours,
  scipy.spatial.cKDTree), reliable to about N = 3 where colours start to repeat.
- :func:`search_refined` restricts each pixel's candidate rows to a window around its
  already-solved neighbours' orders, propagated outwards from seed pixels of known order in
  order of geodesic distance (skimage.graph.MCP_Geometric); it follows the fringe order
  beyond N = 3 as long as neighbouring pixels differ by less than the window.

Both return the residual colour distance per pixel as an error map.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree

from .masks import check_mask

__all__ = [
    "CalibrationTable",
    "RGBResult",
    "colour_spread",
    "MAX_COLOUR_ERROR",
    "MIN_COLOUR_SPREAD",
    "search",
    "search_refined",
]

#: Smallest colour spread (see colour_spread) of an image the RGB method can read.
#: Rendered white-light indents measure 0.047-0.27; photographs of discs in green light
#: 0.0016-0.005 (JPEG noise and uneven lighting give them some spread); grey images 0.
MIN_COLOUR_SPREAD = 0.02

#: Largest colour distance (on the [0, 1] scale) of a pixel the search stands behind: a
#: larger one is a colour the table does not hold (clipped, noisy, another light).
MAX_COLOUR_ERROR = 0.1


@dataclass(frozen=True)
class CalibrationTable:
    """Colour against fringe order: the table of the RGB method.

    Parameters
    ----------
    orders : (n,) float array
        Fringe orders, strictly increasing, n >= 2.
    rgb : (n, 3) float array
        Colours in the units of the images they are compared with (the float [0, 1]
        scale of :func:`normalise`).
    source : str
        Where the table came from (for reports).

    Raises
    ------
    ValueError
        Shapes that do not match, non-finite values or orders not increasing.

    Examples
    --------
    From a synthetic colour chart, a photograph of a calibration line
    (:meth:`from_line`) or a CSV file (:meth:`from_csv`, :meth:`to_csv`):

    >>> from fringekit.analysis import CalibrationTable
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source
    >>> chart = colour_chart(PSM4_ASSUMED, light_source("LED"), Camera(), max_order=4.0, n=401)
    >>> table = CalibrationTable.from_chart(*chart)
    >>> len(table), round(table.step, 3), len(table.resampled(11))
    (401, 0.01, 11)
    """

    orders: np.ndarray
    rgb: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        o = np.asarray(self.orders, float)
        c = np.asarray(self.rgb, float)
        if o.ndim != 1 or len(o) < 2:
            raise ValueError(f"calibration orders shape {o.shape} is not allowed; need (n >= 2,)")
        if c.shape != (len(o), 3):
            raise ValueError(f"calibration rgb shape {c.shape} does not match orders ({len(o)}, 3)")
        if not np.all(np.isfinite(o)) or not np.all(np.isfinite(c)):
            raise ValueError("calibration table holds NaN or infinite values")
        if np.any(np.diff(o) <= 0):
            raise ValueError("calibration orders must be strictly increasing")
        object.__setattr__(self, "orders", o)
        object.__setattr__(self, "rgb", c)

    def __len__(self) -> int:
        return len(self.orders)

    @property
    def step(self) -> float:
        """Mean order spacing of the rows."""
        return float((self.orders[-1] - self.orders[0]) / (len(self.orders) - 1))

    def resampled(self, n: int) -> CalibrationTable:
        """The table on ``n`` equally spaced orders (linear interpolation per channel)."""
        if n < 2:
            raise ValueError(f"n = {n!r} rows is not allowed; need >= 2")
        o = np.linspace(self.orders[0], self.orders[-1], n)
        rgb = np.column_stack([np.interp(o, self.orders, self.rgb[:, k]) for k in range(3)])
        return CalibrationTable(o, rgb, self.source)

    # -- construction --------------------------------------------------------------

    @classmethod
    def from_chart(cls, orders, rgb, source: str = "synthetic colour chart") -> CalibrationTable:
        """From ``optics.colour_chart`` output (or any orders/colours arrays)."""
        return cls(np.asarray(orders, float), np.asarray(rgb, float), source)

    @classmethod
    def from_line(
        cls,
        image,
        start,
        end,
        orders,
        *,
        n_rows: int = 1000,
        source: str = "calibration image",
    ) -> CalibrationTable:
        """From a calibration image with a line of known fringe order.

        Parameters
        ----------
        image : (rows, cols, 3) float in [0, 1] (see :func:`analysis.images.normalise`)
        start, end : (row, col) pixel coordinates of the line ends
        orders : callable or array
            The theoretical fringe order along the line: a function of the position
            s in [0, 1] from ``start`` to ``end`` (vectorised), or an array of orders at
            equally spaced points (its length sets the sampling).
        n_rows : int — rows of the returned, uniformly spaced table

        The line is sampled bilinearly; the samples are sorted by order and resampled to
        ``n_rows`` equally spaced orders. The orders along the line must be monotonic
        (e.g. a disc from its centre outwards), or colours of different orders would mix.
        """
        img = np.asarray(image, float)
        if img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"calibration image shape {img.shape} is not allowed; need colour")
        p0, p1 = np.asarray(start, float), np.asarray(end, float)
        length = float(np.hypot(*(p1 - p0)))
        if length < 2:
            raise ValueError(f"calibration line {tuple(p0)} -> {tuple(p1)} is under 2 px long")
        if callable(orders):
            m = max(int(np.ceil(length * 4)), 8)
            s = np.linspace(0.0, 1.0, m)
            o = np.asarray(orders(s), float)
        else:
            o = np.asarray(orders, float)
            s = np.linspace(0.0, 1.0, len(o))
        if o.shape != s.shape:
            raise ValueError(f"orders along the line have shape {o.shape}, expected {s.shape}")
        d = np.diff(o)
        if not (np.all(d > 0) or np.all(d < 0)):
            raise ValueError("the fringe order along the calibration line must be monotonic")
        rc = p0[:, None] + (p1 - p0)[:, None] * s[None, :]
        for k, n in enumerate(img.shape[:2]):
            if rc[k].min() < 0 or rc[k].max() > n - 1:
                raise ValueError(f"calibration line leaves the image ({img.shape[:2]})")
        rgb = np.column_stack([map_coordinates(img[..., c], rc, order=1) for c in range(3)])
        idx = np.argsort(o)
        return cls(o[idx], rgb[idx], source).resampled(n_rows)

    @classmethod
    def from_csv(cls, path) -> CalibrationTable:
        """Read a table written by :meth:`to_csv` (columns order, R, G, B)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"calibration table {str(path)!r} does not exist")
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
        header = [h.strip().lower() for h in rows[0]] if rows else []
        if header[:4] != ["order", "r", "g", "b"]:
            raise ValueError(f"{path}: header {rows[0] if rows else []} is not order,R,G,B")
        try:
            data = np.array([[float(v) for v in r[:4]] for r in rows[1:] if r], float)
        except ValueError as exc:
            raise ValueError(f"{path}: non-numeric value ({exc})") from None
        return cls(data[:, 0], data[:, 1:4], str(path))

    def to_csv(self, path) -> None:
        """Write columns order, R, G, B (colours on the [0, 1] scale)."""
        with Path(path).open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["order", "R", "G", "B"])
            for o, c in zip(self.orders, self.rgb, strict=True):
                w.writerow([f"{o:.6f}", f"{c[0]:.6f}", f"{c[1]:.6f}", f"{c[2]:.6f}"])


@dataclass(frozen=True)
class RGBResult:
    """Fringe order from colour (made by :func:`search` and :func:`search_refined`).

    Parameters
    ----------
    order : (rows, cols) float array
        Fringe order; NaN outside the mask (and, refined, where no seed reaches).
    error : (rows, cols) float array
        Colour distance sqrt(e) to the chosen row (same scale as the image); large
        values flag colours the table does not hold.
    reliable : (rows, cols) bool array
        Pixels searched and given an order whose colour distance is below the search's
        ``max_error``.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, indent_field
    >>> from fringekit.optics import light_source, retarder, white_light_image
    >>> led = light_source("LED")
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, led, Camera(), max_order=4))
    >>> order, _, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * order[..., None] * k, np.pi / 8)
    >>> image = np.clip(white_light_image(q, led, Camera(), linear=True), 0, 1)
    >>> from fringekit.analysis import search
    >>> res = search(image, table, mask=mask)
    >>> bool((res.reliable == mask).all()), round(float(np.nanmax(res.error)), 3)
    (True, 0.023)
    """

    order: np.ndarray
    error: np.ndarray
    reliable: np.ndarray


def colour_spread(image, mask=None) -> float:
    """How three-dimensional an image's colours are.

    The smallest over the largest eigenvalue of the covariance of its RGB values. White-
    light isochromatics trace a curve that turns through all three colour dimensions; an
    image in single-colour light (or grey) has its colours on a line, up to noise, so the
    ratio is near 0 and colour cannot tell the orders apart (:data:`MIN_COLOUR_SPREAD`).

    Parameters
    ----------
    image : (rows, cols, 3) float array
    mask : (rows, cols) bool array, optional
        Pixels used.

    Returns
    -------
    float
        In [0, 1]; 0 for fewer than 3 pixels.

    Raises
    ------
    ValueError
        A grey image.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, indent_field
    >>> from fringekit.optics import light_source, retarder, white_light_image
    >>> led = light_source("LED")
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, led, Camera(), max_order=4))
    >>> order, _, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * order[..., None] * k, np.pi / 8)
    >>> image = np.clip(white_light_image(q, led, Camera(), linear=True), 0, 1)
    >>> from fringekit.analysis import MIN_COLOUR_SPREAD, colour_spread
    >>> round(colour_spread(image, mask), 2), colour_spread(image, mask) > MIN_COLOUR_SPREAD
    (0.24, True)
    >>> colour_spread(np.repeat(image[..., 1:2], 3, axis=-1))  # grey
    0.0
    """
    img, m = _pixels(image, mask)
    px = img[m]
    if len(px) < 3:
        return 0.0
    ev = np.linalg.eigvalsh(np.cov((px - px.mean(axis=0)).T))
    return float(max(ev[0], 0.0) / ev[2]) if ev[2] > 0 else 0.0


def _reliable(order: np.ndarray, error: np.ndarray, max_error: float) -> np.ndarray:
    """Pixels with an order whose colour distance is below ``max_error``."""
    if not max_error > 0:
        raise ValueError(f"max_error = {max_error!r} is not allowed; must be > 0")
    return np.isfinite(order) & (np.nan_to_num(error, nan=np.inf) < max_error)


def _pixels(image, mask) -> tuple[np.ndarray, np.ndarray]:
    img = np.asarray(image, float)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image shape {img.shape} is not allowed; RGB search needs colour")
    return img, check_mask(mask, img.shape)


def search(
    image, table: CalibrationTable, *, mask=None, max_error: float = MAX_COLOUR_ERROR
) -> RGBResult:
    """Plain least-squares search of every pixel over the whole table (seed eq. 1).

    Reliable to about N = 3, where white-light colours start to repeat.

    Parameters
    ----------
    image : (rows, cols, 3) float array
        Colours on the table's scale.
    table : CalibrationTable
    mask : (rows, cols) bool array, optional
        Pixels to search (default all).
    max_error : float
        Largest colour distance of a reliable pixel (:data:`MAX_COLOUR_ERROR`).

    Returns
    -------
    RGBResult

    Raises
    ------
    ValueError
        A grey image, a mask of another shape, or ``max_error`` not > 0.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, indent_field
    >>> from fringekit.optics import light_source, retarder, white_light_image
    >>> led = light_source("LED")
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, led, Camera(), max_order=4))
    >>> order, _, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * order[..., None] * k, np.pi / 8)
    >>> image = np.clip(white_light_image(q, led, Camera(), linear=True), 0, 1)
    >>> from fringekit.analysis import search
    >>> res = search(image, table, mask=mask)
    >>> round(float(np.abs(res.order - order)[res.reliable].max()), 3)  # fringe
    0.005
    """
    img, m = _pixels(image, mask)
    dist, idx = cKDTree(table.rgb).query(img[m], k=1)
    order = np.full(m.shape, np.nan)
    error = np.full(m.shape, np.nan)
    order[m] = table.orders[idx]
    error[m] = dist
    return RGBResult(order, error, _reliable(order, error, max_error))


def _seed_arrays(seeds, tab: CalibrationTable, m: np.ndarray, window: float):
    """Seed rows, columns and orders (int, int, float arrays) from a sequence of
    ((row, col), order) or a (rows, cols) map of orders (NaN off the seeds); each checked:
    inside the image and the mask, its order inside the table's range."""
    rows, cols = m.shape
    if isinstance(seeds, np.ndarray) and seeds.shape == m.shape:
        r, c = np.nonzero(np.isfinite(seeds))
        o = seeds[r, c].astype(float)
    else:
        seeds = list(seeds)
        rc = np.array([p for p, _ in seeds], float).reshape(-1, 2)
        r, c = np.round(rc[:, 0]).astype(np.int64), np.round(rc[:, 1]).astype(np.int64)
        o = np.array([v for _, v in seeds], float)
    if not len(o):
        raise ValueError("search_refined needs at least one seed ((row, col), order)")
    inside = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
    bad = ~inside
    bad[inside] = ~m[r[inside], c[inside]]
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"seed pixel {(int(r[i]), int(c[i]))} is outside the image or the mask")
    out = (o < tab.orders[0] - window) | (o > tab.orders[-1] + window) | ~np.isfinite(o)
    if out.any():
        raise ValueError(
            f"seed order {float(o[np.argmax(out)])!r} is outside the table range "
            f"[{tab.orders[0]:.3g}, {tab.orders[-1]:.3g}]"
        )
    return r, c, o


def _windows(tab: CalibrationTable, k: int):
    """The table's colours (n, 3), and for every row the squared norms (n, 2k+1) and the
    per-channel colours [(n, 2k+1)] x 3 of the rows within +-k of it (edge-padded)."""
    T = tab.rgb.astype(np.float32)
    Tpad = np.concatenate([np.repeat(T[:1], k, 0), T, np.repeat(T[-1:], k, 0)])
    Tw = np.lib.stride_tricks.sliding_window_view(Tpad, 2 * k + 1, axis=0)  # (n, 3, 2k+1)
    Tn = (Tw.astype(np.float32) ** 2).sum(axis=1)  # (n, 2k+1)
    Tc = [np.ascontiguousarray(Tw[:, c, :]) for c in range(3)]  # per channel, (n, 2k+1)
    return T, Tn, Tc


def search_refined(
    image,
    table: CalibrationTable,
    seeds,
    *,
    mask=None,
    window: float = 0.25,
    max_error: float = MAX_COLOUR_ERROR,
    stop_above: float = np.inf,
) -> RGBResult:
    """Search restricted to +-``window`` fringe around the neighbours' orders.

    Pixels of the mask not connected to any seed stay NaN. The search grows from the
    seeds best colour match first (quality-guided, as in phase unwrapping), so an
    ambiguous pixel is solved last, from its clearest neighbours.

    Parameters
    ----------
    image : (rows, cols, 3) float array
        Colours on the table's scale.
    table : CalibrationTable
        Resampled to uniform spacing internally.
    seeds : sequence of ((row, col), order), or (rows, cols) float array
        Pixels of known fringe order (e.g. the far field at 0, or a point on a
        calibrated fringe), or a map of known orders, NaN off them (a no-load region).
        Every pixel connected to a seed inside ``mask`` is solved.
    mask : (rows, cols) bool array, optional
    window : float
        Half-width of the order window (fringes). Must exceed the largest order change
        between neighbouring pixels plus the colour noise in orders; 0.25 follows
        ~0.2 fringe/pixel (0.15 already lost the diametral disc at 0.25 mm/px).
    max_error : float
        Largest colour distance of a reliable pixel (:data:`MAX_COLOUR_ERROR`).
    stop_above : float
        Pixels solved above this order are kept (unreliable) but the search does not
        grow from them: beyond the colours' reach it stops instead of wandering.

    Returns
    -------
    RGBResult

    Raises
    ------
    ValueError
        No seed, a seed outside the image, the mask or the table's range, a window that
        is not > 0, or ``max_error`` not > 0.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import CalibrationTable
    >>> from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, indent_field
    >>> from fringekit.optics import light_source, retarder, white_light_image
    >>> led = light_source("LED")
    >>> table = CalibrationTable.from_chart(*colour_chart(PSM4_ASSUMED, led, Camera(), max_order=4))
    >>> order, _, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    >>> q = retarder(2 * np.pi * order[..., None] * k, np.pi / 8)
    >>> image = np.clip(white_light_image(q, led, Camera(), linear=True), 0, 1)
    >>> from fringekit.analysis import search_refined
    >>> res = search_refined(image, table, [((0, 0), 0.3)], mask=mask)  # the corner is at 0.3
    >>> int(res.reliable.sum()), round(float(np.abs(res.order - order)[res.reliable].max()), 3)
    (2280, 0.013)
    """
    img, m = _pixels(image, mask)
    if not window > 0:
        raise ValueError(f"window = {window!r} fringe is not allowed; must be > 0")
    rows, cols = m.shape
    tab = (
        table
        if np.allclose(np.diff(table.orders), table.step)
        else table.resampled(max(len(table), 2))
    )
    step = tab.step
    k = int(np.ceil(window / step))
    sr, sc, so = _seed_arrays(seeds, tab, m, window)
    # work on a one-pixel padded grid so that every pixel has 8 neighbours
    pc = cols + 2
    inside = np.zeros((rows + 2, pc), bool)
    inside[1:-1, 1:-1] = m
    inside = inside.ravel()
    order = np.full((rows + 2) * pc, np.nan)
    error = np.full((rows + 2) * pc, np.nan)
    pix = np.zeros(((rows + 2) * pc, 3), np.float32)
    pix.reshape(rows + 2, pc, 3)[1:-1, 1:-1] = img
    T, Tn, Tc = _windows(tab, k)
    nb = np.array([-pc - 1, -pc, -pc + 1, -1, 1, pc - 1, pc, pc + 1])
    seed_flat = (sr + 1) * pc + sc + 1
    order[seed_flat] = so
    error[seed_flat] = cKDTree(T).query(pix[seed_flat], k=1)[0]
    # Quality-guided growth: the frontier (unsolved pixels next to solved ones) is solved
    # in windows around its solved neighbours, and only its better half by colour error
    # is accepted in each wave; the rest wait for more solved neighbours. A pixel whose
    # colour is ambiguous (near a dark fringe, clipped, noisy) is thus reached last, from
    # the side where the order is clear, instead of passing a wrong step on round a
    # ring as a front marching by distance would (one wrong pixel at 96 px gave an RMS
    # of 0.3 fringe that way).
    in_front = np.zeros_like(inside)

    def grow(done: np.ndarray) -> np.ndarray:
        cand = np.unique((done[:, None] + nb).ravel())
        cand = cand[inside[cand] & np.isnan(order[cand]) & ~in_front[cand]]
        in_front[cand] = True
        return cand

    front = grow(np.asarray(seed_flat, np.int64))
    while front.size:
        nval = order[front[:, None] + nb]
        cnt = np.isfinite(nval).sum(axis=1)
        ref = np.nansum(nval, axis=1) / np.maximum(cnt, 1)
        centre = np.clip(np.round((ref - tab.orders[0]) / step).astype(np.int64), 0, len(T) - 1)
        p_ = pix[front]
        dot = p_[:, 0, None] * Tc[0][centre]
        dot += p_[:, 1, None] * Tc[1][centre]
        dot += p_[:, 2, None] * Tc[2][centre]
        d2 = Tn[centre] - 2.0 * dot
        rows_best = np.clip(centre + np.argmin(d2, axis=1) - k, 0, len(T) - 1)
        e = np.sqrt(((p_ - T[rows_best]) ** 2).sum(axis=1))
        take = e <= np.median(e) if front.size > 8 else np.ones(front.size, bool)
        done = front[take]
        order[done] = tab.orders[rows_best[take]]
        error[done] = e[take]
        in_front[done] = False
        front = np.concatenate([front[~take], grow(done[order[done] <= stop_above])])
    order = order.reshape(rows + 2, pc)[1:-1, 1:-1]
    error = error.reshape(rows + 2, pc)[1:-1, 1:-1]
    out = np.where(m, order, np.nan)
    err = np.where(m, error, np.nan)
    return RGBResult(out, err, _reliable(out, err, max_error) & ~(out > stop_above))
