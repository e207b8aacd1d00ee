"""The first frame of a stream: its contacts found and fitted quickly (the quick start),
and the residual near each contact that decides whether a fit is kept.

:func:`quick_start` is the tracker's start: ``invert``'s detection and start scan, then
one robust joint fit and one basin search on every ``stride``-th pixel, the contacts
left after dropping the insignificant ones fitted again, and the residual searched for
contacts detection missed. ``invert``
(:func:`fringekit.inversion.fit.invert_image`) adds a far-field fit, more basin searches,
merges of flagged pairs and second starts, on every 2nd pixel, and takes 4-20 times
longer. The
quick answer is kept only where it explains the frame to the camera's noise; elsewhere
the tracker runs the whole inverse. :func:`settle_new` searches the axes about a contact
found in a later frame whose fit leaves it far worse explained than its neighbours.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fringekit.inversion.fit import (
    EXACT_MM,
    WINDOW_MM,
    fit_indenters,
    start_params,
    subsample,
)
from fringekit.inversion.hop import hop, hop_to
from fringekit.inversion.model import N_PARAMS, ImageModel, unpack
from fringekit.inversion.selection import prune, residual_candidates
from fringekit.inversion.uncertainty import parameter_sd
from fringekit.inversion.verdict import window_rms
from fringekit.tracking.warm import ChordFit

__all__ = [
    "MISFIT_TIMES",
    "QUICK_NOISE",
    "QUICK_RESIDUAL",
    "QUICK_ROUNDS",
    "RING_MM",
    "RING_POINTS",
    "near_residual",
    "quick_start",
    "settle_new",
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
    See :class:`fringekit.tracking.Tracker`, whose first frame starts here.
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
    r, gains = ChordFit(noise).residual(fixed, p, diam)
    amp = float(np.mean(np.abs(gains)))
    limit = min(QUICK_RESIDUAL, QUICK_NOISE * noise / amp) if amp > 0 else 0.0
    return ~(near_residual(fixed, p, r, gains) <= limit)


#: A contact found in a redetection whose residual is this many times the held contacts'
#: (at least 3 noise sd) has the axes about it searched (:func:`settle_new`) ...
MISFIT_TIMES = 5.0
#: ... from RING_POINTS axes on each of these circles about it (mm).
RING_MM = (0.5, 1.0)
RING_POINTS = 8


def settle_new(model: ImageModel, p: np.ndarray, diam: list, n_held: int, noise: float) -> int:
    """Search the axes about each new contact (indices from ``n_held`` of ``p``, which is
    changed in place) whose residual stays MISFIT_TIMES above the held contacts' (their
    median, at least 3 ``noise`` sd's share): local fits from RING_MM rings about it
    (:func:`~fringekit.inversion.hop.hop_to`). The basin search scans loads at a fixed
    axis, and a touch detected 0.9 mm off its axis was fitted there with a tangential
    load it did not bear (residual 0.15 against 0.004 of its neighbours, under the
    warning level: taken as reliable). Returns how many moved.

    Examples
    --------
    No new contact, nothing searched:

    >>> settle_new(None, np.zeros(5), [3.5e-3], 1, 0.01)
    0
    """
    if n_held == 0 or len(diam) == n_held:
        return 0
    fixed = replace(model, keep=model.outside_contacts(unpack(p, diam)))
    r, gains = ChordFit(noise).residual(fixed, p, diam)  # one synthesis, as quick_start's
    rms = near_residual(fixed, p, r, gains)
    amp = float(np.mean(np.abs(gains))) or 1.0
    level = MISFIT_TIMES * max(float(np.median(rms[:n_held])), 3 * noise / amp)
    moved = 0
    angles = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    for k in range(n_held, len(diam)):  # the new contacts of one frame: one or two
        if not rms[k] > level:
            continue
        axis = p.reshape(-1, N_PARAMS)[k, :2]
        ring = [axis + d * np.array([np.cos(a), np.sin(a)]) for d in RING_MM for a in angles]
        q, changed = hop_to(model, p, diam, noise, k, ring)
        p[:], moved = q, moved + changed
    return moved
