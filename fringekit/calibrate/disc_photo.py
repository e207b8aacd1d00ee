"""The material fringe value fitted directly to photographs of a disc in compression.

A disc of diameter D under a diametral load P has Frocht's closed-form field; in
transmission its fringe order is N(x) = P g(x) / f_sigma with g = t (sigma1 - sigma2) at
P = 1 N (:class:`optics.DiametralDisc`); at the centre g = 8 / (pi D), so the centre
order is 8 P / (pi D f_sigma) (Frocht, *Photoelasticity* Vol. 2, Wiley 1948). Behind a
circular polariscope in monochromatic light the photograph is

    I_k(x) = b_k + a_k(x) sin^2(pi (P_k g(x) / f_sigma + N_0))      (dark field; cos^2 bright)

with a_k(x) = a0 + a1 x + a2 y + a3 r^2 the illumination (uniform, tilt, vignetting), b_k
the background, and N_0 a residual order common to the series (frozen-in stress along
the load's principal axes), fitted - uniform, it is told apart from the load's order
even in one photograph, and a zero-load ``reference`` pins it further.

The fit is variable projection (Golub and Pereyra, SIAM J. Numer. Anal. 10, 1973): for
given 1/f_sigma, N_0 and the load axis angle the model is linear in a_k, b_k, which are
solved exactly; the outer least-squares (``scipy.optimize.least_squares``, soft-L1 loss)
starts from the best point of a vectorised grid over the centre order of the highest
load and N_0, since sin^2 has a minimum every half fringe. With several loads the fringe
value follows from the slope of order against load, so N_0 does not bias it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from fringekit.errors import InputError
from fringekit.optics import DiametralDisc

__all__ = ["DiscImage", "DiscFit", "fit_disc_photos", "disc_pixels", "REFUSE_RESIDUAL"]

#: RMS residual (fraction of the fringe amplitude) above which a photo is not explained
#: by Frocht's field: refused.
REFUSE_RESIDUAL = 0.25
#: ... and above which the result carries a warning (fits of rendered realistic photos
#: leave 0.011-0.014; fixing a residual order of 0.1 fringe at zero leaves 0.046).
WARN_RESIDUAL = 0.04

#: Pixels used: within this fraction of the radius, and farther than LOAD_POINT_GAP D
#: from the load points (fringes there are denser than the pixels).
FIT_RADIUS = 0.9
LOAD_POINT_GAP = 0.15
MAX_PIXELS = 20000
#: Pixels per image of the starting grid search.
GRID_PIXELS = 2500
#: Largest tilt (rad) of the load axis from the image's vertical that the fit explores.
MAX_ANGLE = 0.1
#: Largest change of the centre or radius (fraction of the radius) the fit explores.
GEOMETRY_MARGIN = 0.05


@dataclass(frozen=True)
class DiscImage:
    """One photograph of the disc: grey intensities (rows, cols) in [0, 1] and the load
    (N; 0 for a zero-load reference)."""

    data: np.ndarray
    load_N: float
    name: str = ""


@dataclass(frozen=True)
class DiscGeometry:
    """Where the disc is in the photographs (all of one series): centre (row, col) px,
    radius (px), and the load axis's tilt from the image vertical (rad, + anticlockwise)."""

    row: float
    col: float
    radius_px: float
    angle_rad: float = 0.0


@dataclass(frozen=True)
class DiscFit:
    """Result: f_sigma (N/m per fringe) and its 1-sigma, the residual order N_0, the
    fitted geometry, per image the centre order of the load
    (without N_0) and the RMS residual (fraction of the fringe amplitude), and how the
    uncertainty was found."""

    f_sigma: float
    f_sigma_sd: float
    offset_order: float
    geometry: DiscGeometry
    centre_orders: tuple[float, ...]
    residuals: tuple[float, ...]
    sd_method: str
    evaluations: int


def disc_pixels(shape, geometry: DiscGeometry, stride: int | None = None):
    """(rows, cols) of the fit pixels: within :data:`FIT_RADIUS` of the radius and away
    from the load points, with a margin for the refinement of the geometry (the fit
    needs the same pixels at every step)."""
    R = geometry.radius_px
    if stride is None:
        stride = max(1, int(np.sqrt(np.pi * (FIT_RADIUS * R) ** 2 / MAX_PIXELS)))
    r, c = np.mgrid[0 : shape[0] : stride, 0 : shape[1] : stride]
    dx, dy = c - geometry.col, geometry.row - r
    keep = np.hypot(dx, dy) <= (FIT_RADIUS - GEOMETRY_MARGIN) * R
    gap = (LOAD_POINT_GAP * 2 + MAX_ANGLE + GEOMETRY_MARGIN) * R
    keep &= (np.hypot(dx, dy - R) > gap) & (np.hypot(dx, dy + R) > gap)
    return r[keep], c[keep]


def disc_coordinates(rows, cols, geometry: DiscGeometry, diameter: float) -> np.ndarray:
    """(n, 2) m: pixel centres in the disc's frame (x across, y along the load axis)."""
    dx, dy = cols - geometry.col, geometry.row - rows
    ca, sa = np.cos(geometry.angle_rad), np.sin(geometry.angle_rad)
    u, v = ca * dx + sa * dy, -sa * dx + ca * dy
    return np.column_stack([u, v]) * (diameter / (2 * geometry.radius_px))


def _shape(xy: np.ndarray, diameter: float, thickness: float) -> np.ndarray:
    """g(x) = t (sigma1 - sigma2) per newton of load (1/m): N = P g / f_sigma."""
    return thickness * DiametralDisc(P=1.0, D=diameter, t=thickness).stress_difference(xy)


def _basis(xy: np.ndarray, diameter: float) -> np.ndarray:
    """(n, 4) illumination basis 1, x, y, r^2 (normalised by the radius)."""
    x, y = xy[:, 0] / (diameter / 2), xy[:, 1] / (diameter / 2)
    return np.column_stack([np.ones_like(x), x, y, x * x + y * y])


def _project(S: np.ndarray, basis: np.ndarray, b: np.ndarray, vectors: bool = True):
    """Batched variable projection: for fringe terms S (K, n), the least-squares image
    S (basis @ c[:4]) + c[4] against b (n,), by its 5 x 5 normal equations built from
    matrix products over the pixels. Returns (residual vectors (K, n), or residual sums of
    squares (K,) when not ``vectors``; the amplitude c0 (K,))."""
    K, n = S.shape
    m = basis.shape[1]
    pairs = (basis[:, :, None] * basis[:, None, :]).reshape(n, m * m)
    AtA = np.empty((K, m + 1, m + 1))
    AtA[:, :m, :m] = ((S * S) @ pairs).reshape(K, m, m)
    AtA[:, :m, m] = AtA[:, m, :m] = S @ basis
    AtA[:, m, m] = n
    Atb = np.empty((K, m + 1))
    Atb[:, :m] = S @ (basis * b[:, None])
    Atb[:, m] = b.sum()
    coef = np.linalg.solve(AtA + 1e-12 * np.eye(m + 1), Atb[..., None])[..., 0]
    if not vectors:
        return np.maximum(float(b @ b) - np.einsum("ki,ki->k", coef, Atb), 0.0), coef[:, 0]
    return b - S * (coef[:, :m] @ basis.T) - coef[:, m:], coef[:, 0]


class _Problem:
    """The data of a fit: per image the sampled intensities; g and the illumination basis
    at the current geometry."""

    def __init__(self, images, geometry, diameter, thickness, field, fit_offset, shared=False):
        self.images, self.D, self.t = images, diameter, thickness
        self.field, self.fit_offset, self.shared = field, fit_offset, shared
        self.loads = np.array([im.load_N for im in images], float)
        self.g0 = 8.0 / (np.pi * diameter)  # g at the centre
        self.evaluations = 0
        self.rows, self.cols = disc_pixels(images[0].data.shape, geometry)
        self.values = [im.data[self.rows, self.cols] for im in images]
        # the residual scales are properties of the sampled photographs: computed once
        self.spreads = [_spread(v) for v in self.values]
        self.stack_spread = _spread(np.concatenate(self.values))
        self.geometry = None
        self.at(geometry)

    def at(self, geometry: DiscGeometry) -> None:
        if geometry == self.geometry:
            return
        self.geometry = geometry
        xy = disc_coordinates(self.rows, self.cols, geometry, self.D)
        self.g, self.basis = _shape(xy, self.D, self.t), _basis(xy, self.D)

    def fringe(self, N: np.ndarray) -> np.ndarray:
        s = np.sin(np.pi * N) ** 2
        return s if self.field == "dark" else 1.0 - s

    def residuals(self, kappa: np.ndarray, offset: np.ndarray, sub=slice(None), vectors=True):
        """Per image the residuals over the image's spread (robust sd of its sampled
        intensities) for K candidates (1/f_sigma, N_0) - vectors (K, n) or, not
        ``vectors``, mean squares (K,) - and the fringe amplitudes; on the pixels ``sub``."""
        self.evaluations += len(kappa)
        g, basis = self.g[sub], self.basis[sub]
        if self.shared:  # one light for all: one projection over the stacked photographs
            g = np.concatenate([P * g for P in self.loads])
            basis = np.tile(basis, (len(self.loads), 1))
            b = np.concatenate([v[sub] for v in self.values])
            N = g[None, :] * kappa[:, None] + offset[:, None]
            res, amp = _project(self.fringe(N), basis, b, vectors)
            whole = isinstance(sub, slice) and sub == slice(None)
            scale = self.stack_spread if whole else _spread(b)
            return [(res / scale if vectors else res / scale**2 / len(g), amp)]
        out = []
        for P, b, scale in zip(self.loads, self.values, self.spreads, strict=True):
            N = P * g[None, :] * kappa[:, None] + offset[:, None]
            res, amp = _project(self.fringe(N), basis, b[sub], vectors)
            out.append((res / scale if vectors else res / scale**2 / len(g), amp))
        return out

    def cost(self, kappa, offset, sub=slice(None)) -> np.ndarray:
        """Mean squared relative residual summed over the images, (K,); infinite where a
        fringe amplitude is not positive (a flipped pattern mimics half a fringe of N_0)."""
        parts = self.residuals(kappa, offset, sub, vectors=False)
        total = sum(ms for ms, _ in parts)
        return np.where(np.all([amp > 0 for _, amp in parts], axis=0), total, np.inf)


def _spread(b: np.ndarray) -> float:
    """Robust spread of sampled intensities: half the 2-98 % range (a floor of 1e-3)."""
    lo, hi = np.percentile(b, [2.0, 98.0])
    return max(0.5 * float(hi - lo), 1e-3)


def _grid_start(pb: _Problem, max_order: float) -> tuple[float, float]:
    """Best (1/f_sigma, N_0) on a grid: centre order of the highest load 0.02-max_order
    in steps of 0.02 fringe; N_0 -0.45..0.5 in steps of 0.05 when fitted."""
    p_max = float(pb.loads.max())
    n_c = np.arange(0.02, max_order + 1e-9, 0.02)
    offsets = np.arange(-0.45, 0.501, 0.05) if pb.fit_offset else np.zeros(1)
    sub = np.arange(0, len(pb.g), max(1, len(pb.g) // GRID_PIXELS))
    best, arg = np.inf, (0.0, 0.0)
    for off in offsets:
        for chunk in np.array_split(n_c, max(1, len(n_c) // 100)):
            kappa = chunk / (p_max * pb.g0)
            cost = pb.cost(kappa, np.full_like(kappa, off), sub)
            k = int(np.argmin(cost))
            if cost[k] < best:
                best, arg = float(cost[k]), (float(kappa[k]), float(off))
    return arg


def _geometry(g0: DiscGeometry, p) -> DiscGeometry:
    """The geometry at parameters p[2:] = (angle, d_row, d_col, d_log_radius)."""
    R = g0.radius_px
    return DiscGeometry(g0.row + p[3] * R, g0.col + p[4] * R, R * np.exp(p[5]), float(p[2]))


def _refine(pb: _Problem, start: tuple[float, float], geometry: DiscGeometry):
    """least_squares over (centre order of the highest load, N_0, load axis angle, centre
    and radius)."""
    p_max = float(pb.loads.max())

    def fun(p):
        pb.at(_geometry(geometry, p))
        kappa = np.array([p[0] / (p_max * pb.g0)])
        offset = np.array([p[1] if pb.fit_offset else 0.0])
        parts = [res[0] / np.sqrt(len(res[0])) for res, _ in pb.residuals(kappa, offset)]
        return np.concatenate(parts)

    m = GEOMETRY_MARGIN
    x0 = [start[0] * p_max * pb.g0, start[1], geometry.angle_rad, 0.0, 0.0, 0.0]
    sol = least_squares(
        fun,
        x0,
        loss="soft_l1",
        f_scale=0.1,
        x_scale=[0.05, 0.05, 0.01, 0.005, 0.005, 0.005],
        bounds=([1e-4, -0.5, -MAX_ANGLE, -m, -m, -m], [np.inf, 0.5, MAX_ANGLE, m, m, m]),
    )
    pb.at(_geometry(geometry, sol.x))
    return sol


def _per_image(pb: _Problem, kappa: float, offset: float):
    """Centre orders (load part) and RMS residuals relative to the fringe amplitude, per
    photograph (sliced from the stacked residual after a shared-light fit)."""
    centre = tuple(float(P * pb.g0 * kappa) for P in pb.loads)
    parts = pb.residuals(np.array([kappa]), np.array([offset]))
    if pb.shared:
        res, amp = parts[0]
        scaled = res[0] * pb.stack_spread / max(float(amp[0]), 1e-6)
        resid = [float(np.sqrt(np.mean(r**2))) for r in np.split(scaled, len(pb.values))]
    else:
        resid = [
            float(np.sqrt(np.mean(res[0] ** 2)) * s / max(float(amp[0]), 1e-6))
            for (res, amp), s in zip(parts, pb.spreads, strict=True)
        ]
    return centre, tuple(resid)


#: Angular sectors of the disc left out in turn for the uncertainty of one photograph.
SECTORS = 8


def _refit_kappa(pb: _Problem, start: tuple[float, float], keep=None) -> float:
    """1/f_sigma refitted at fixed geometry (and N_0 when fitted), on the pixels ``keep``."""
    p_max = float(pb.loads.max())
    sel = slice(None) if keep is None else keep

    def fun(p):
        kappa = np.array([p[0] / (p_max * pb.g0)])
        offset = np.array([p[1] if pb.fit_offset else 0.0])
        return np.concatenate([r[0] for r, _ in pb.residuals(kappa, offset, sel)])

    sol = least_squares(
        fun,
        [start[0] * p_max * pb.g0, start[1]],
        loss="soft_l1",
        f_scale=0.1,
        bounds=([1e-4, -0.5], [np.inf, 0.5]),
    )
    return float(sol.x[0] / (p_max * pb.g0))


def _jackknife(pb: _Problem, images, start, by_image: bool) -> tuple[float, str]:
    """1-sigma of f_sigma by the delete-a-group jackknife (Efron and Stein, Ann. Stat. 9,
    1981): groups are the photographs (three or more loaded ones) or the disc's
    :data:`SECTORS` angular sectors (one photograph: neighbouring pixels share their
    errors, so they are left out together). Geometry stays at the full fit's."""
    fs = []
    if by_image:
        for k in range(len(images)):
            rest = [im for i, im in enumerate(images) if i != k]
            if any(im.load_N > 0 for im in rest):
                sub = _Problem(rest, pb.geometry, pb.D, pb.t, pb.field, pb.fit_offset, pb.shared)
                fs.append(1.0 / _refit_kappa(sub, start))
        how = f"jackknife over {len(fs)} photographs"
    else:
        xy = disc_coordinates(pb.rows, pb.cols, pb.geometry, pb.D)
        sector = (
            np.floor((np.arctan2(xy[:, 1], xy[:, 0]) + np.pi) / (2 * np.pi) * SECTORS).astype(int)
            % SECTORS
        )
        for k in range(SECTORS):
            fs.append(1.0 / _refit_kappa(pb, start, sector != k))
        how = f"jackknife over {SECTORS} sectors of the disc"
    n = len(fs)
    sd = (
        float(np.sqrt((n - 1) / n * np.sum((np.array(fs) - np.mean(fs)) ** 2))) if n > 1 else np.nan
    )
    return sd, how


def fit_disc_photos(
    images: list[DiscImage],
    geometry: DiscGeometry,
    *,
    diameter: float,
    thickness: float,
    field: str = "dark",
    fit_offset: bool = True,
    shared_light: bool = False,
    max_order: float = 12.0,
) -> DiscFit:
    """f_sigma of a disc from one or more photographs at known loads (module doc).

    ``fit_offset`` fits the common residual order N_0 (it is separable from the load's
    order even in one photograph: N_0 is uniform, Frocht's order is not).
    ``shared_light``: all photographs share one illumination and background (the same
    light and exposure) - what lets a zero-load reference (load 0, N = N_0 everywhere)
    fix N_0. The 1-sigma of f_sigma is a jackknife (:func:`_jackknife`).
    """
    if field not in ("dark", "bright"):
        raise InputError(f"--field {field!r} is not allowed; use dark or bright")
    loaded = [im for im in images if im.load_N > 0]
    if not loaded:
        raise InputError("--load-N: at least one photograph must carry a load > 0")
    pb = _Problem(images, geometry, diameter, thickness, field, fit_offset, shared_light)
    start = _grid_start(pb, max_order)
    sol = _refine(pb, start, geometry)
    p_max = float(pb.loads.max())
    kappa, offset = sol.x[0] / (p_max * pb.g0), float(sol.x[1])
    fitted = pb.geometry
    if not fit_offset:
        offset = 0.0
    centre, resid = _per_image(pb, kappa, offset)
    f = 1.0 / kappa
    sd, how = _jackknife(pb, images, (kappa, offset), len(loaded) >= 3)
    return DiscFit(f, sd, offset, fitted, centre, resid, how, pb.evaluations)
