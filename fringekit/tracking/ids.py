"""Contact identity from frame to frame: which contact of one frame is which of the next,
and how each moved.

Two spheres' axes stay at least a diameter apart (3.5 mm for the usual heads), and a
frame moves a contact far less, so the contacts of two frames pair up as the assignment
of least total distance (H. W. Kuhn, "The Hungarian method for the assignment problem",
Naval Res. Logist. Q. 2, 1955; scipy's ``linear_sum_assignment``), within a gate.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from fringekit.inversion.model import N_PARAMS

__all__ = ["assign", "heirs", "previous_params", "twins", "velocity"]


def assign(old_mm, new_mm, gate_mm: float = np.inf, allowed=None):
    """Pair positions of one frame with those of the next.

    Parameters
    ----------
    old_mm : (n, 2) array
        Positions (mm) the contacts had.
    new_mm : (k, 2) array
        Positions (mm) found now.
    gate_mm : float
        A pair farther apart than this (mm) is not made.
    allowed : (n,) bool array, optional
        The old positions that may be paired (default all).

    Returns
    -------
    rows, cols : int arrays
        Old index ``rows[i]`` is new index ``cols[i]``; the least total distance over
        the pairs allowed.

    Examples
    --------
    Two contacts passing each other 4 mm apart, each moved 0.5 mm:

    >>> import numpy as np
    >>> rows, cols = assign([[-2.0, 0.0], [2.0, 0.0]], [[2.0, -0.5], [-2.0, 0.5]], 3.0)
    >>> rows.tolist(), cols.tolist()
    ([0, 1], [1, 0])
    """
    old = np.reshape(np.asarray(old_mm, float), (-1, 2))
    new = np.reshape(np.asarray(new_mm, float), (-1, 2))
    if not (len(old) and len(new)):
        return np.zeros(0, int), np.zeros(0, int)
    dist = np.hypot(*(old[:, None, :] - new[None, :, :]).transpose(2, 0, 1))
    ok = dist <= gate_mm
    if allowed is not None:
        ok &= np.asarray(allowed, bool)[:, None]
    cost = np.where(ok, dist, 1e6)
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < 1e6
    return rows[keep].astype(int), cols[keep].astype(int)


def velocity(before, after, gap: int) -> np.ndarray:
    """Each contact's change per frame from ``before`` to ``after``.

    Parameters
    ----------
    before, after : (p, ids)
        Parameter vectors (n * 5,) x, y (mm), Fz, Fx, Fy (N) and their contacts' ids.
    gap : int
        Frames between them.

    Returns
    -------
    (m * 5,) array
        The change per frame of each contact of ``after``; zero for one new in it.

    Examples
    --------
    >>> import numpy as np
    >>> v = velocity((np.arange(5.0), np.array([7])), (np.arange(5.0) + 2, np.array([7])), 2)
    >>> v.tolist()
    [1.0, 1.0, 1.0, 1.0, 1.0]
    """
    p0, ids0 = before
    p1, ids1 = after
    q0, q1 = np.reshape(p0, (-1, N_PARAMS)), np.reshape(p1, (-1, N_PARAMS))
    rows = _rows_of(ids0, ids1)
    had = rows >= 0
    v = np.zeros_like(q1, dtype=float)
    v[had] = (q1[had] - q0[rows[had]]) / gap
    return v.ravel()


def _rows_of(ids_before, ids) -> np.ndarray:
    """(n,) int: the row of each of ``ids`` among ``ids_before``; -1 for an id new now."""
    before = [int(i) for i in np.ravel(ids_before)]
    return np.array([before.index(int(i)) if int(i) in before else -1 for i in ids], int)


def twins(gaps, dropped, kept, new) -> dict:
    """Contacts tracked before that were dropped beside one found in the same frame: the
    same contact seen twice (a search after dropped frames can put a new contact on the
    rings of a tracked one, and the fit then shares the load between the two).

    Parameters
    ----------
    gaps : (n, n) array
        Distance between the contacts' axes less their spheres' radii (mm; below 0 for
        two closer than their spheres allow), as
        :func:`~fringekit.inversion.selection.sphere_gaps` gives it.
    dropped, kept : sequences of int
        The contacts dropped and kept.
    new : (n,) bool array
        The contacts found in this frame.

    Returns
    -------
    dict
        Kept new contact -> the dropped tracked contact whose id it takes (each kept
        contact takes one id at most).

    Examples
    --------
    >>> import numpy as np
    >>> gaps = np.array([[np.inf, -3.1, 5.5], [-3.1, np.inf, 5.1], [5.5, 5.1, np.inf]])
    >>> twins(gaps, [0], [1, 2], [False, True, True])
    {1: 0}
    """
    new = np.asarray(new)
    out: dict = {}
    for i in dropped:  # a handful of contacts
        if new[i]:
            continue
        near = [j for j in kept if new[j] and j not in out and gaps[i, j] < 0]
        if near:
            out[near[0]] = int(i)
    return out


def heirs(gaps, dropped, kept, before_mm, now_mm) -> dict:
    """Two tracked contacts that met in this frame, the one kept lying where the dropped
    one was: the kept one takes the dropped one's id. When a lifted contact's fit slides
    onto a neighbour's rings, the two clash and the stronger is kept (the rule of
    :func:`~fringekit.inversion.selection.prune`); the one kept is then the neighbour,
    whatever fit reached it, and its id is the one whose contact was there a frame before.

    Parameters
    ----------
    gaps : (n, n) array
        Distance between the contacts' axes less their spheres' radii (mm; below 0 for
        two closer than their spheres allow).
    dropped, kept : sequences of int
        The contacts dropped and kept.
    before_mm : (n, 2) array
        Each contact's position (mm) in the frame before; NaN for one found in this frame.
    now_mm : (n, 2) array
        Each contact's position (mm) now.

    Returns
    -------
    dict
        Kept contact -> the dropped one whose id it takes: a dropped contact it met
        whose position a frame before lies nearer to it than its own did; the nearest
        such pairs first, each id given once.

    Examples
    --------
    Contact 1, lifted at (-5, 5), slid onto contact 0's rings at (-2.2, 0.75) and was
    kept as the stronger of the two:

    >>> import numpy as np
    >>> gaps = np.array([[np.inf, -3.4], [-3.4, np.inf]])
    >>> heirs(gaps, [0], [1], [[-2.2, 0.0], [-5.0, 5.0]], [[-2.2, 0.8], [-2.2, 0.75]])
    {1: 0}
    """
    before = np.reshape(np.asarray(before_mm, float), (-1, 2))
    now = np.reshape(np.asarray(now_mm, float), (-1, 2))
    pairs = []
    for j in kept:  # a handful of contacts
        own = np.hypot(*(before[j] - now[j]))
        for i in dropped:
            d = np.hypot(*(before[i] - now[j]))
            if gaps[i, j] < 0 and d < own:  # (False where either is NaN)
                pairs.append((d, int(j), int(i)))
    out: dict = {}
    for _, j, i in sorted(pairs):  # nearest first, each id given once
        if j not in out and i not in out.values():
            out[j] = i
    return out


def previous_params(p_before, ids_before, ids) -> np.ndarray:
    """Each contact's parameters in the frame before, found by its id (not by its row:
    a frame that released one contact and found another has as many rows in another
    order).

    Parameters
    ----------
    p_before : (m * 5,) array
        The parameters of the frame before: x, y (mm), Fz, Fx, Fy (N) per contact.
    ids_before : (m,) int array
        Their ids.
    ids : (n,) int array
        The ids of the contacts now.

    Returns
    -------
    (n, 5) array
        The parameters (mm, N) each had; NaN for a contact found in this frame.

    Examples
    --------
    >>> previous_params([1.0, 2.0, 3.0, 0.0, 0.0], [7], [8, 7]).tolist()
    [[nan, nan, nan, nan, nan], [1.0, 2.0, 3.0, 0.0, 0.0]]
    """
    q = np.reshape(np.asarray(p_before, float), (-1, N_PARAMS))
    rows = _rows_of(ids_before, ids)
    out = np.full((len(rows), N_PARAMS), np.nan)
    out[rows >= 0] = q[rows[rows >= 0]]
    return out
