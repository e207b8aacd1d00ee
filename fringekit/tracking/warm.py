"""The warm fit of a tracked frame: Gauss-Newton steps with a Jacobian kept from frame to
frame (the chord method: J. M. Ortega and W. C. Rheinboldt, *Iterative Solution of
Nonlinear Equations in Several Variables*, 1970, sec. 7.1).

The fit is ``invert``'s (:class:`~fringekit.inversion.model.ImageModel`: the library's
superposed fields through the polariscope, the exposure's gain and offset solved exactly
at every evaluation, the range penalty of the tangential load). What differs is the
Jacobian: finite differences cost one batch of syntheses per contact, so a contact's
columns are made again only when it has moved more than JAC_MOVE_MM, or its loads by
more than JAC_LOAD of the library's largest, since they were made; between, Broyden's
rank-one update keeps them exact along the steps taken. A step that raises the cost
makes every column again. A contact's columns are the spatial pattern of its fringes:
they turn over within a fringe spacing (about 0.5 mm near a contact), so a Jacobian kept
over larger moves steers the fit to a point where the residual is orthogonal to the
wrong columns, not to the minimum.
"""

from __future__ import annotations

from collections import deque
from dataclasses import replace

import numpy as np

from fringekit.inversion.fit import fit_bounds
from fringekit.inversion.model import N_PARAMS, ImageModel, range_penalty, unpack
from fringekit.inversion.quick import penalised_residual
from fringekit.inversion.uncertainty import floor_sd, model_sd

__all__ = [
    "CHORD_STEPS",
    "FTOL",
    "GAIN_TOL",
    "JAC_LOAD",
    "JAC_MOVE_MM",
    "MISFIT",
    "SETTLE",
    "STEP_TOL",
    "ChordFit",
]

#: Gauss-Newton steps per frame at most.
CHORD_STEPS = 10
#: The Jacobian is made again when a contact has moved this far (mm) since it was made...
JAC_MOVE_MM = 0.1
#: ... or one of its loads changed by this fraction of the library's largest load.
JAC_LOAD = 0.05
#: The fit has converged when a step changes the cost by less than this many noise
#: variances, up or down (the parameters are then within about one sd of the minimum
#: along every direction, as far as the cost resolves it: bilinear in the lattice, it
#: wanders by 1-3 variances about its minimum even with a fresh Jacobian), or moves no
#: parameter by more than STEP_TOL (mm and N). A rise within it ends the fit without
#: making the Jacobian again. On the track bench (256 x 256 px, four contacts) this took
#: the warm frame from 133 to 46 ms median (from 0.1 variance, where a rise remade every
#: column) and left the errors as they were.
FTOL = 1.0
STEP_TOL = 1e-5
#: ... or before a step, when the fall of the cost the linear model predicts for it is
#: below GAIN_TOL * FTOL noise variances: the step is then within sqrt(GAIN_TOL) = 0.5
#: sd of where it starts (the predicted fall is the step's squared Mahalanobis length
#: in noise variances), and evaluating it would only confirm that. On the track bench
#: this took the frame's evaluations from 4.6 to 4.0 (mean), the errors as they were;
#: at GAIN_TOL 1 they fell to 3.0, but a noise-free 16-bit stream then stopped 2 um
#: short of the minimum, against the 1 um it is tracked to.
GAIN_TOL = 0.25
#: Where the model's misfit, not the camera's noise, makes the cost (above MISFIT noise
#: variances a pixel: FEM frames and photographs, against the library's own fields), the
#: cost falls by 0.2-0.5 % a step at steps of 5-20 um for many steps (a valley of the
#: misfit, not of the noise), and the tests above seldom pass: on the FEM sequence of
#: ``bench/track.py`` 16 of 18 warm rgb frames ended unconverged (the steps ran out, or
#: a fresh Jacobian's halved step still raised the cost), each then fitted again
#: robustly (2-4 s). There the fit also ends when the frame before ended
#: misfit-dominated too (a touch's unmodelled fringes make one frame's cost the
#: model's: stopped early there, a crossing contact was left 0.5 mm behind), every
#: Jacobian column was made in this frame (a kept one's small step held a contact's
#: tangential direction 23 degrees off), and the Gauss-Newton step moves no parameter
#: by more than SETTLE of the model-error floor
#: (:func:`~fringekit.inversion.uncertainty.model_sd`: 11 um, 0.55 % of Fz, 0.28 % of Fz
#: in the tangential loads on the default library). On the FEM sequence this took the
#: warm frame from 89 to 60 ms (mono) and 775 to 143 ms (rgb) median, 95th percentile
#: 2.6 and 4.4 s to 113 and 254 ms, and the median errors fell (docs/library.md). A
#: large residual makes Gauss-Newton's steps short of the least-squares minimum
#: (J. Nocedal and S. J. Wright, *Numerical Optimization*, 2nd ed., 2006, sec. 10.3):
#: on a frame with 0.1 fringe of frozen stress the fit stopped 3 floors short of it,
#: the minimum itself 0.6 mm from the truth.
MISFIT = 4.0
SETTLE = 0.25
#: A step that raises the cost with a Jacobian made at its start is halved at most this
#: many times (a backtracking line search).
HALVINGS = 3


class ChordFit:
    """The warm fit's state: the Jacobian kept (image rows, one block of five columns per
    contact), the parameters it was made at, and the last evaluation.

    Parameters
    ----------
    noise : float
        The frames' noise sd (intensity): the range penalty's scale and the convergence
        test's unit.

    Examples
    --------
    See :class:`~fringekit.tracking.tracker.Tracker`, which runs one per stream.
    """

    def __init__(self, noise: float):
        self.noise = float(noise)
        self.jac: np.ndarray | None = None
        self.p_jac = np.zeros(0)
        self.last: tuple | None = None  # (p, residuals, gains) of the last evaluation
        #: whether the last frame's fit ended with a cost that is the model's misfit
        self.misfit = False
        #: (model, p, every contact's slab pairs) of the last two evaluations: the
        #: Jacobian made at one of them reuses its fields (five interpolations a refresh)
        self.fields: deque = deque(maxlen=2)

    def forget(self) -> None:
        """Another set of contacts: the Jacobian and the last evaluation are void."""
        self.jac = None
        self.last = None
        self.misfit = False
        self.fields.clear()

    def run(self, sub: ImageModel, p: np.ndarray, diam: list) -> tuple[np.ndarray, bool]:
        """Chord steps from ``p`` (n * 5,) on ``sub``: (the parameters, whether the fit
        converged)."""
        lo, hi = fit_bounds(sub, len(diam))
        fixed = replace(sub, keep=sub.outside_contacts(unpack(p, diam)))
        r, gains = self.residual(fixed, p, diam)
        due = self.stale(p, diam, sub.lib)
        self.refresh(fixed, p, diam, due)
        cost = float(r @ r)
        self.last = (p, r, gains)
        fresh, done = False, False
        made = len(due) == len(diam)  # every column made in this frame (or since)
        steady, self.misfit = self.misfit, False  # the misfit the frame before had
        for _ in range(CHORD_STEPS):  # a few steps; each one synthesis of the image
            step, gain = self._solve(p, r, sub.lib)
            if gain <= GAIN_TOL * self._ftol(cost):  # the next step would not pay: converged
                done = True
                break
            if made and steady and self._settled(p, step, r, sub.lib):  # (the model's error)
                done = True
                break
            pn = np.clip(p + step, lo, hi)
            rn, gains = self.residual(fixed, pn, diam)
            cn = float(rn @ rn)
            if cn > cost and fresh:  # the model bends within the step: halve it
                for _ in range(HALVINGS):
                    step = 0.5 * step
                    pn = np.clip(p + step, lo, hi)
                    rn, gains = self.residual(fixed, pn, diam)
                    cn = float(rn @ rn)
                    if cn <= cost:
                        break
            if cn > cost:
                within = cn <= cost + self._ftol(cost)  # at the noise floor already
                if fresh or within:  # (a fresh Jacobian's halved step within the
                    # model's error, where it makes the cost: at what the model resolves)
                    done = within or (steady and fresh and self._settled(p, step, r, sub.lib))
                    break
                self.refresh(fixed, p, diam, np.arange(len(diam)))
                fresh = made = True
                continue
            self._broyden(pn - p, rn[: len(self.jac)] - r[: len(self.jac)])
            done = cost - cn <= self._ftol(cost) or bool(np.all(np.abs(pn - p) <= STEP_TOL))
            p, r, cost = pn, rn, cn
            self.last = (p, r, gains)
            if done:
                break
        self.misfit = self._misfit(r)
        return p, done

    def _misfit(self, r: np.ndarray) -> bool:
        """Whether the image's residuals ``r`` are the model's misfit, not the camera's
        noise: above MISFIT noise variances a pixel."""
        image = r[: len(self.jac)]
        return float(image @ image) > MISFIT * np.count_nonzero(image) * self.noise**2

    def _settled(self, p: np.ndarray, step: np.ndarray, r: np.ndarray, lib) -> bool:
        """Whether the cost is the model's misfit (:meth:`_misfit`) and ``step`` moves
        no parameter by more than SETTLE of its model-error floor (positions in mm;
        loads as fractions of Fz, or of the library's first load for a lighter
        contact)."""
        if not self._misfit(r):
            return False
        floor = floor_sd(model_sd(lib.shear_ratio), p, float(lib.load_N[1]))
        return bool(np.all(np.abs(step) <= SETTLE * floor.ravel()))

    def _ftol(self, cost: float) -> float:
        """The least change of the cost that is worth another step: FTOL noise
        variances (what the cost resolves), or 1e-6 of the cost where the misfit is the
        model's."""
        return max(FTOL * self.noise**2, 1e-6 * cost)

    def stale(self, p: np.ndarray, diam: list, lib) -> np.ndarray:
        """The contacts (indices) whose Jacobian columns are due: moved JAC_MOVE_MM or
        their loads by JAC_LOAD of the library's largest since they were made."""
        if self.jac is None or len(self.p_jac) != len(p):
            return np.arange(len(diam))
        d = np.abs(p - self.p_jac).reshape(-1, N_PARAMS)
        load = JAC_LOAD * lib.max_load_N
        due = (np.hypot(d[:, 0], d[:, 1]) > JAC_MOVE_MM) | np.any(d[:, 2:] > load, axis=1)
        return np.flatnonzero(due)

    def refresh(self, fixed: ImageModel, p: np.ndarray, diam: list, which) -> None:
        """Make the Jacobian columns of the contacts ``which`` again at ``p``."""
        which = np.asarray(which, int)
        if not len(which):
            return
        cols = (which[:, None] * N_PARAMS + np.arange(N_PARAMS)).ravel()
        own = next((f for m, q, f in self.fields if m is fixed and np.array_equal(q, p)), None)
        part = fixed.jacobian(p, diam, which=which, own=own)
        if self.jac is None or len(which) == len(diam) or len(self.p_jac) != len(p):
            self.jac = np.zeros((part.shape[0], len(p)))
            self.p_jac = p.copy()
        self.jac[:, cols] = part
        self.p_jac[cols] = p[cols]

    def _broyden(self, dp: np.ndarray, dr: np.ndarray) -> None:
        """Broyden's rank-one update of the kept Jacobian along an accepted step (C. G.
        Broyden, "A class of methods for solving nonlinear simultaneous equations", Math.
        Comp. 19, 1965): the image's change ``dr`` is then exact along ``dp``."""
        nn = float(dp @ dp)
        if nn > 0:
            self.jac += np.outer(dr - self.jac @ dp, dp / nn)

    def residual(self, fixed: ImageModel, p: np.ndarray, diam: list):
        """Residuals of the image (P * C,) and of the range penalty, and the gains (C,)
        (:func:`~fringekit.inversion.quick.penalised_residual`); the contacts' fields
        are kept for a Jacobian made at ``p``."""
        r, gains, own = penalised_residual(fixed, p, diam, self.noise)
        self.fields.append((fixed, p.copy(), own))
        return r, gains

    def full_jacobian(self, p: np.ndarray, lib) -> np.ndarray:
        """The kept Jacobian with the range penalty's rows made at ``p``."""
        _, jp = range_penalty(p, lib.max_ratio, 3.0 * self.noise)
        return np.vstack([self.jac, jp])

    def _solve(self, p: np.ndarray, r: np.ndarray, lib) -> tuple[np.ndarray, float]:
        """The Gauss-Newton step of residuals ``r`` with the kept Jacobian, slightly
        damped (Levenberg), and the fall of the cost the linear model predicts for it,
        ``|r|^2 - |r + J step|^2`` (J. Nocedal and S. J. Wright, *Numerical
        Optimization*, 2nd ed., 2006, sec. 10.3)."""
        J = self.full_jacobian(p, lib)
        A = J.T @ J
        A[np.diag_indices_from(A)] *= 1.0 + 1e-9
        A[np.diag_indices_from(A)] += 1e-30
        g = J.T @ r
        step = -np.linalg.solve(A, g)
        return step, float(r @ r - np.sum((r + J @ step) ** 2))
