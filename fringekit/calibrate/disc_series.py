"""Load stepping: the fringe value from a disc series whose frozen stress is as strong as
the load's.

Frozen-in stress and the load's stress coexist in the same thin disc, so their stresses
add and, by the stress-optic law (Dally and Riley, *Experimental Stress Analysis*, 4th
ed., 2005, ch. 13), so do their secondary principal stress-difference vectors, in fringes:

    W_k(x) = P_k s(x) / f_sigma + w(x),      N_k = |W_k|,

with s = t (sigma_xx - sigma_yy, 2 sigma_xy) of Frocht's disc at 1 N (*Photoelasticity*
Vol. 2, Wiley 1948) and w the frozen order vector, the same in every photograph. Behind
a circular polariscope in monochromatic light I_k = b + a sin^2(pi N_k) (dark field;
cos^2 bright).

Where the frozen vector lies along the load's principal direction (w = alpha s / |s|),
N_k = P_k |s| / f_sigma + alpha, and each pixel's intensities over the series are a
harmonic of its load order: I_k = A + B cos(2 pi c_k) + C sin(2 pi c_k), c_k = P_k |s| /
f_sigma, linear in A, B, C whatever alpha, the light and the field. That is load
stepping: the frozen order is each pixel's phase, never unwrapped. For each trial
f_sigma every pixel's harmonic is fitted (three unknowns, so four or more photographs at
distinct loads); the fringe value is the one whose best half of the pixels fit best -
least trimmed squares (Rousseeuw, *J. Am. Stat. Assoc.* 79, 1984), which leaves out the
pixels where the frozen vector has a large component across the load's direction and
bends the harmonic. The search is a grid over the centre order of the highest load,
then a finer one within 5 % and a parabola through the best three points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fringekit.calibrate.disc_photo import (
    FIT_RADIUS,
    DiscGeometry,
    DiscImage,
    disc_coordinates,
    disc_pixels,
)
from fringekit.errors import InputError
from fringekit.optics import DiametralDisc

__all__ = ["SeriesFit", "fit_disc_series", "MIN_SERIES"]

#: Least number of photographs at distinct loads (a zero-load reference counts): each
#: pixel's harmonic in the load has three unknowns.
MIN_SERIES = 4
#: Fraction of the pixels whose harmonics rank the fringe value (the best-fitting ones).
KEEP = 0.5
#: Pixels sampled over the disc, and the step (fringes) of the coarse search over the
#: centre order of the highest load.
SERIES_PIXELS = 1500
ORDER_STEP = 0.02
#: Angular sectors left out in turn for the uncertainty of a series of MIN_SERIES photos.
SECTORS = 8


@dataclass(frozen=True)
class SeriesFit:
    """The fringe value of a load series by load stepping (:func:`fit_disc_series`).

    Attributes
    ----------
    f_sigma, f_sigma_sd : float
        The fringe value and its 1-sigma (N/m per fringe).
    offset_order : float
        The frozen order at the disc centre modulo one fringe, in [-0.5, 0.5) (fringes).
    geometry : DiscGeometry
        The disc, as given.
    centre_orders : tuple of float
        Per photograph, the load's centre order 8 P / (pi D f_sigma) (fringes).
    residuals : tuple of float
        Per photograph, the RMS residual of the kept pixels' harmonics (fraction of their
        fringe amplitude).
    sd_method : str
        How the 1-sigma was found.
    evaluations : int
        Trial fringe values ranked.
    load_scales : tuple of float
        Per photograph, the factor on its load that fits it best with the others held
        (1 when photo and load agree; NaN for a zero-load reference).
    own_centre_orders : tuple of float
        Per photograph, the load's centre order at that factor (fringes).
    r_squared : float
        R^2 of ``own_centre_orders`` against the loads (a line with intercept).

    Examples
    --------
    See :func:`fit_disc_series`; the fields it holds:

    >>> fit = SeriesFit(7000.0, 50.0, 0.2, DiscGeometry(100, 100, 80), (1.0, 2.0),
    ...                 (0.05, 0.05), "jackknife", 600, (1.0, 1.0), (1.0, 2.0), 1.0)
    >>> fit.r_squared, fit.load_scales
    (1.0, (1.0, 1.0))
    """

    f_sigma: float
    f_sigma_sd: float
    offset_order: float
    geometry: DiscGeometry
    centre_orders: tuple
    residuals: tuple
    sd_method: str
    evaluations: int
    load_scales: tuple
    own_centre_orders: tuple
    r_squared: float


def _normalised(values: np.ndarray) -> np.ndarray:
    """(K, n) intensities scaled to each photograph's 2-98 % range."""
    lo, hi = np.percentile(values, [2.0, 98.0], axis=1)
    return (values - lo[:, None]) / np.maximum(hi - lo, 1e-3)[:, None]


def _harmonics(J, loads, s_abs, kappas):
    """Per trial 1/f_sigma (q,) and pixel (n,) the residual sum of squares (q, n) of J_k =
    A + B cos 2 pi c_k + C sin 2 pi c_k, c_k = kappa P_k |s|, and the amplitude (q, n)."""
    c = 2 * np.pi * kappas[:, None, None] * loads[None, :, None] * s_abs[None, None, :]
    X = np.stack([np.ones_like(c), np.cos(c), np.sin(c)], -1)  # (q, K, n, 3)
    XtX = np.einsum("qkni,qknj->qnij", X, X) + 1e-9 * np.eye(3)
    XtJ = np.einsum("qkni,kn->qni", X, J)
    coef = np.linalg.solve(XtX, XtJ[..., None])[..., 0]
    ss = np.maximum((J * J).sum(0)[None] - (coef * XtJ).sum(-1), 0.0)
    return ss, np.hypot(coef[..., 1], coef[..., 2]), coef


def _trimmed(J, loads, s_abs, kappas) -> np.ndarray:
    """(q,) sum of the KEEP fraction of smallest per-pixel residuals, per trial kappa."""
    out = []
    for chunk in np.array_split(kappas, max(1, len(kappas) // 40)):
        ss = _harmonics(J, loads, s_abs, chunk)[0]
        out.append(np.sort(ss, 1)[:, : max(1, int(KEEP * ss.shape[1]))].sum(1))
    return np.concatenate(out)


def _best(grid: np.ndarray, cost: np.ndarray) -> float:
    """The grid point of least cost, refined by a parabola through it and its neighbours."""
    k = int(np.clip(np.argmin(cost), 1, len(grid) - 2))
    y0, y1, y2 = cost[k - 1 : k + 2]
    den = y0 - 2 * y1 + y2
    step = 0.5 * (y0 - y2) / den if den > 0 else 0.0
    return float(grid[k] + np.clip(step, -1, 1) * (grid[k + 1] - grid[k]))


def _kappa(J, loads, s_abs, per_order: float, max_order: float) -> tuple[float, int]:
    """1/f_sigma ranked over the centre order of the highest load (coarse grid, then a
    finer one within 5 %); and the number of trials."""
    coarse = np.arange(ORDER_STEP, max_order + 1e-9, ORDER_STEP)
    n0 = coarse[int(np.argmin(_trimmed(J, loads, s_abs, per_order * coarse)))]
    fine = n0 * np.linspace(0.95, 1.05, 101)
    return per_order * _best(fine, _trimmed(J, loads, s_abs, per_order * fine)), 101 + len(coarse)


def _load_scales(J, loads, s_abs, kappa) -> np.ndarray:
    """Per photograph the factor on its load (0.7-1.3) that fits best, the others held."""
    factors = np.linspace(0.7, 1.3, 121)
    scales = np.full(len(loads), np.nan)
    for k in np.flatnonzero(loads > 0):
        cost = []
        for f in factors:
            trial = loads.copy()
            trial[k] *= f
            cost.append(_trimmed(J, trial, s_abs, np.array([kappa]))[0])
        scales[k] = _best(factors, np.array(cost))
    return scales


def _jackknife(J, loads, s_abs, per_order, max_order, sector) -> tuple[float, str]:
    """1-sigma of f_sigma by the delete-a-group jackknife (Efron and Stein, *Ann. Stat.* 9,
    1981) over the photographs (more than MIN_SERIES distinct loads) or SECTORS sectors."""
    if len(np.unique(loads)) > MIN_SERIES:
        groups = [(np.arange(len(loads)) != k, slice(None)) for k in range(len(loads))]
        how = f"jackknife over {len(loads)} photographs"
    else:
        groups = [(slice(None), sector != k) for k in range(SECTORS)]
        how = f"jackknife over {SECTORS} sectors of the disc"
    fs = []
    for photos, pixels in groups:
        kappa, _ = _kappa(J[photos][:, pixels], loads[photos], s_abs[pixels], per_order, max_order)
        fs.append(1.0 / kappa)
    n = len(fs)
    return float(np.sqrt((n - 1) / n * np.sum((np.array(fs) - np.mean(fs)) ** 2))), how


def _diagnostics(J, loads, s_abs, kappa, xy, radius, field):
    """Per photograph the RMS residual of the kept pixels over their fringe amplitude, and
    the frozen order at the centre modulo one fringe (the harmonics' phase there)."""
    ss, amp, coef = (a[0] for a in _harmonics(J, loads, s_abs, np.array([kappa])))
    keep = ss <= np.quantile(ss, KEEP)
    c = 2 * np.pi * kappa * loads[:, None] * s_abs[None, keep]
    co = coef[keep]
    pred = co[:, 0] + co[:, 1] * np.cos(c) + co[:, 2] * np.sin(c)
    rel = (J[:, keep] - pred) / np.maximum(2 * amp[keep], 1e-6)
    resid = tuple(float(v) for v in np.sqrt(np.mean(rel**2, 1)))
    sign = -1.0 if field == "dark" else 1.0
    phase = np.arctan2(-sign * co[:, 2], sign * co[:, 1])
    near = np.hypot(xy[keep, 0], xy[keep, 1]) < 0.2 * radius
    pick = near if near.any() else np.argsort(np.hypot(xy[keep, 0], xy[keep, 1]))[:10]
    mean = np.angle(np.mean(np.exp(1j * phase[pick])))
    return resid, float((mean / (2 * np.pi) + 0.5) % 1.0 - 0.5)


def fit_disc_series(
    images: list[DiscImage],
    geometry: DiscGeometry,
    *,
    diameter: float,
    thickness: float,
    field: str = "dark",
    max_order: float = 12.0,
) -> SeriesFit:
    """The fringe value of a disc from a load series with frozen stress (module doc).

    Parameters
    ----------
    images : list of DiscImage
        The photographs (grey, one size) and their loads (N); at least
        :data:`MIN_SERIES` distinct loads (a zero-load reference counts).
    geometry : DiscGeometry
        The disc in the photographs (centre, radius px; load axis tilt).
    diameter, thickness : float
        The disc's diameter and thickness (m).
    field : {"dark", "bright"}
        The polariscope's field (it sets only the sign of the frozen order's phase).
    max_order : float
        Largest centre order of the highest load searched (fringes).

    Returns
    -------
    SeriesFit

    Raises
    ------
    InputError
        Fewer than :data:`MIN_SERIES` distinct loads, or a field other than dark/bright.

    Examples
    --------
    Five rendered photographs of a 40 mm, 6 mm disc (f_sigma 7000 N/m) with a frozen
    order of 0.7 fringe along the load's axes:

    >>> from fringekit.optics import DiametralDisc, dark_field_circular, intensity, retarder
    >>> r, c = np.mgrid[:112, :112] - 55.5
    >>> xy = np.stack([c, -r], -1) * (0.04 / 98)
    >>> s = DiametralDisc(P=1.0, D=0.04, t=0.006).stress(xy)
    >>> theta = 0.5 * np.arctan2(2 * s[..., 0, 1], s[..., 0, 0] - s[..., 1, 1])
    >>> images = []
    >>> for load in (100.0, 130.0, 160.0, 190.0, 230.0):
    ...     N = 0.006 * load * DiametralDisc(P=1.0, D=0.04, t=0.006).stress_difference(xy)
    ...     q = retarder(2 * np.pi * (np.nan_to_num(N) / 7000 + 0.7), theta)
    ...     images.append(DiscImage(intensity(q, dark_field_circular()), load))
    >>> fit = fit_disc_series(images, DiscGeometry(55.5, 55.5, 49.0), diameter=0.04,
    ...                       thickness=0.006)
    >>> round(fit.f_sigma, -1), round(fit.offset_order, 2), round(fit.r_squared, 3)
    (7000.0, -0.3, 1.0)
    """
    if field not in ("dark", "bright"):
        raise InputError(f"--field {field!r} is not allowed; use dark or bright")
    loads = np.array([im.load_N for im in images], float)
    if len(np.unique(loads)) < MIN_SERIES or not (loads > 0).any():
        raise InputError(
            f"--residual-field series: {len(np.unique(loads))} distinct load(s); allowed: at "
            f"least {MIN_SERIES} photographs at distinct loads (a zero-load --reference counts)"
        )
    R = geometry.radius_px
    stride = max(1, int(np.sqrt(np.pi * (FIT_RADIUS * R) ** 2 / SERIES_PIXELS)))
    rows, cols = disc_pixels(images[0].data.shape, geometry, stride)
    xy = disc_coordinates(rows, cols, geometry, diameter)
    st = DiametralDisc(P=1.0, D=diameter, t=thickness).stress(xy)
    s_abs = thickness * np.hypot(st[:, 0, 0] - st[:, 1, 1], 2 * st[:, 0, 1])
    J = _normalised(np.array([im.data[rows, cols] for im in images], float))
    g0, p_max = 8.0 / (np.pi * diameter), float(loads.max())
    per_order = 1.0 / (p_max * g0)
    kappa, trials = _kappa(J, loads, s_abs, per_order, max_order)
    scales = _load_scales(J, loads, s_abs, kappa)
    sector = np.floor((np.arctan2(xy[:, 1], xy[:, 0]) + np.pi) / (2 * np.pi) * SECTORS)
    sd, how = _jackknife(J, loads, s_abs, per_order, max_order, sector.astype(int) % SECTORS)
    resid, offset = _diagnostics(J, loads, s_abs, kappa, xy, diameter / 2, field)
    own = np.nan_to_num(scales, nan=0.0) * loads * g0 * kappa
    r2 = float(np.corrcoef(loads, own)[0, 1] ** 2) if len(loads) > 2 else 1.0
    return SeriesFit(
        1.0 / kappa,
        sd,
        offset,
        geometry,
        tuple(float(P * g0 * kappa) for P in loads),
        resid,
        how,
        trials,
        tuple(float(v) for v in scales),
        tuple(float(v) for v in own),
        r2,
    )
