"""Model selection's rules: which of the fitted indenters are kept.

An indenter is kept when its normal load is significant (above 3 sd, and from
:data:`MIN_LOAD_FRACTION` of the library's first load unless it is tracked already), and
no stronger one sits closer to it than their spheres allow (:func:`sphere_gaps`). The fit
itself is :mod:`fringekit.inversion.fit`'s. Indenters not yet fitted are looked for in
the residual of those that are (:func:`residual_candidates`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fringekit.inversion.detect import detect
from fringekit.inversion.match import match_candidates
from fringekit.inversion.model import N_PARAMS, ImageModel, unpack
from fringekit.inversion.verdict import at_library_edge

__all__ = ["MIN_LOAD_FRACTION", "prune", "residual_candidates", "sphere_gaps"]

#: A new indenter is kept from this fraction of the library's first (smallest non-zero) load.
MIN_LOAD_FRACTION = 0.5


def sphere_gaps(p: np.ndarray, diam) -> np.ndarray:
    """(n, n) distance (mm) between every two indenters' axes less the sum of their
    spheres' radii, inf on the diagonal: below 0 where two are closer than their spheres
    allow (parameter vector ``p`` (n * 5,), x, y in mm; diameters in m).

    Examples
    --------
    >>> sphere_gaps(np.array([0.0, 0, 1, 0, 0, 3.0, 0, 1, 0, 0]), [3.5e-3, 3.5e-3])[0, 1]
    np.float64(-0.5)
    """
    q = np.reshape(p, (-1, N_PARAMS))
    d = np.asarray(diam, float)
    gap = np.hypot(*(q[:, None, :2] - q[None, :, :2]).transpose(2, 0, 1)) - 0.5e3 * (d[:, None] + d)
    np.fill_diagonal(gap, np.inf)
    return gap


def prune(
    p: np.ndarray, sd: np.ndarray, diam: list, lib, held=None, floor: float = MIN_LOAD_FRACTION
) -> tuple[np.ndarray, list, list]:
    """Drop indenters whose normal load is not significant, and the weaker of two whose
    axes are closer than their spheres allow (centres at least a diameter apart; the
    stronger is kept whatever its sd, which such a pair inflates); returns (parameters,
    diameters, indices kept).

    A load is significant above 3 sd and from ``floor`` (default MIN_LOAD_FRACTION) of
    the library's first load; ``held`` (n,) bool marks indenters already tracked
    (``track``), which need the first only: a contact is taken from that level and let go
    when its load is no longer told from zero, so a load ramping through the level does
    not give a contact a new id every frame (found, dropped, found again)."""
    q = p.reshape(-1, N_PARAMS)
    s = sd.reshape(-1, N_PARAMS)
    with np.errstate(invalid="ignore"):
        significant = ~(q[:, 2] <= 3 * s[:, 2])  # an undefined sd keeps it
    gap = sphere_gaps(p, diam)
    # two fitted onto one contact share its load and their sds grow without bound (their
    # columns are alike): each alone may look insignificant though together they are
    # not (1.8 + 1.2 N with sds of 1.2 N, both dropped and the contact lost). The
    # stronger of them is kept and fitted again.
    twin = (gap < 0).any(axis=1)
    # an indenter held at the largest load is kept, to be refused (never dropped silently)
    enough = q[:, 2] >= floor * lib.load_N[1]
    if held is not None:
        enough |= np.asarray(held, bool)
    keep = enough & (significant | twin)
    keep |= at_library_edge(q, lib)[0]
    kept: list[int] = []
    for i in np.argsort(-q[:, 2]):  # strongest first; a handful of indenters
        clash = any(gap[i, j] < 0 for j in kept)
        if keep[i] and not clash:
            kept.append(int(i))
    kept.sort()
    return q[kept].ravel(), [diam[i] for i in kept], kept


def residual_candidates(
    fine: ImageModel, p: np.ndarray, diam, noise: float, dropped, matched: bool
) -> np.ndarray:
    """Candidates (k, 2) (mm) where the residual of the indenters ``p`` (n * 5,) with
    diameters ``diam`` (m) keeps fringes: detection on the image less their fitted
    model (zero inside their contact circles), beyond a sphere diameter of every fitted
    axis and of the ``dropped`` ones (m, 2) (mm).

    ``matched``: the residual's peaks are detected beyond the dropped axes only and
    matched to one-indenter images on ``fine``'s own image
    (:func:`~fringekit.inversion.match.match_candidates`), none landing within a sphere
    diameter of a fitted or dropped axis: a residual peak beside a fitted axis is looked
    for beyond it. Otherwise the peaks near any of them are dropped.

    Examples
    --------
    See :func:`fringekit.inversion.fit.select_indenters` and
    :func:`fringekit.inversion.quick.quick_start`, which look for more indenters so.
    """
    fitted, _, _, outside = fine.fitted(unpack(p, diam))
    resid = replace(
        fine, measured=np.where(outside[:, None], fine.misfit(fitted), 0.0), censored=None
    )
    taken = np.concatenate([np.reshape(p, (-1, N_PARAMS))[:, :2], np.reshape(dropped, (-1, 2))])
    if matched:
        return match_candidates(fine, detect(resid, noise, exclude=dropped), taken)
    return detect(resid, noise, exclude=taken)
