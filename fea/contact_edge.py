"""Where the contact ends: the contact radius from the open gap just outside the contact.

The sign of the contact pressure resolves the edge only to the quadrature points' spacing
(a ring of points switches in or out as the load or the load path changes), and under
stick the pressure at the last ring in contact does not fall to zero on a finite mesh.
The gap just outside the edge is smooth: near the edge of a smooth, non-conforming contact
the pressure falls as the square root of the distance to the edge and the separation grows
as its 3/2 power, so g^(2/3) is linear in the distance from the edge. For the Hertz
contact (Johnson, *Contact Mechanics*, 1985, §3.4: the displacement outside the loaded
circle) a straight line through g^(2/3) over the half contact radius beyond the edge finds
the edge to 4e-5 of the radius. :func:`edge_radius` fits that line to the open points of
an indenter's contact face, with the edge a circle about the indenter's axis shifted along
the directions no symmetry plane fixes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EDGE_BAND", "edge_radius"]

#: The band beyond the outermost point in contact whose open gaps are fitted, as a
#: fraction of that point's distance from the axis.
EDGE_BAND = 0.5

_MIN_POINTS = 8
#: Refits about the fitted edge's centre: the radial distance from an off-centre axis is
#: the distance from the edge only to first order in the offset.
_RECENTRES = 2


def edge_radius(
    points: np.ndarray,
    gap: np.ndarray,
    active: np.ndarray,
    axis_xy: np.ndarray,
    fixed_axes: tuple[int, ...] = (),
) -> tuple[float, float] | None:
    """Contact radius from the open gap beyond the edge, and its standard error.

    Fits g^(2/3) = c (r - a_0 - d_x cos(theta) - d_y sin(theta)) by linear least squares
    over the open
    points (``gap > 0``, not ``active``) within :data:`EDGE_BAND` times the outermost
    active point's distance r_out beyond it; (r, theta) are polar coordinates about the
    indenter's axis in the x-y plane, and the shifts d_x, d_y are left out for the axes
    in ``fixed_axes`` (a symmetry plane through the axis fixes them). The fit is repeated
    twice about the centre it found (the radial distance from an off-centre axis is the
    distance from the edge only to first order in the offset), and the radius returned is
    that of the circle with the fitted edge's area, sqrt(a_0^2 + (d_x^2 + d_y^2) / 2).

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
        point). None when fewer than 8 open points lie in the band, no point is in contact,
        the gap does not grow outwards, or the edge falls outside the band's span.

    Examples
    --------
    The Hertz separation outside a contact of radius 1 mm under a sphere of radius 2 mm
    (Johnson 1985, eq. 3.42b with the Hertz pressure), sampled on rings about the axis:

    >>> import numpy as np
    >>> R, a = 2e-3, 1e-3
    >>> r = np.repeat(np.linspace(0.4e-3, 1.6e-3, 25), 8)
    >>> t = np.tile(np.linspace(0, 2 * np.pi, 8, endpoint=False), 25)
    >>> ra = np.maximum(r, a)
    >>> g = r**2 / (2 * R) - a**2 / R + ((2 * a * a - ra**2) * np.arcsin(a / ra)
    ...     + a * np.sqrt(ra**2 - a * a)) / (np.pi * R)
    >>> g = np.where(r <= a, 0.0, g)
    >>> pts = np.c_[r * np.cos(t), r * np.sin(t), np.zeros_like(r)]
    >>> a_fit, sd = edge_radius(pts, g, r <= a, np.zeros(2))
    >>> round(a_fit * 1e3, 3)
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
        rb, th = r[band], np.arctan2(d[band, 1], d[band, 0])
        harm = [np.cos(th), np.sin(th)]
        A = np.stack([rb, -np.ones_like(rb)] + [-harm[k] for k in free], axis=1)
        q = g[band] ** (2.0 / 3.0)
        coef, *_ = np.linalg.lstsq(A, q, rcond=None)
        c = coef[0]
        if c <= 0:
            return None
        u = coef[1:] / c  # (a0, the free shifts)
        centre[free] += u[1:]
    shifts = u[1:]
    a = float(np.sqrt(u[0] ** 2 + 0.5 * float(shifts @ shifts)))
    if not r[act].min() <= a <= r_out * (1.0 + EDGE_BAND):
        return None
    # the sandwich (heteroscedasticity-consistent) covariance: g^(2/3) amplifies the
    # scatter of the smallest gaps, next to the edge (H. White, Econometrica 48, 1980)
    e = q - A @ coef
    bread = np.linalg.pinv(A.T @ A)
    cov = bread @ ((A * (e * e)[:, None]).T @ A) @ bread * len(q) / max(len(q) - A.shape[1], 1)
    v = np.concatenate([[u[0]], 0.5 * shifts]) / a  # d a / d u
    grad = np.concatenate([[-float(v @ u) / c], v / c])  # d a / d coef
    sd = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
    return a, sd
