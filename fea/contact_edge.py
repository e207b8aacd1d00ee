"""Where the contact ends: the contact radius from the open gap just outside the contact.

The sign of the contact pressure resolves the edge only to the quadrature points' spacing
(a ring of points switches in or out as the load or the load path changes), and under
stick the pressure at the last ring in contact does not fall to zero on a finite mesh.
The gap just outside the edge is smooth: near the edge of a smooth, non-conforming contact
the pressure falls as the square root of the distance to the edge and the separation grows
as its 3/2 power, so g^(2/3) is linear in the distance from the edge (for Hertz's
contact: Johnson, *Contact Mechanics*, 1985, §3.4, the displacement outside the loaded
circle). Away from the edge it bends: the sphere's normal turns (the gap here is the
distance normal to the sphere, and a 3.5 mm sphere's contact reaches 0.67 of its radius)
and the layer is not a half-space. :func:`edge_radius` therefore fits a quadratic in r
to g^(2/3) over three quarters of a contact radius beyond the outermost point in contact
and takes its root: on the reference case (8 N, frictionless) it puts the edge 0.05-0.2 %
beyond that point on meshes of 0.3 and 0.2 mm, where a straight line put it 0.7 % inside.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EDGE_BAND", "MAX_SD", "edge_radius"]

#: The band beyond the outermost point in contact whose open gaps are fitted, as a
#: fraction of that point's distance from the axis.
EDGE_BAND = 0.75

_MIN_POINTS = 12
#: A fit whose sd exceeds this fraction of its radius is not taken: the contact spans too
#: few facets (the test blocks' 1 mm and 0.6 mm facets under contacts of 0.7-0.9 mm: sds
#: of 0.6-0.8 %, 11-68 open points in the band; the reference case's default mesh: 361
#: points, sd 0.12 %).
MAX_SD = 0.005
#: Refits about the fitted edge's centre: the radial distance from an off-centre axis is
#: the distance from the edge only to first order in the offset.
_RECENTRES = 2


def _fit(r, th, q, free):
    """Least squares of q = b0 + b1 r + b2 r^2 + (b_x cos th, b_y sin th as ``free``
    says): (coefficients, design matrix)."""
    harm = [np.cos(th), np.sin(th)]
    A = np.stack([np.ones_like(r), r, r * r] + [harm[k] for k in free], axis=1)
    coef, *_ = np.linalg.lstsq(A, q, rcond=None)
    return coef, A


def _root(coef, near: float) -> float | None:
    """The real root of b0 + b1 r + b2 r^2 nearest ``near`` where the quadratic rises."""
    b0, b1, b2 = coef[:3]
    roots = np.roots([b2, b1, b0]) if abs(b2) > 0 else np.array([-b0 / b1])
    roots = roots[np.abs(roots.imag) < 1e-12 * max(1.0, abs(near))].real
    roots = roots[b1 + 2 * b2 * roots > 0]
    return float(roots[np.argmin(np.abs(roots - near))]) if len(roots) else None


def edge_radius(
    points: np.ndarray,
    gap: np.ndarray,
    active: np.ndarray,
    axis_xy: np.ndarray,
    fixed_axes: tuple[int, ...] = (),
) -> tuple[float, float] | None:
    """Contact radius from the open gap beyond the edge, and its standard error.

    Fits g^(2/3) = b0 + b1 r + b2 r^2 + b_x cos(theta) + b_y sin(theta) by linear least
    squares over the open points (``gap > 0``, not ``active``) within :data:`EDGE_BAND`
    times the outermost active point's distance r_out beyond it, and takes the root of
    the quadratic nearest r_out where it rises; (r, theta) are polar coordinates about
    the indenter's axis in the x-y plane. The harmonic terms shift the edge's centre by
    d = -(b_x, b_y) / (b1 + 2 b2 a); they are left out for the axes in ``fixed_axes`` (a
    symmetry plane through the axis fixes them). The fit is repeated twice about the
    centre it found (the radial distance from an off-centre axis is the distance from the
    edge only to first order in the offset), and the radius returned is that of the
    circle with the fitted edge's area, sqrt(a^2 + |d|^2 / 2).

    Parameters
    ----------
    points : (m, 3) float array
        Current positions of the contact face's quadrature points (m).
    gap : (m,) float array
        Their normal gap to the indenter (m), negative where they penetrate.
    active : (m,) bool array
        The points in contact.
    axis_xy : (2,) float array
        The indenter's axis in the x-y plane (m).
    fixed_axes : tuple of int
        0 for the plane x = axis_x, 1 for y = axis_y: symmetry planes the contact's centre
        cannot leave.

    Returns
    -------
    (a, sd) : tuple of float, or None
        The radius of the fitted edge (m) and its standard error from the fit's residuals
        (m; the sandwich covariance, which holds when the scatter differs from point to
        point: g^(2/3) amplifies that of the smallest gaps). None when no point is in
        contact, fewer than 12 open points lie in the band, the quadratic has no rising
        root, the root falls outside the band's span, or the sd exceeds :data:`MAX_SD` of
        the radius.

    Examples
    --------
    The Hertz separation outside a contact of radius 1 mm under a sphere of radius 2 mm
    (Johnson 1985, eq. 3.42b with the Hertz pressure), sampled on rings about the axis:

    >>> import numpy as np
    >>> R, a = 2e-3, 1e-3
    >>> r = np.repeat(np.linspace(0.4e-3, 1.9e-3, 31), 8)
    >>> t = np.tile(np.linspace(0, 2 * np.pi, 8, endpoint=False), 31)
    >>> ra = np.maximum(r, a)
    >>> g = r**2 / (2 * R) - a**2 / R + ((2 * a * a - ra**2) * np.arcsin(a / ra)
    ...     + a * np.sqrt(ra**2 - a * a)) / (np.pi * R)
    >>> g = np.where(r <= a, 0.0, g)
    >>> pts = np.c_[r * np.cos(t), r * np.sin(t), np.zeros_like(r)]
    >>> a_fit, sd = edge_radius(pts, g, r <= a, np.zeros(2))
    >>> round(a_fit * 1e3, 2)
    1.0
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    g = np.asarray(gap, dtype=float).ravel()
    act = np.asarray(active, dtype=bool).ravel()
    if not act.any():
        return None
    centre = np.asarray(axis_xy, dtype=float).copy()
    free = [k for k in (0, 1) if k not in fixed_axes]
    for _ in range(_RECENTRES + 1):
        d = pts[:, :2] - centre[None, :]
        r = np.hypot(d[:, 0], d[:, 1])
        r_out = float(r[act].max())
        band = ~act & (g > 0) & (r > r_out) & (r < r_out * (1.0 + EDGE_BAND))
        if band.sum() < _MIN_POINTS:
            return None
        q = g[band] ** (2.0 / 3.0)
        coef, A = _fit(r[band], np.arctan2(d[band, 1], d[band, 0]), q, free)
        a0 = _root(coef, r_out)
        if a0 is None:
            return None
        slope = coef[1] + 2 * coef[2] * a0
        shift = -coef[3:] / slope
        centre[free] += shift
    a = float(np.sqrt(a0**2 + 0.5 * float(shift @ shift)))
    if not r[act].min() <= a <= r_out * (1.0 + EDGE_BAND):
        return None
    # the sandwich (heteroscedasticity-consistent) covariance (H. White, Econometrica 48,
    # 1980), carried to the root by its gradient: d a0 / d b = -(1, a0, a0^2) / slope
    e = q - A @ coef
    bread = np.linalg.pinv(A.T @ A)
    cov = bread @ ((A * (e * e)[:, None]).T @ A) @ bread * len(q) / max(len(q) - A.shape[1], 1)
    grad = -np.array([1.0, a0, a0 * a0]) / slope
    sd = float(np.sqrt(max(grad @ cov[:3, :3] @ grad, 0.0)))
    return (a, sd) if sd <= MAX_SD * a else None
