"""Rigid spherical indenters against the contact face: augmented Lagrangian with friction.

Contact is evaluated at the 7 quadrature points of every 6-node contact facet, in the
current configuration. For an indenter of centre ``c`` and radius ``R`` and a surface point
``x`` (``y = x - c``, ``r = |y|``, ``n = y / r``) the normal gap is ``g = r - R``. With a
multiplier ``lambda`` (nominal pressure, Pa) and penalty ``eps_N`` (Pa/m) the pressure is

.. math::

    p = \\langle \\lambda - \\varepsilon_N g \\rangle_+ , \\qquad
    \\Pi_N = \\sum_q \\frac{w_q}{2 \\varepsilon_N}
             \\left( \\langle \\lambda_q - \\varepsilon_N g_q \\rangle_+^2 - \\lambda_q^2 \\right),

the augmented Lagrangian of Alart & Curnier (CMAME 92, 1991) and Laursen,
*Computational Contact and Impact Mechanics* (2002), section 5.4; after each converged
solve ``lambda <- p`` (Uzawa update). ``w_q`` is the reference-area weight, so ``p`` is
a nominal (first Piola-Kirchhoff) pressure; :func:`cauchy_pressure` converts it.

Friction (Wriggers, *Computational Contact Mechanics*, 2nd ed., 2006, section 5.2):
each active point carries an anchor ``a`` on the sphere (relative to ``c``; the
indenter does not rotate) with normal ``n0 = a / R``. The elastic tangential slip is
``s = (I - n0 n0) (y - a)`` with penalty ``eps_T``. Stick: force ``w eps_T s``
(energy ``w eps_T |s|^2 / 2``). Coulomb slip when ``eps_T |s| > mu p``: force
``w mu p s / |s|`` (return mapping), with its consistent, unsymmetric tangent.

A point sticks where it first touches. A point that was not in contact at the previous
iterate (relative position ``y0``, trial pressure ``t0 = lambda - eps_N g0 <= 0``) and
is in contact now (``t > 0``) is anchored where the straight path between the two
crosses the contact condition, ``y_c = y0 + tau (y - y0)`` with
``tau = t0 / (t0 - t)``, projected on the sphere: ``a = R y_c / |y_c|``. As the point
just touches, ``tau -> 1`` and ``s -> 0``, so the stick energy is continuous at first
touch (an anchor fixed beforehand makes it jump by ``w eps_T |s|^2 / 2``), and the
anchor does not depend on how the load path is cut into increments beyond the
linearity of the path within one Newton step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .element import TRI_QUADRATURE, tri6_shape

__all__ = [
    "ContactFace",
    "ContactResult",
    "FRICTION_STICK",
    "first_touch_anchors",
    "sphere_contact",
]

#: Friction coefficient meaning "full stick" (no slip whatever the tangential force).
FRICTION_STICK = float("inf")

_N, _dN = tri6_shape(TRI_QUADRATURE[0])
_W = TRI_QUADRATURE[1]
#: (q, 7): shape functions of the 6 face nodes, then -1 for the indenter centre.
_NEXT = np.hstack([_N, -np.ones((len(_N), 1))])


def _quadratic_basis(rs: np.ndarray) -> np.ndarray:
    r, s = rs[:, 0], rs[:, 1]
    return np.stack([np.ones_like(r), r, s, r * r, r * s, s * s], axis=1)


def _sub_centroids(n: int) -> np.ndarray:
    """Centroids of the n^2 equal sub-triangles of the parametric triangle."""
    up = [((3 * i + 1) / (3 * n), (3 * j + 1) / (3 * n)) for i in range(n) for j in range(n - i)]
    down = [
        ((3 * i + 2) / (3 * n), (3 * j + 2) / (3 * n)) for i in range(n) for j in range(n - 1 - i)
    ]
    return np.array(up + down)


#: least-squares quadratic through the 7 quadrature points: coefficients = _FIT @ values
_FIT = np.linalg.pinv(_quadratic_basis(TRI_QUADRATURE[0]))
_SUB = _sub_centroids(8)
_SUB_BASIS = _quadratic_basis(_SUB)
_SUB_N, _SUB_DN = tri6_shape(_SUB)
_SUB_AREA = 0.5 / len(_SUB)  # parametric area of each sub-triangle


@dataclass(frozen=True)
class ContactFace:
    """The contact facets with their reference-area quadrature weights.

    Attributes
    ----------
    nodes : (m, 6) int array, facet node ids.
    weights : (m, q) float array, reference area per quadrature point (m^2).
    """

    nodes: np.ndarray
    weights: np.ndarray

    @classmethod
    def from_points(cls, points: np.ndarray, nodes: np.ndarray) -> ContactFace:
        X = points[nodes]  # (m, 6, 3)
        t = np.einsum("fai,qar->fqri", X, _dN)
        area = np.linalg.norm(np.cross(t[:, :, 0], t[:, :, 1]), axis=-1)
        return cls(nodes=nodes, weights=area * _W[None, :])

    @property
    def n_qp(self) -> int:
        return len(_W)

    def points(self, x: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
        """(f, q, 3) quadrature point positions for nodal positions ``x`` (n, 3)."""
        nodes = self.nodes if faces is None else self.nodes[faces]
        return np.einsum("qa,fai->fqi", _N, x[nodes])

    def projected_area(self, x: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(f, q) current area weights projected on the x-y plane (m^2)."""
        t = np.einsum("fai,qar->fqri", x[self.nodes[faces]], _dN)
        return np.abs(np.cross(t[:, :, 0], t[:, :, 1])[..., 2]) * _W[None, :]

    def current_area(self, x: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(f, q) current area weights (m^2)."""
        t = np.einsum("fai,qar->fqri", x[self.nodes[faces]], _dN)
        return np.linalg.norm(np.cross(t[:, :, 0], t[:, :, 1]), axis=-1) * _W[None, :]

    def projected_contact_area(self, x: np.ndarray, faces: np.ndarray, f: np.ndarray) -> float:
        """Area (m^2), projected on the x-y plane, where the contact indicator is positive,
        resolved inside the facets.

        ``f`` (faces, q) is a signed indicator at the quadrature points, continuous across
        the contact edge: the pressure where the point is in contact and ``-eps_N g`` (the
        penalty times the open gap) where it is not, i.e. the augmented-Lagrangian trial
        pressure. Per facet it is fitted by a least-squares quadratic in the facet's
        parametric coordinates through its 7 points and its sign is read at the centroids
        of 64 sub-triangles, so the contact edge is placed to 1/8 of a facet instead of
        at the facets' (or the quadrature points') boundaries.
        """
        if len(faces) == 0:
            return 0.0
        val = self._sub_indicator(f)
        t = np.einsum("fai,sar->fsri", x[self.nodes[faces]], _SUB_DN)
        dens = np.abs(np.cross(t[:, :, 0], t[:, :, 1])[..., 2])  # projected Jacobian
        return float((dens * (val > 0)).sum() * _SUB_AREA)

    def contact_hull_area(
        self, x: np.ndarray, faces: np.ndarray, f: np.ndarray, mirror_axes=()
    ) -> float:
        """Area (m^2), projected on x-y, of the convex hull of the sub-facet samples where
        the indicator ``f`` (see :meth:`projected_contact_area`) is positive.

        ``mirror_axes`` lists the symmetry planes x = 0 (0) and y = 0 (1) the indenter sits
        on: the samples are mirrored across them first, so the hull (and the area
        returned) is that of the whole patch, not of the modelled part.

        A sphere on a flat sheet touches a convex patch; on coarse facets a few points
        inside it sit a hair off the sphere and carry no pressure, which punches holes
        into the plain area (a 0.6 mm mesh gave a radius 11 % small that way). The hull
        bridges them. 0 when fewer than three samples are in contact.
        """
        if len(faces) == 0:
            return 0.0
        val = self._sub_indicator(f)
        pts = np.einsum("sa,fai->fsi", _SUB_N, x[self.nodes[faces], :2])[val > 0]
        for a in mirror_axes:
            flipped = pts.copy()
            flipped[:, a] *= -1.0
            pts = np.vstack([pts, flipped])
        if len(pts) < 3:
            return 0.0
        try:
            return float(ConvexHull(pts).volume)  # in 2-D, "volume" is the area
        except QhullError:  # all samples on a line
            return 0.0

    @staticmethod
    def _sub_indicator(f: np.ndarray) -> np.ndarray:
        """(faces, 64) the indicator's per-facet quadratic fit at the sub-triangles."""
        return (np.asarray(f, float) @ _FIT.T) @ _SUB_BASIS.T


@dataclass(frozen=True)
class ContactResult:
    """Contact contributions of one indenter on its candidate facets.

    Attributes
    ----------
    energy : float (J); for Coulomb slip points the work-like value ``w mu p |s|``.
    force : (f, 7, 3) float array, dPi/d(node positions) per facet node, and in slot 6
        dPi/dc for the indenter centre (N).
    K : (f, 21, 21) float array or None, the block tangent (N/m).
    p : (f, q) nominal pressure (Pa).
    gap : (f, q) normal gap (m), negative = penetration.
    slip : (f, q) bool, points in Coulomb slip.
    s : (f, q, 3) elastic tangential slip (m).
    anchor : (f, q, 3) float array or None, the stick anchors used, relative to the centre
        (m): the fixed ones, and first-touch anchors for the points that came into contact
        since the previous iterate; None without friction.
    y : (f, q, 3) positions of the points relative to the centre (m).
    """

    energy: float
    force: np.ndarray
    K: np.ndarray | None
    p: np.ndarray
    gap: np.ndarray
    slip: np.ndarray
    s: np.ndarray
    anchor: np.ndarray | None = None
    y: np.ndarray | None = None


def first_touch_anchors(y, trial, anchor, anchored, y_from, lam, eps_n, radius):
    """Stick anchors (f, q, 3) with first-touch anchors for the points newly in contact.

    Points with ``anchored`` keep ``anchor``; the others out of contact get their own
    projection on the sphere (unused while they are out of contact). A point in contact
    now (``trial > 0``) and not anchored is anchored where the straight path from
    ``y_from`` (its position at the previous iterate, relative to the centre) to ``y``
    crosses the contact
    condition ``lambda - eps_n g = 0`` (module docstring), projected on the sphere; a
    point already in contact at ``y_from`` (after a multiplier update) is anchored at
    its own projection. Positions in m, ``lam`` and ``trial`` in Pa.

    Examples
    --------
    A point 10 um above a 1 mm sphere's pole moves to about 10 um inside it and 20 um
    sideways: it touched about half-way, 10 um to the side.

    >>> import numpy as np
    >>> y0 = np.array([[[0.0, 0.0, 1.01e-3]]])
    >>> y1 = np.array([[[2e-5, 0.0, 0.99e-3]]])
    >>> t1 = -1e9 * (np.linalg.norm(y1, axis=-1) - 1e-3)
    >>> a = first_touch_anchors(y1, t1, np.zeros_like(y1), np.zeros((1, 1), bool), y0,
    ...                         np.zeros((1, 1)), 1e9, 1e-3)
    >>> np.round(a[0, 0] * 1e6, 2).tolist()  # um
    [10.1, 0.0, 999.95]
    """
    fresh = (trial > 0) & ~anchored
    yc = y
    if y_from is not None and np.any(fresh):
        t0 = lam - eps_n * (np.linalg.norm(y_from, axis=-1) - radius)
        cross = fresh & (t0 <= 0)
        tau = np.where(cross, t0 / np.where(cross, t0 - trial, 1.0), 1.0)
        yc = y_from + tau[..., None] * (y - y_from)
    proj = radius * yc / np.linalg.norm(yc, axis=-1, keepdims=True)
    # points out of contact and not anchored get their projection: unused, but finite
    return np.where(anchored[..., None], anchor, proj)


def sphere_contact(
    xq: np.ndarray,
    w: np.ndarray,
    centre: np.ndarray,
    radius: float,
    lam: np.ndarray,
    eps_n: float,
    *,
    mu: float = 0.0,
    anchor: np.ndarray | None = None,
    anchored: np.ndarray | None = None,
    y_from: np.ndarray | None = None,
    eps_t: float = 0.0,
    tangent: bool = True,
    p_curvature_cap: float = np.inf,
) -> ContactResult:
    """Augmented-Lagrangian sphere contact at surface quadrature points.

    Parameters
    ----------
    xq : (f, q, 3) float array
        Current positions of the quadrature points (m).
    w : (f, q) float array
        Reference-area weights (m^2).
    centre : (3,) float array
        Current indenter centre (m).
    radius : float
        Sphere radius (m).
    lam : (f, q) float array
        Normal multipliers (Pa), >= 0.
    eps_n, eps_t : float
        Normal and tangential penalties (Pa/m).
    mu : float
        Friction coefficient; 0 frictionless, ``inf`` full stick.
    anchor : (f, q, 3) float array or None
        Stick anchors relative to the centre (m); required when ``mu > 0``.
    anchored : (f, q) bool array, optional
        The points whose anchor is fixed (in contact at the previous iterate); the
        others are anchored where they first touch (:func:`first_touch_anchors`).
        Default: every anchor is fixed.
    y_from : (f, q, 3) float array, optional
        Positions relative to the centre at the previous iterate (m), for the
        first-touch anchors; without it a newly touching point is anchored at its own
        projection.
    p_curvature_cap : float
        Pressure (Pa) above which the curvature term of the normal tangent,
        ``-(p / r) (I - n n)``, is taken at this pressure instead of ``p``. That term is
        a NEGATIVE tangential stiffness: a point pushed deep into the sphere is pushed
        sideways out of it. With the penalty pressures of a first placement (100 times
        the physical ones) it outweighs the sheet's lateral stiffness, the tangent turns
        indefinite and Newton throws surface nodes millimetres sideways (inverted
        elements, line-search crawl). Only the tangent changes, never the residual, so
        the converged state is the same; below the cap the tangent is exact.
    """
    y = xq - centre
    r = np.linalg.norm(y, axis=-1)
    n = y / r[..., None]
    g = r - radius
    trial = lam - eps_n * g
    act = trial > 0
    p = np.where(act, trial, 0.0)
    energy = float((w / (2 * eps_n) * (p * p - lam * lam)).sum())
    gy = -(w * p)[..., None] * n  # dPi/dy
    eye = np.eye(3)
    H = None
    if tangent:
        nn = n[..., :, None] * n[..., None, :]
        pc = np.minimum(p, p_curvature_cap)
        H = (w * act)[..., None, None] * (eps_n * nn - (pc / r)[..., None, None] * (eye - nn))
    slip = np.zeros(g.shape, dtype=bool)
    s = np.zeros_like(y)
    if mu > 0:
        if anchor is None:
            raise ValueError("friction needs stick anchors")
        if anchored is not None:
            anchor = first_touch_anchors(y, trial, anchor, anchored, y_from, lam, eps_n, radius)
        n0 = anchor / np.linalg.norm(anchor, axis=-1, keepdims=True)
        d = y - anchor
        s = d - np.einsum("fqi,fqi->fq", d, n0)[..., None] * n0
        s = np.where(act[..., None], s, 0.0)
        s_norm = np.linalg.norm(s, axis=-1)
        P0 = eye - n0[..., :, None] * n0[..., None, :]
        slip = act & (eps_t * s_norm > mu * p) if np.isfinite(mu) else np.zeros_like(act)
        stick = act & ~slip
        # stick: energy eps_t |s|^2 / 2, force eps_t s, tangent eps_t P0
        energy += float((w * stick * 0.5 * eps_t * s_norm**2).sum())
        gy = gy + (w * stick * eps_t)[..., None] * s
        if tangent:
            H = H + (w * stick * eps_t)[..., None, None] * P0
        if np.any(slip):
            safe = np.where(slip, s_norm, 1.0)
            e = s / safe[..., None]
            energy += float((w * slip * mu * p * s_norm).sum())
            gy = gy + (w * slip * mu * p)[..., None] * e
            if tangent:
                # d(mu p e)/dy = mu e (x) dp/dy + mu p (I - e e) P0 / |s|, dp/dy = -eps_n n
                ee = e[..., :, None] * e[..., None, :]
                Hs = -mu * eps_n * e[..., :, None] * n[..., None, :]
                Hs = Hs + (mu * p / safe)[..., None, None] * np.einsum(
                    "fqij,fqjk->fqik", eye - ee, P0
                )
                H = H + (w * slip)[..., None, None] * Hs
    force = np.einsum("qa,fqi->fai", _NEXT, gy)
    K = None
    if tangent:
        K = np.einsum("qa,qb,fqik->faibk", _NEXT, _NEXT, H, optimize=True).reshape(-1, 21, 21)
    return ContactResult(energy, force, K, p, g, slip, s, anchor if mu > 0 else None, y)
