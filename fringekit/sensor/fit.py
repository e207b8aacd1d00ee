"""The known-load frames' joint fit: the sheet's modulus and fringe-value scales, the
camera's response, the illumination and the sheet's rotation in the image.

Every known frame f is modelled as

    D_f(x) = lin_f(x) - lin_rest(x) = L(x) M_f(x; k, s, positions, rho) + o_f

with lin = ((v - b) / (1 - b)) ** gamma the linear intensity of a stored value v (black
level b), M_f the library's image of the frame's loads (read at F / k, stresses times k:
:meth:`~fringekit.library.store.Library.scaled`; fringe value times s; tangential loads
turned by rho from the sheet's axes into the image's), L(x) the illumination times the
exposure gain, a low-order polynomial (Legendre, total degree :data:`ILLUMINATION_DEGREE`)
shared by the frames per channel, and o_f an offset per frame and channel. L and o enter
linearly and are solved at every evaluation (variable projection, as ``invert`` solves
its gains); the residual is divided by the mean gain, so that a change of gamma, which
rescales the linear intensities, does not lower the cost by itself. The pixels within the
contact circles (widened) are left out, as ``invert`` leaves them out, and the mask is
held fixed during a fit.

For the six phase steps (C = 6), and for a grey sensor given six rest steps
(``residual_steps``), the rest is not subtracted (lin_rest = 0): the rest steps,
linearised at the gamma being tried, give the sheet's residual retarder
(:func:`~fringekit.inversion.rest.steps_retarder`, at the fringe value being tried), which
M_f holds in series with the loads' retardation; the six steps of a known frame share L
and o_f (one light, one exposure), as ``invert`` gives them one gain and offset.

The loads are known; the contacts' positions in the image are fitted (with a known
position, the start). The 1-sigma of the fitted values are those of a linear
least-squares problem at the solution (sigma^2 (J^T J)^-1, sigma^2 the residual's
variance) times the residual's correlation area (the largest of the frames':
:func:`~fringekit.inversion.uncertainty.correlation_area`, as ``invert`` states its
1-sigma): neighbouring pixels of a misfit fringe err together, so the frames carry fewer
independent values than pixels. The positions' and the rotation's add, in quadrature, the
model-error floor ``invert`` states its answers with
(:func:`~fringekit.inversion.uncertainty.model_sd`): the fit absorbs the library's own
error into them, which leaves no trace in the residual (:func:`direction_floor` for the
rotation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.polynomial import legendre
from scipy.optimize import least_squares

from fringekit.inversion.fit import EXACT_MM, subsample
from fringekit.inversion.model import ImageModel
from fringekit.inversion.rest import PHASE_STEPS, steps_retarder
from fringekit.inversion.uncertainty import correlation_area, model_sd, parameter_sd
from fringekit.library.calibrated import linearise
from fringekit.library.store import LoadedIndenter

__all__ = [
    "ILLUMINATION_DEGREE",
    "KnownFit",
    "UNDETERMINED_SD",
    "direction_floor",
    "fit_known",
    "illumination_basis",
]

#: Total degree of the illumination's polynomial (6 terms: vignetting and a tilt of the
#: light, which vary over the field of view, not from pixel to pixel).
ILLUMINATION_DEGREE = 2
#: The fit uses at most this many pixels a side per frame (every k-th pixel).
MAX_SIDE_PX = 160
#: Relative finite-difference step of the Jacobian: the library's float32 fields and
#: lattice interpolation make the image rough below it (scipy's default, 1.5e-8, gave
#: derivatives of that roughness and a fit stalled 9 % off in the modulus scale).
DIFF_STEP = 1e-4
#: Evaluations per fit at most.
MAX_NFEV = 100
#: The scales are fitted within [MIN_SCALE, 1 / MIN_SCALE].
MIN_SCALE = 0.3
#: Fringe-value scales tried for the start: a scale far from the truth puts the fit in a
#: basin of the wrong fringe count.
START_SCALES = np.geomspace(0.6, 1.6, 13)
#: Camera responses tried for the start: linear, and the usual encodings.
START_GAMMAS = (1.0, 1.8, 2.2, 2.6)


def illumination_basis(shape, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Legendre polynomials (n, J) of total degree <= ILLUMINATION_DEGREE at pixels
    (rows, cols) of an image of ``shape``, each coordinate mapped onto [-1, 1]; the first
    column is 1."""
    u = 2.0 * np.asarray(cols, float) / max(shape[1] - 1, 1) - 1.0
    v = 2.0 * np.asarray(rows, float) / max(shape[0] - 1, 1) - 1.0
    deg = ILLUMINATION_DEGREE
    full = legendre.legvander2d(v, u, [deg, deg])
    pick = [i * (deg + 1) + j for i in range(deg + 1) for j in range(deg + 1) if i + j <= deg]
    return full[:, pick]


#: A fitted scale (or the gamma) whose 1-sigma is above this fraction of its value is
#: reported as not determined by the known frames (the grey bench with six rest steps
#: left the modulus scale at 37 % and the gamma at 16 %; the six-step calibration of the
#: same sensor gives 5 % and 3 %).
UNDETERMINED_SD = 0.1


@dataclass(frozen=True)
class KnownFit:
    """The joint fit of the known frames.

    Attributes
    ----------
    modulus_scale, fringe_scale, gamma, rotation_deg : float
    sd : dict — their 1-sigma (``rotation_deg`` NaN when no frame has a tangential load)
    positions_mm : list of (n_f, 2) — every contact's axis in the image's axes (mm, about
        the grid's origin)
    position_sd_mm : list of (n_f, 2)
    coefficients : (J, C) — the illumination polynomial per channel (gain included)
    coefficient_cov : (C, J, J)
    residual_rms : (F,) — per frame, of the mean gain, within 3 mm of its contacts
    fitted, measured : list of (P_f, C) — per frame on the fitted pixels (figures)
    grid_shape : (rows, cols) of the fitted pixels
    at_bound : tuple of str — the scales and response that ended on a bound of the fit
        (not determined by the frames: a warning)
    """

    modulus_scale: float
    fringe_scale: float
    gamma: float
    rotation_deg: float
    sd: dict
    positions_mm: list
    position_sd_mm: list
    coefficients: np.ndarray
    coefficient_cov: np.ndarray
    residual_rms: np.ndarray
    fitted: list
    measured: list
    grid_shape: tuple
    at_bound: tuple = ()

    def undetermined(self, limit: float = UNDETERMINED_SD) -> tuple:
        """The scales and response whose stated 1-sigma exceeds ``limit`` of their value
        (not on a bound: those are :attr:`at_bound`): the known frames leave them open.

        Examples
        --------
        >>> import numpy as np
        >>> fit = KnownFit(1.07, 0.925, 2.10, 2.2, {"modulus_scale": 0.40,
        ...     "fringe_scale": 0.027, "gamma": 0.33}, [], [], np.zeros((1, 1)),
        ...     np.zeros((1, 1, 1)), np.zeros(1), [], [], (1, 1))
        >>> fit.undetermined()  # the grey bench with six rest steps: 37 % and 16 %
        ('modulus_scale', 'gamma')
        """
        return tuple(
            name
            for name in ("modulus_scale", "fringe_scale", "gamma")
            if name not in self.at_bound
            and not self.sd[name] <= limit * abs(getattr(self, name))  # NaN counts
        )


class _Problem:
    """The residual of the known frames as a function of the parameter vector
    [ln k, ln s, gamma, rho (if any tangential load), x, y of every contact]."""

    def __init__(self, base: ImageModel, frames, rest: np.ndarray, black, stride: int):
        self.frames, self.black = frames, np.asarray(black, float)
        self.stride, self.groups = stride, base.groups
        rows, cols = base.grid.shape
        pick = np.ix_(np.arange(0, rows, stride), np.arange(0, cols, stride))
        self.models = []
        for fr in frames:
            m = replace(base, measured=fr.raw.reshape(rows * cols, -1), usable=fr.usable)
            self.models.append(replace(subsample(m, stride), exact=EXACT_MM * 1e-3))
        self.sub_shape = self.models[0].grid.shape
        rr, cc = np.meshgrid(*(np.arange(0, n, stride) for n in (rows, cols)), indexing="ij")
        self.basis = illumination_basis((rows, cols), rr.ravel(), cc.ravel())
        self.rest = rest[pick].reshape(-1, rest.shape[-1])
        # six rest steps (phase, or a grey sensor's --residual-steps): the residual retarder
        self.steps = rest[pick] if rest.shape[-1] == PHASE_STEPS else None
        if self.steps is not None:  # where the residual is not read: held fixed
            _, unknown = steps_retarder(linearise(self.steps, self.black, 1.0), None, base.law)
            self.models = [replace(m, usable=m.usable & ~unknown) for m in self.models]
        self.law0 = base.law
        self.f0 = base.law.f_sigma
        self.lib0 = base.lib
        self.sheared = any(np.any(fr.loads[:, 2:4] != 0) for fr in frames)
        self.n_global = 4 if self.sheared else 3
        self.keep: list | None = None

    def indenters(self, theta: np.ndarray) -> list[list[LoadedIndenter]]:
        rho = theta[3] if self.sheared else 0.0
        c, s = math.cos(rho), math.sin(rho)
        xy = theta[self.n_global :].reshape(-1, 2)
        out, i = [], 0
        for fr in self.frames:
            inds = []
            for (_, _, fx, fy, fz), d in zip(fr.loads, fr.diameters_mm, strict=True):
                x, y = xy[i]
                i += 1
                inds.append(
                    LoadedIndenter(
                        x * 1e-3, y * 1e-3, d * 1e-3, c * fx - s * fy, s * fx + c * fy, fz
                    )
                )
            out.append(inds)
        return out

    def parts(self, theta: np.ndarray):
        """Per-frame model images M_f (P, C), measured D_f (P, C) and the pixels used."""
        k, s, gamma = math.exp(theta[0]), math.exp(theta[1]), theta[2]
        lib = self.lib0.scaled(k)
        law = replace(self.law0, f_sigma=self.f0 * s)
        ab, rest = self.at_rest(gamma, law)
        M, D, use = [], [], []
        for model, inds, j in zip(
            self.models, self.indenters(theta), range(len(self.models)), strict=True
        ):
            mf = replace(model, lib=lib, law=law, residual_ab=ab)
            lin, outside = mf.linear(inds)
            M.append(lin)
            D.append(linearise(model.measured, self.black, gamma) - rest)
            use.append(model.usable & (outside if self.keep is None else self.keep[j]))
        return M, D, use

    def at_rest(self, gamma: float, law):
        """(residual_ab (P, 2) or None, rest light (P, C) or 0): the phase method's rest
        steps read as the residual retarder (:func:`~fringekit.inversion.rest.steps_retarder`)
        at the response ``gamma`` and the sheet's ``law``, which the model holds; the
        dark-field methods' rest light, which is subtracted."""
        if self.steps is None:
            return None, linearise(self.rest, self.black, gamma)
        ab, _ = steps_retarder(linearise(self.steps, self.black, gamma), None, law)
        return ab, 0.0

    def solve_linear(self, M, D, use):
        """The illumination coefficients (J, C), offsets (F, C), fitted images and the
        normal matrices' inverses (C, J + F, J + F) on the used pixels: one illumination
        and offset per channel group (a colour channel; the grey image; the six phase
        steps together, which share the light and the exposure)."""
        F, J, C = len(M), self.basis.shape[1], M[0].shape[1]
        coef, offs = np.zeros((J, C)), np.zeros((F, C))
        cov = np.zeros((C, J + F, J + F))
        fitted = [np.zeros_like(m) for m in M]
        for g in self.groups:  # one to three groups
            pairs = [(f, c) for f in range(F) for c in g]
            A = np.concatenate([self._design(M[f][:, c], f, F)[use[f]] for f, c in pairs])
            b = np.concatenate([D[f][use[f], c] for f, c in pairs])
            x, *_ = np.linalg.lstsq(A, b, rcond=None)
            coef[:, g], offs[:, g] = x[:J, None], x[J:, None]
            r = b - A @ x
            cov[g] = float(r @ r) / max(len(b) - J - F, 1) * np.linalg.pinv(A.T @ A)
            for f, c in pairs:
                fitted[f][:, c] = self._design(M[f][:, c], f, F) @ x
        return coef, offs, fitted, cov

    def _design(self, m: np.ndarray, f: int, F: int) -> np.ndarray:
        e = np.zeros((len(m), F))
        e[:, f] = 1.0
        return np.concatenate([self.basis * m[:, None], e], axis=1)

    def residual(self, theta: np.ndarray) -> np.ndarray:
        M, D, use = self.parts(theta)
        coef, _, fitted, _ = self.solve_linear(M, D, use)
        gain = np.abs(coef[0]).mean() or 1.0
        return (
            np.concatenate([((D[f] - fitted[f]) * use[f][:, None]).ravel() for f in range(len(M))])
            / gain
        )


def _start_theta(problem: _Problem, starts: list, k0: float, scales=None) -> np.ndarray:
    """The start: modulus scale ``k0``, the fringe-value scale of START_SCALES and the
    response of START_GAMMAS with the least cost, no rotation (or ``scales``: k, s,
    gamma, rotation in degrees), the contacts where ``starts`` puts them."""
    xy = np.concatenate([np.asarray(s, float).reshape(-1, 2) for s in starts]).ravel()
    k, s, g, rot = scales if scales is not None else (k0, 1.0, 1.0, 0.0)
    head = [math.log(max(k, k0)), math.log(s), g] + ([math.radians(rot)] if problem.sheared else [])
    theta = np.concatenate([head, xy])
    problem.keep = None
    _, _, use = problem.parts(theta)
    problem.keep = [u.copy() for u in use]
    if scales is not None:
        return theta
    best = (math.inf, 0.0, 1.0)
    for g in START_GAMMAS:  # a small grid, each point a handful of synthesised frames
        for s in START_SCALES:
            t = theta.copy()
            t[1:3] = math.log(s), g
            best = min(best, (float(np.sum(problem.residual(t) ** 2)), math.log(s), g))
    theta[1:3] = best[1:]
    return theta


def fit_known(base: ImageModel, frames, rest, black, starts, scales=None) -> KnownFit:
    """Fit the known frames (module docstring).

    Parameters
    ----------
    base : ImageModel
        The library, optics and pixel grid of the frames (measured and usable unused).
    frames : list of :class:`~fringekit.sensor.frames.KnownFrame`
    rest : (rows, cols, C) stored values of the sheet at rest, or (rows, cols, 6) its six
        phase steps (read as the residual retarder)
    black : (C,) black level
    starts : list of (n_f, 2) start positions (mm, image axes about the grid's origin)
    scales : (k, s, gamma, rotation_deg), optional
        The start of a fit made before (no scan of the scales).
    """
    rows, cols = base.grid.shape
    stride = max(1, math.ceil(max(rows, cols) / MAX_SIDE_PX))
    problem = _Problem(base, frames, rest, black, stride)
    # k no smaller than puts a known load beyond the library (its fields are clamped there)
    k_min = max(MIN_SCALE, max(float(fr.loads[:, 4].max()) for fr in frames) / base.lib.max_load_N)
    theta = _start_theta(problem, starts, max(1.0, k_min * (1 + 1e-6)), scales)
    n = problem.n_global
    lo = np.full(theta.size, -np.inf)
    hi = np.full(theta.size, np.inf)
    lo[:3] = [math.log(k_min), math.log(MIN_SCALE), 0.2]
    hi[:3] = [math.log(1.0 / MIN_SCALE), math.log(1.0 / MIN_SCALE), 5.0]
    res = None
    for _ in range(2):  # the second fit with the contact circles where the first put them
        res = least_squares(
            problem.residual,
            theta,
            bounds=(lo, hi),
            diff_step=DIFF_STEP,
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=MAX_NFEV,
        )
        theta = res.x
        problem.keep = None
        _, _, use = problem.parts(theta)
        problem.keep = [u.copy() for u in use]
    M, D, use = problem.parts(theta)
    coef, _, fitted, ccov = problem.solve_linear(M, D, use)
    area = max(
        correlation_area((d - f).reshape(*problem.sub_shape, -1), u.reshape(problem.sub_shape))
        for d, f, u in zip(D, fitted, use, strict=True)
    )
    sd = np.sqrt(area) * parameter_sd(res.jac, res.fun, len(res.fun))
    ccov = area * ccov
    k, s = math.exp(theta[0]), math.exp(theta[1])
    rho = theta[3] if problem.sheared else 0.0
    floor = model_sd(base.lib.shear_ratio)
    xy = theta[n:].reshape(-1, 2)
    xy_sd = np.hypot(sd[n:].reshape(-1, 2), floor[:2])
    rho_sd = math.hypot(sd[3], direction_floor(frames, floor[3])) if problem.sheared else math.nan
    split = np.cumsum([len(fr.loads) for fr in frames])[:-1]
    gain = np.abs(coef[0]).mean() or 1.0
    return KnownFit(
        modulus_scale=k,
        fringe_scale=s,
        gamma=float(theta[2]),
        rotation_deg=math.degrees(rho),
        sd={
            "modulus_scale": k * sd[0],
            "fringe_scale": s * sd[1],
            "gamma": float(sd[2]),
            "rotation_deg": math.degrees(rho_sd),
        },
        positions_mm=np.split(xy, split),
        position_sd_mm=np.split(xy_sd, split),
        coefficients=coef,
        coefficient_cov=ccov[:, : coef.shape[0], : coef.shape[0]],
        residual_rms=_frame_rms(problem, theta, D, fitted, use, gain),
        fitted=fitted,
        measured=D,
        grid_shape=problem.sub_shape,
        at_bound=tuple(
            name
            for name, v, a, b in zip(
                ("modulus_scale", "fringe_scale", "gamma"), theta[:3], lo[:3], hi[:3], strict=True
            )
            if min(v - a, b - v) < 1e-6 * max(1.0, abs(v))
        ),
    )


def direction_floor(frames, tangential_floor: float) -> float:
    """The model-error floor (rad) of the rotation the known frames' tangential loads
    give: each contact's load direction errs by ``tangential_floor`` Fz / Ft (rad; the
    floor of a tangential component, :func:`~fringekit.inversion.uncertainty.model_sd`,
    is a fraction of Fz), the contacts' combined by inverse variance. Infinite without
    a tangential load.

    Examples
    --------
    Two contacts, each with a tangential load of a quarter of Fz, a floor of 0.011 Fz:

    >>> from types import SimpleNamespace
    >>> fr = SimpleNamespace(loads=np.array([[0, 0, 0.5, 0, 2.0], [0, 0, 0, 1.0, 4.0]]))
    >>> round(math.degrees(direction_floor([fr], 0.011)), 3)
    1.783
    """
    loads = np.concatenate([np.asarray(fr.loads, float) for fr in frames])
    loads = loads[loads[:, 4] > 0]  # a contact without normal load gives no direction
    ratio = np.hypot(loads[:, 2], loads[:, 3]) / loads[:, 4]
    weight = float(np.sum((ratio / tangential_floor) ** 2))
    return 1.0 / math.sqrt(weight) if weight > 0 else math.inf


def _frame_rms(problem: _Problem, theta, D, fitted, use, gain: float) -> np.ndarray:
    """Per frame: the RMS residual over the used pixels within 3 mm of its contacts, of
    the mean gain."""
    out = []
    for model, inds, d, f, u in zip(
        problem.models, problem.indenters(theta), D, fitted, use, strict=True
    ):
        xy = model.xy
        near = np.zeros(len(xy), bool)
        for ind in inds:
            near |= np.hypot(xy[:, 0] - ind.x, xy[:, 1] - ind.y) < 3e-3
        pick = u & near
        r = (d - f)[pick]
        out.append(float(np.sqrt(np.mean(r**2)) / gain) if r.size else math.nan)
    return np.array(out)
