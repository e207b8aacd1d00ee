"""The quick start: the contacts of one image found and fitted on every few pixels, and
kept only where they explain the image to the camera's noise.

:func:`quick_start` is a stream's first frame (:class:`fringekit.tracking.Tracker`):
``invert``'s detection and start scan, then one robust joint fit and one basin search on
every ``stride``-th pixel, the contacts left after dropping the insignificant ones fitted
again, and the residual searched for contacts detection missed. The whole inverse
(:func:`fringekit.inversion.fit.invert_image`) adds a far-field fit, more basin searches,
merges of flagged pairs and second starts, on every 2nd pixel, and takes 4-20 times
longer; ``invert`` (:func:`invert_or_quick`) tries the quick start as well when the whole
inverse leaves an indenter flagged or refuses the image. The quick answer is kept only
where it explains the image to the camera's noise (:func:`near_residual`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from fringekit.inversion.budget import Budget
from fringekit.inversion.detect import detect, noise_sd
from fringekit.inversion.fit import (
    EXACT_MM,
    WINDOW_MM,
    InvertResult,
    finish_answer,
    fit_indenters,
    invert_image,
    start_params,
    subsample,
)
from fringekit.inversion.hop import hop
from fringekit.inversion.match import match_candidates
from fringekit.inversion.model import N_PARAMS, ImageModel, range_penalty, unpack
from fringekit.inversion.selection import prune, residual_candidates
from fringekit.inversion.uncertainty import parameter_sd
from fringekit.inversion.verdict import (
    WARN_RESIDUAL,
    InvertError,
    better_answer,
    fit_verdict,
    window_rms,
)

__all__ = [
    "QUICK_NOISE",
    "QUICK_RESIDUAL",
    "QUICK_ROUNDS",
    "QUICK_STRIDE",
    "invert_or_quick",
    "near_residual",
    "penalised_residual",
    "quick_start",
]

#: The quick start is kept when every contact's residual is within this (fringe
#: amplitudes; half invert's warning level): on the bench's first frame it read a contact
#: at the frame's edge 10 % low with 0.21, where the whole inverse left 0.007.
QUICK_RESIDUAL = 0.11
#: ... and within this many times the camera noise's own share of it (noise sd over the
#: fringe amplitude): a wrong minimum can leave little. On a 16-bit frame of two contacts
#: the quick start read one 0.3 mm and 0.2 N off with a residual of 0.05 (the other
#: 0.0018, the noise's share 0.002); the right answers leave 1-1.5 times the noise's
#: share. A model's own misfit (an FEM image, a photograph) is above this, and such a
#: frame is started by the whole inverse.
QUICK_NOISE = 3.0
#: Rounds of the quick start that look for contacts in the residual of those fitted.
QUICK_ROUNDS = 2
#: The pixels ``invert``'s quick start fits (every this many), as a stream's frames.
QUICK_STRIDE = 4


def near_residual(fixed: ImageModel, p: np.ndarray, r: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """Residual RMS near each contact, in fringe amplitudes.

    Parameters
    ----------
    fixed : ImageModel
        The model the residuals are of (its ``usable`` and ``keep`` pixels count).
    p : (n * 5,) array
        The contacts' parameters (x, y in mm; loads in N).
    r : (P * C + k,) array
        The residuals of the image (intensity), then of the range penalty.
    gains : (C,) array
        The fitted exposure gains: the fringe amplitude is their mean magnitude.

    Returns
    -------
    (n,) array
        The RMS of the image residual within ``WINDOW_MM`` of each contact's axis over
        the fringe amplitude; inf where no pixel is near it.

    Examples
    --------
    See :func:`quick_start`, which keeps a fit only where every contact's is small.
    """
    img = r[: fixed.measured.size].reshape(fixed.measured.shape)
    amp = float(np.mean(np.abs(gains)))
    q = np.reshape(p, (-1, N_PARAMS))
    rms = window_rms(img, fixed.usable & fixed.keep, fixed.xy * 1e3, q, amp, WINDOW_MM)
    return np.where(np.isnan(rms), np.inf, rms)


def quick_start(full: ImageModel, cand: np.ndarray, stride: int, noise: float):
    """The contacts of a first frame from ``invert``'s detections, fitted on every
    ``stride``-th pixel; kept only where they explain the frame to its noise.

    Parameters
    ----------
    full : ImageModel
        The frame's model at every pixel (its measured image set).
    cand : (m, 2) array
        Detected candidate axes (mm), :func:`fringekit.inversion.detect.detect`'s.
    stride : int
        Every ``stride``-th pixel in both directions is fitted.
    noise : float
        The camera noise sd (intensity units of ``full.measured``).

    Returns
    -------
    tuple
        (p (n * 5,), diameters (n,) in m) when every contact left has its residual near
        it (:func:`near_residual`) within QUICK_RESIDUAL and QUICK_NOISE times the
        noise's share, else (None, None).

    Notes
    -----
    The fit again after dropping is what makes the quick start hold: a spurious
    candidate takes load and fringes from a real contact beside it, and on the track
    bench's first frame the four left read one of them 1.0 mm off (residual 0.47) until
    fitted without it (1 um off, residual 0.007; 1.8 s): 11 s for the frame, where the
    whole inverse took 58 s.

    The residual of the contacts fitted is then searched for contacts detection missed,
    as ``invert``'s model selection does (at most QUICK_ROUNDS times, while it finds one
    or a contact is left unexplained): detection on the residual image beyond a sphere
    diameter of every fitted and dropped axis, the new candidates matched to
    one-indenter images, the basins of those and of the unexplained contacts searched,
    and everything fitted again. Started alone, frames 50, 100, 150 and 199 of that
    stream each had a contact missed by detection (two contacts' fringes merge into one
    ridge of gradient energy) and went to the whole inverse: 215-461 s, one of them read
    1.5 N off and one refused; with the search each is a quick start of 12-37 s, every
    contact within 2 mN and 9 um.

    Examples
    --------
    See :class:`fringekit.tracking.Tracker`, whose first frame starts here, and
    :func:`invert_or_quick`, which tries it on an image the whole inverse leaves flagged
    or refuses.
    """
    sub = replace(subsample(full, stride), exact=EXACT_MM * 1e-3)
    half = subsample(full, 2)  # where the residual is searched, as invert's model selection
    p, diam = start_params(sub, cand)
    p = fit_indenters(sub, p, diam, noise).x
    p, _ = hop(sub, p, diam, noise)
    dropped = np.zeros((0, 2))
    for round_ in range(QUICK_ROUNDS + 1):
        p, diam, gone = _fit_and_prune(sub, p, diam, noise)
        dropped = np.concatenate([dropped, gone])
        if not diam:
            return None, None
        flagged = _flagged(sub, p, diam, noise)
        last = round_ == QUICK_ROUNDS
        new = np.zeros((0, 2)) if last else residual_candidates(half, p, diam, noise, dropped, True)
        if not flagged.any() and not len(new):
            return p, diam
        if last:
            break
        pn, dn = start_params(sub, new)
        n = len(diam)
        p, diam = np.concatenate([p, pn]), diam + dn
        search = [*np.flatnonzero(flagged), *range(n, len(diam))]
        p, moved = hop(sub, fit_indenters(sub, p, diam, noise).x, diam, noise, which=search)
        if not len(new) and not moved:  # nothing new, nothing moved: the same fit again
            break
    return None, None


def _fit_and_prune(sub: ImageModel, p: np.ndarray, diam: list, noise: float):
    """Fit, drop the insignificant contacts, and fit again while one is dropped:
    (p, diameters, the dropped axes (k, 2) mm)."""
    gone = []
    for _ in range(len(diam) + 1):  # a round drops one at least, or is the last
        res = fit_indenters(sub, p, diam, noise)
        sd = parameter_sd(res.jac, res.fun, int(np.count_nonzero(res.fun)))
        n = len(diam)
        p, diam, kept = prune(res.x, sd, diam, sub.lib)
        q = res.x.reshape(-1, N_PARAMS)
        gone += [q[k, :2] for k in range(n) if k not in kept]
        if len(diam) in (0, n):
            break
    return p, diam, np.reshape(gone, (-1, 2))


def _flagged(sub: ImageModel, p: np.ndarray, diam: list, noise: float) -> np.ndarray:
    """(n,) bool: the contacts whose residual near them is above QUICK_RESIDUAL or
    QUICK_NOISE times the noise's share."""
    fixed = replace(sub, keep=sub.outside_contacts(unpack(p, diam)))
    r, gains, _ = penalised_residual(fixed, p, diam, noise)
    amp = float(np.mean(np.abs(gains)))
    limit = min(QUICK_RESIDUAL, QUICK_NOISE * noise / amp) if amp > 0 else 0.0
    return ~(near_residual(fixed, p, r, gains) <= limit)


def penalised_residual(fixed: ImageModel, p: np.ndarray, diam: list, noise: float):
    """The residuals of ``fixed``'s image at ``p`` and of the range penalty, as the fits
    take them, from each contact's own field.

    Parameters
    ----------
    fixed : ImageModel
        The model, its ``keep`` set (the pixels outside the contacts).
    p : (n * 5,) array
        The contacts' parameters (x, y in mm; loads in N).
    diam : list of float
        Their sphere diameters (m).
    noise : float
        The noise sd (intensity): the range penalty's scale is three of it.

    Returns
    -------
    tuple
        (residuals (P * C + n,) in intensity, zero on pixels left out; the fitted gains
        (C,); every contact's slab pairs (P, S, 2) on ``fixed``'s pixels, which a
        Jacobian at ``p`` can reuse).

    Examples
    --------
    See :func:`quick_start`, whose answer is judged on it, and
    :meth:`fringekit.tracking.warm.ChordFit.residual`.
    """
    inds = unpack(p, diam)
    own = [fixed.lib.slabs(ind, fixed.xy)[0] for ind in inds]
    ab = np.zeros((len(fixed.xy), fixed.lib.lattice.n_slabs, 2), np.float32)
    for one in own:  # summed as superpose sums them
        ab += one
    ab = fixed.with_background(ab)
    use = fixed.usable & fixed.keep
    fitted, gains, _ = fixed.project(fixed.intensities(ab, inds), use)
    res = fixed.misfit(fitted)
    res[~use] = 0.0
    pen, _ = range_penalty(p, fixed.lib.max_ratio, 3.0 * noise)
    return np.concatenate([res.ravel(), pen]), gains, own


def invert_or_quick(
    model: ImageModel, *, budget: Budget | None = None, noise: float | None = None
) -> InvertResult:
    """``invert``'s answer (:func:`~fringekit.inversion.fit.invert_image`), or the quick
    start's where that one leaves an indenter flagged or is refused and the quick start
    explains the image to its noise.

    The whole inverse and the quick start take different paths through the same cost,
    and each can end in a wrong basin where the other does not: on frame 50 of the track
    bench (four contacts of the library's own model, 256 x 256 px) the whole inverse
    flagged two contacts after its three starts (one 1.5 N and 0.8 mm off, residuals
    0.25 and 0.43), where the quick start reads every contact within 1 mN and 3 um. The
    quick start's answer is fitted again on ``invert``'s pixels (every 2nd) and kept
    when it leaves fewer indenters flagged, then the smaller residual, as ``invert``'s
    own retries are.

    Parameters
    ----------
    model : ImageModel
        The image's model at every pixel (its measured image set).
    budget : Budget, optional
        The time budget; the quick start is its own stage (``quick_start_s``), and none
        is tried once the budget is spent.
    noise : float, optional
        The image's noise sd (default :func:`~fringekit.inversion.detect.noise_sd`).

    Returns
    -------
    InvertResult
        The better answer.

    Raises
    ------
    InvertError
        When the whole inverse refuses the image and the quick start does not explain it.

    Examples
    --------
    See :func:`fringekit.inversion.invert`, which reads every image through it.
    """
    budget = budget or Budget(math.inf)
    noise = noise_sd(model) if noise is None else noise
    res, refused = None, None
    try:
        res = invert_image(model, budget=budget, noise=noise)
    except InvertError as err:
        refused = err
    unsure = refused is not None or bool(np.any(res.residual_rms > WARN_RESIDUAL))
    if not unsure or budget.stopped is not None:
        return _answer(res, refused)
    budget.say("invert: an indenter is flagged or the image refused: trying the quick start")
    fine = subsample(model, 2)
    cand = match_candidates(fine, detect(fine, noise))
    p, diam = quick_start(model, cand, QUICK_STRIDE, noise) if len(cand) else (None, None)
    found = "no answer explains the image to its noise" if p is None else f"{len(diam)} kept"
    if budget.spent("quick start", found) or p is None:
        return _answer(res, refused, budget)
    fit = fit_indenters(fine, p, diam, noise)
    if res is None:
        verdict = fit_verdict(fine, fit.x, diam, WINDOW_MM)
    else:  # the retries' rule: fewer flagged, then the smaller residual
        held = (res.params, list(res.diameters), None, (res.residual_rms, res.residual))
        better = better_answer(fine, held, (fit.x, diam, fit), WINDOW_MM)
        if better is held:
            return _answer(res, None, budget)
        verdict = better[3]
    its = fit.nfev + (0 if res is None else res.iterations)
    try:
        return finish_answer(fine, fit.x, diam, fit, verdict, noise, its, budget)
    except InvertError:  # refused too: the whole inverse's answer, or its own refusal
        return _answer(res, refused, budget)


def _answer(res: InvertResult | None, refused: InvertError | None, budget: Budget | None = None):
    """The whole inverse's answer (its stage times now counting the quick start's when
    ``budget`` is given), or its refusal."""
    if res is None:
        raise refused
    return res if budget is None else replace(res, times_s=budget.stage_times())
