"""Six-step phase shifting: isoclinic, isochromatic, the pi/2 ambiguity, unwrapping.

Conventions (``docs/theory.md``, "Six-step phase shifting"; Ramesh, *Digital
Photoelasticity*, Springer 2000, sec. 6; seed paper eqs. 2-4). With a = i5 - i3,
b = i4 - i6, c = i1 - i2 the ideal intensities give

    a = Ia sin 2t sin d,   b = Ia cos 2t sin d,   c = Ia cos d,

so the vector (b, a) = Ia sin d (cos 2t, sin 2t) is unambiguous while its split into an angle
and a non-negative length is not: where sin d < 0 the isoclinic t comes out pi/2 off and d
comes out as 2 pi - d (the "reversed phasemap" of the seed paper).

The ambiguity is resolved here without assuming the load. The principal direction t is
continuous (mod pi), so (cos 2t, sin 2t) is continuous, even around isotropic points and
around the indenter axis where t winds by 2 pi; hence sin d changes sign between two
neighbouring pixels exactly when their measured vectors (b, a) point in opposite
directions. A maximum spanning tree over these neighbour relations (the most reliable
first) fixes the sign of sin d up to one global sign per connected region; relations that
contradict the result are counted and their pixels reported unreliable. The global sign is
fixed after unwrapping by the physics: the isochromatic fringe order is a magnitude, never
below its zero-order anchor. The signed wrapped phase is then unwrapped
(:mod:`analysis.unwrap`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra, minimum_spanning_tree
from scipy.spatial.transform import Rotation

from .images import Frame
from .masks import check_mask

__all__ = [
    "SixStep",
    "Resolution",
    "six_step",
    "resolve_ambiguity",
    "principal_stress_difference",
    "wrap",
]

TWO_PI = 2.0 * np.pi


def wrap(phase):
    """Wrap angles to [-pi, pi).

    Parameters
    ----------
    phase : float or array
        Angles (rad).

    Returns
    -------
    float or array
        ``phase`` + 2 pi k in [-pi, pi).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import wrap
    >>> wrap(np.array([3.5, -3.5, 7.0])).round(4).tolist()
    [-2.7832, 2.7832, 0.7168]
    """
    return (np.asarray(phase) + np.pi) % TWO_PI - np.pi


@dataclass(frozen=True)
class SixStep:
    """Per-pixel results of the six-step formulas (all (rows, cols); made by :func:`six_step`).

    Parameters
    ----------
    isoclinic : (rows, cols) float array
        rad in [-pi/2, pi/2), 1/2 atan2(i5 - i3, i4 - i6): exact where sin d > 0,
        pi/2 off where sin d < 0.
    isoclinic_eq2 : (rows, cols) float array
        rad in (-pi/4, pi/4], the seed paper's eq. 2 with a plain arctan.
    delta_eq3 : (rows, cols) float array
        rad in [0, 2 pi), the seed paper's eq. 3 evaluated with ``isoclinic_eq2``
        (numerator (i5 - i3) sin 2t + (i4 - i6) cos 2t = (i4 - i6)/cos 2t, free of the
        singularity at t = pi/4). Shows the reversed zones of the paper.
    delta_axis_insensitive : (rows, cols) float array
        rad in [0, pi], atan2(sqrt((i5-i3)^2 + (i4-i6)^2), i1 - i2) (the paper's second
        eq. 4): the isochromatic phase folded to [0, pi].
    modulation : (rows, cols) float array
        sqrt((i5-i3)^2 + (i4-i6)^2 + (i1-i2)^2) / (i1 + i2), in [0, 1]; 1 for ideal optics
        with no background light.
    consistency : (rows, cols) float array
        (|(i1+i2) - (i3+i5)| + |(i1+i2) - (i4+i6)|) / (i1 + i2); 0 for ideal optics.
        Element misalignment and quarter-wave errors raise it.
    valid : (rows, cols) bool array
        Inside the mask, no saturated step, modulation >= the threshold.

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> result.isoclinic.shape, bool(result.valid.sum() == mask.sum())
    ((48, 48), True)
    >>> round(float(result.modulation[mask].min()), 6), round(float(result.consistency.max()), 6)
    (1.0, 0.0)
    """

    isoclinic: np.ndarray
    isoclinic_eq2: np.ndarray
    delta_eq3: np.ndarray
    delta_axis_insensitive: np.ndarray
    modulation: np.ndarray
    consistency: np.ndarray
    valid: np.ndarray


def _stack(images) -> tuple[np.ndarray, np.ndarray]:
    frames = list(images)
    if len(frames) != 6:
        raise ValueError(f"six_step needs exactly 6 images (got {len(frames)})")
    data, sat = [], []
    for k, f in enumerate(frames):
        if isinstance(f, Frame):
            d, s = f.data, f.saturated
        else:
            d = np.asarray(f, dtype=np.float64)
            s = np.zeros(d.shape[:2], bool)
        if d.ndim == 3:
            d = d.mean(axis=2)
        if d.ndim != 2:
            raise ValueError(f"image {k + 1} has shape {d.shape}; need (rows, cols)")
        data.append(d)
        sat.append(s)
    shapes = {d.shape for d in data}
    if len(shapes) != 1:
        raise ValueError(f"the six images differ in size: {[d.shape for d in data]}")
    return np.stack(data), np.any(np.stack(sat), axis=0)


def six_step(images, *, mask=None, min_modulation: float = 0.1) -> SixStep:
    """Apply the six-step formulas to images in :data:`SIX_STEP_ORDER`.

    Parameters
    ----------
    images : sequence of six (rows, cols) arrays or :class:`Frame`
        The six phase-stepped images (colour is averaged), any common intensity scale.
    mask : (rows, cols) bool array, optional
        Region of interest (default: all pixels).
    min_modulation : float in [0, 1)
        Pixels whose modulation ratio falls below it are not valid (too little signal to
        give a phase).

    Returns
    -------
    SixStep

    Raises
    ------
    ValueError
        Not six images, images of different sizes, or ``min_modulation`` outside [0, 1).

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> import numpy as np
    >>> folded = np.arccos(np.cos(2 * np.pi * order))  # the order's phase folded to [0, pi]
    >>> float(np.abs(result.delta_axis_insensitive - folded)[mask].max()) < 1e-9
    True
    """
    if not 0.0 <= min_modulation < 1.0:
        raise ValueError(f"min_modulation = {min_modulation!r} is not allowed; use [0, 1)")
    i, sat = _stack(images)
    roi = check_mask(mask, i.shape[1:])
    i1, i2, i3, i4, i5, i6 = i
    a, b, c = i5 - i3, i4 - i6, i1 - i2
    total = i1 + i2
    safe = np.where(total > 0, total, np.inf)
    theta = 0.5 * np.arctan2(a, b)
    theta = np.where(theta >= np.pi / 2, theta - np.pi, theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        theta2 = 0.5 * np.arctan(np.where(b != 0, a / b, np.copysign(np.inf, a)))
    num = a * np.sin(2 * theta2) + b * np.cos(2 * theta2)
    delta_eq3 = np.arctan2(num, c) % TWO_PI
    delta_ai = np.arctan2(np.hypot(a, b), c)
    modulation = np.sqrt(a * a + b * b + c * c) / safe
    consistency = (np.abs(total - (i3 + i5)) + np.abs(total - (i4 + i6))) / safe
    valid = roi & ~sat & (modulation >= min_modulation) & (total > 0)
    return SixStep(theta, theta2, delta_eq3, delta_ai, modulation, consistency, valid)


@dataclass(frozen=True)
class Resolution:
    """The isoclinic ambiguity resolved (all maps (rows, cols); by :func:`resolve_ambiguity`).

    Parameters
    ----------
    sign : (rows, cols) int8 array
        +1 / -1: the sign of sin d relative to the pixel's group; 0 = not valid.
    group : (rows, cols) int array
        Connected group of valid pixels (-1 = none); each group has its own global sign,
        fixed in :func:`unwrap_fringe_order`.
    phase : (rows, cols) float array
        Signed wrapped isochromatic phase sign * d_folded (rad, [-pi, pi)).
    isoclinic : (rows, cols) float array
        The principal direction consistent with ``phase`` (rad, [-pi/2, pi/2)).
    conflicts : int
        Neighbour pairs whose measured relation contradicts the signs.
    reliable : (rows, cols) bool array
        Valid pixels on no contradicted pair.

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> from fringekit.analysis import resolve_ambiguity
    >>> res = resolve_ambiguity(result)
    >>> res.conflicts, bool((res.reliable == result.valid).all()), int(res.group.max())
    (0, True, 0)
    """

    sign: np.ndarray
    group: np.ndarray
    phase: np.ndarray
    isoclinic: np.ndarray
    conflicts: int
    reliable: np.ndarray


def _edges(valid: np.ndarray, weak: np.ndarray | None = None):
    """Flat index pairs of valid 4-neighbours, plus pairs two apart across a weak pixel.

    A pixel on a fringe contour (sin d ~ 0, ``weak``) has a tiny vector whose direction is
    noise, so the two relations through it are a coin toss each, while the pair across it
    measures the sign change directly (seen on 8-bit FEM indentation images: one such pixel
    line around the order-1 ring flipped the whole field inside it). The pixel between
    must be valid, so the groups stay the 4-connected regions ``unwrap_phase`` unwraps.
    """
    idx = np.arange(valid.size).reshape(valid.shape)
    v = valid.ravel()
    p, q = [], []
    for a, b in ((idx[:, :-1], idx[:, 1:]), (idx[:-1, :], idx[1:, :])):
        ok = v[a] & v[b]
        p.append(a[ok])
        q.append(b[ok])
    if weak is not None:
        w = weak.ravel() & v
        for a, m, b in (
            (idx[:, :-2], idx[:, 1:-1], idx[:, 2:]),
            (idx[:-2, :], idx[1:-1, :], idx[2:, :]),
        ):
            ok = v[a] & w[m] & v[b]
            p.append(a[ok])
            q.append(b[ok])
    return np.concatenate(p), np.concatenate(q)


def resolve_ambiguity(result: SixStep, *, conflict_weight: float = 0.05) -> Resolution:
    """Resolve the pi/2 isoclinic / 2 pi - d ambiguity from the continuity of the axes.

    The measured vector v = (i4 - i6, i5 - i3) / (i1 + i2) equals m sin d (cos 2t, sin 2t)
    with m the modulation. Since the principal direction t is continuous (mod pi, so
    (cos 2t, sin 2t) is continuous even around isotropic points and the indenter axis),
    sin d changes sign between two neighbouring pixels exactly when their vectors point
    in opposite directions. The pixel graph with edge relation sign(v_p . v_q) and
    reliability |v_p . v_q| is reduced to a maximum spanning tree (the most reliable
    relations win; Kruskal via scipy.sparse.csgraph); the tree's positive edges form
    clusters of equal sign (the fringe bands) and the negative edges order them, so the
    signs follow from the parity of the path length in the small cluster tree.

    Parameters
    ----------
    result : SixStep
    conflict_weight : float
        A non-tree pair contradicting the signs counts as a conflict when its reliability
        |v_p . v_q| exceeds this value (vectors of length ~1 give ~1).

    Returns
    -------
    Resolution

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> import numpy as np
    >>> from fringekit.analysis import resolve_ambiguity
    >>> res = resolve_ambiguity(result)
    >>> sorted(np.unique(res.sign[mask]).tolist())  # sin d changes sign across each fringe
    [-1, 1]
    """
    valid = result.valid
    shape = valid.shape
    th, d = result.isoclinic, result.delta_axis_insensitive
    amp = result.modulation * np.sin(d)  # = |v| >= 0 on the atan2 branch
    vx = (amp * np.cos(2 * th)).ravel()
    vy = (amp * np.sin(2 * th)).ravel()
    p, q = _edges(valid, weak=np.abs(amp) < 0.3 * np.maximum(result.modulation, 1e-12))
    dot = vx[p] * vx[q] + vy[p] * vy[q]
    n = valid.size
    sign = np.zeros(n, np.int8)
    group = np.full(n, -1, np.int64)
    if len(p):
        # reliability |v_p . v_q| cos^2(phi), phi the angle between the two vectors: a
        # relation is only trusted when the vectors are (anti)parallel. Near integer
        # orders, where |v| is small, the characteristic isoclinic of a ray with rotating
        # axes may turn quickly (Aben's characteristic parameters are undefined at
        # Delta* = 2 pi k); cos^2 keeps such oblique pairs out of the tree.
        norm = np.hypot(vx[p], vy[p]) * np.hypot(vx[q], vy[q]) + 1e-300
        w = coo_matrix((-(np.abs(dot) * (dot / norm) ** 2 + 1e-12), (p, q)), shape=(n, n))
        w = w.tocsr()
        tree = minimum_spanning_tree(w).tocoo()
        tp, tq = tree.row, tree.col
        tdot = vx[tp] * vx[tq] + vy[tp] * vy[tq]
        pos = tdot >= 0
        same = coo_matrix((np.ones(pos.sum()), (tp[pos], tq[pos])), shape=(n, n))
        n_cl, cluster = connected_components(same, directed=False)
        # the cluster tree: one node per band, an edge per sign change
        neg = ~pos
        ca, cb = cluster[tp[neg]], cluster[tq[neg]]
        ctree = coo_matrix((np.ones(len(ca)), (ca, cb)), shape=(n_cl, n_cl)).tocsr()
        n_grp, cgroup = connected_components(ctree, directed=False)
        roots = np.unique(cgroup, return_index=True)[1]
        depth = dijkstra(ctree, directed=False, indices=roots, unweighted=True, min_only=True)
        parity = np.round(depth).astype(np.int64) % 2
        sign = np.where(parity[cluster] == 0, 1, -1).astype(np.int8)
        group = cgroup[cluster]
        sign[~valid.ravel()] = 0
        group[~valid.ravel()] = -1
    # contradicted relations among all neighbour pairs
    bad = (np.sign(dot) * sign[p] * sign[q] < 0) & (np.abs(dot) > conflict_weight)
    unreliable = np.zeros(n, bool)
    unreliable[p[bad]] = unreliable[q[bad]] = True
    sign = sign.reshape(shape)
    phase = np.where(valid, wrap(np.where(sign < 0, -d, d)), 0.0)
    iso = np.where(sign < 0, th + np.pi / 2, th)
    iso = (iso + np.pi / 2) % np.pi - np.pi / 2
    reliable = valid & ~unreliable.reshape(shape)
    return Resolution(sign, group.reshape(shape), phase, iso, int(bad.sum()), reliable)


def principal_stress_difference(order, f_sigma: float, thickness: float, *, reflection=True):
    """sigma1 - sigma2 from the fringe order: N f_sigma / L.

    L = 2 t in reflection, t in transmission (seed paper eq. 4; ``docs/theory.md``, "The
    stress-optic law").

    Parameters
    ----------
    order : float or array
        Fringe order.
    f_sigma : float
        Material fringe value (N/m per fringe, i.e. Pa m).
    thickness : float
        Sheet thickness t (m).
    reflection : bool
        The light crosses the sheet twice.

    Returns
    -------
    float array
        Principal stress difference (Pa), the shape of ``order``.

    Raises
    ------
    ValueError
        ``f_sigma`` or ``thickness`` not > 0.

    Examples
    --------
    >>> from fringekit.analysis import principal_stress_difference
    >>> round(float(principal_stress_difference(1.0, f_sigma=386.0, thickness=3e-3)))  # Pa
    64333
    """
    if not f_sigma > 0:
        raise ValueError(f"f_sigma = {f_sigma!r} N/m is not allowed; must be > 0")
    if not thickness > 0:
        raise ValueError(f"thickness = {thickness!r} m is not allowed; must be > 0")
    path = (2.0 if reflection else 1.0) * thickness
    return np.asarray(order, float) * f_sigma / path


def subtract_reference(result: SixStep, reference: SixStep) -> SixStep:
    """The six-step result of the specimen alone: a zero-load reference's retardation removed.

    The residual birefringence of the sheet and the optics is removed vectorially. On the
    Poincare sphere a linear retarder of retardation d and axis t turns the light by d
    about the equatorial axis a(t) = (cos 2t, sin 2t, 0) (Theocaris and Gdoutos, *Matrix
    Theory of Photoelasticity*, Springer 1979, ch. 4); the six steps measure where the
    circularly polarised input ends up, s = R z (its fold d <-> 2 pi - d is the same
    point). The reference, a linear retarder, gives its own R_r exactly, so the residual
    acting first turns z to p = R_r z, and the specimen's retarder R_s then takes p to
    the measured m. A rotation about an equatorial axis that takes p to m has its axis
    normal to both z and m - p, and its angle is the turn from p to m about that axis;
    R_s z is what the specimen alone would have given. Validity needs both; the
    modulation is the smaller of the two. Exact for a residual retarder in series with a
    linear specimen retarder.

    Parameters
    ----------
    result : SixStep
        The loaded specimen.
    reference : SixStep
        The same sensor at zero load, same optics and size.

    Returns
    -------
    SixStep

    Raises
    ------
    ValueError
        The two results differ in size.

    Examples
    --------
    A residual retarder of 0.3 rad at 20 degrees in front of a specimen of 1 rad at
    50 degrees:

    >>> import numpy as np
    >>> from fringekit.analysis import six_step, subtract_reference
    >>> from fringekit.optics import intensity, retarder, six_step_arrangements
    >>> from fringekit.optics.jones import qmul
    >>> residual = retarder(np.full((4, 4), 0.3), np.radians(20))
    >>> loaded = qmul(retarder(np.full((4, 4), 1.0), np.radians(50)), residual)
    >>> steps = six_step_arrangements()
    >>> ref = six_step([intensity(residual, a) for a in steps])
    >>> both = six_step([intensity(loaded, a) for a in steps])
    >>> alone = subtract_reference(both, ref)
    >>> round(float(alone.delta_axis_insensitive[0, 0]), 6)  # rad
    1.0
    >>> round(float(np.degrees(alone.isoclinic[0, 0])), 4)  # degrees
    50.0
    """
    if result.valid.shape != reference.valid.shape:
        raise ValueError(
            f"reference shape {reference.valid.shape} does not match the images "
            f"{result.valid.shape}"
        )

    def end_point(r: SixStep) -> np.ndarray:
        d, t = r.delta_axis_insensitive.ravel(), r.isoclinic.ravel()
        axis = np.stack([np.cos(2 * t), np.sin(2 * t), np.zeros_like(t)], -1)
        return Rotation.from_rotvec(d[:, None] * axis).apply([0.0, 0.0, 1.0])

    p, m = end_point(reference), end_point(result)
    w = m - p
    axis = np.stack([-w[:, 1], w[:, 0], np.zeros(len(w))], -1)
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(norm > 1e-12, axis / np.maximum(norm, 1e-300), [1.0, 0.0, 0.0])
    pp = p - np.sum(axis * p, axis=1, keepdims=True) * axis
    mp = m - np.sum(axis * m, axis=1, keepdims=True) * axis
    turn = np.arctan2(np.sum(axis * np.cross(pp, mp), axis=1), np.sum(pp * mp, axis=1))
    turn = np.where(norm[:, 0] > 1e-12, turn, 0.0)
    axis = np.where(turn[:, None] < 0, -axis, axis)
    d = np.abs(turn).reshape(result.valid.shape)
    theta = 0.5 * np.arctan2(axis[:, 1], axis[:, 0])
    theta = np.where(theta >= np.pi / 2, theta - np.pi, theta).reshape(result.valid.shape)
    return SixStep(
        isoclinic=theta,
        isoclinic_eq2=(theta + np.pi / 4) % (np.pi / 2) - np.pi / 4,
        delta_eq3=d,
        delta_axis_insensitive=d,
        modulation=np.minimum(result.modulation, reference.modulation),
        consistency=np.maximum(result.consistency, reference.consistency),
        valid=result.valid & reference.valid,
    )
