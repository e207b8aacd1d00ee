"""Closed-form sphere indentation: Hertz and a bonded incompressible layer.

Used as validation answers (tests, ``docs/validation.md``) and, by the solver, for first
guesses of the indentation depth and the stiffness of an indenter out of contact.
"""

from __future__ import annotations

import numpy as np

__all__ = ["hertz_force", "dimitriadis_force", "depth_guess"]


def hertz_force(depth, radius: float, E: float, nu: float):
    """Hertz sphere on a half-space: F = 4/3 E* R^1/2 d^3/2, E* = E / (1 - nu^2).

    H. Hertz, J. reine angew. Math. 92 (1882); K. L. Johnson, *Contact Mechanics*
    (Cambridge 1985), eq. 4.22.

    Parameters
    ----------
    depth : float or array
        Indentation depth (m).
    radius : float
        Sphere radius (m).
    E : float
        Young's modulus of the half-space (Pa); the sphere is rigid.
    nu : float
        Poisson's ratio of the half-space.

    Returns
    -------
    force : float or array
        Normal force (N), the shape of ``depth``.

    Examples
    --------
    >>> from fringekit.fea import hertz_force
    >>> round(float(hertz_force(0.1e-3, radius=1.75e-3, E=4e6, nu=0.49)), 3)  # N
    0.294
    """
    Es = E / (1 - nu**2)
    return 4.0 / 3.0 * Es * np.sqrt(radius) * np.asarray(depth) ** 1.5


def dimitriadis_force(depth, radius: float, E: float, thickness: float, *, bonded: bool = True):
    """Sphere on an incompressible layer of thickness h on a rigid base.

    Dimitriadis et al., Biophys. J. 82 (2002), eq. 12 (bonded) / 13 (unbonded), nu = 0.5:
    F = 16E/9 R^1/2 d^3/2 [1 + a1 chi + a2 chi^2 + a3 chi^3 + a4 chi^4], chi = sqrt(R d)/h.

    Parameters
    ----------
    depth : float or array
        Indentation depth (m).
    radius, thickness : float
        Sphere radius and layer thickness (m).
    E : float
        Young's modulus of the layer (Pa).
    bonded : bool
        The layer bonded to the base (eq. 12) or sliding on it (eq. 13).

    Returns
    -------
    force : float or array
        Normal force (N), the shape of ``depth``.

    Examples
    --------
    A thin layer is stiffer than the half-space of :func:`hertz_force`:

    >>> from fringekit.fea import dimitriadis_force
    >>> round(float(dimitriadis_force(0.1e-3, radius=1.75e-3, E=4e6, thickness=3e-3)), 3)  # N
    0.353
    """
    d = np.asarray(depth, dtype=float)
    chi = np.sqrt(radius * d) / thickness
    a = (1.133, 1.283, 0.769, 0.0975) if bonded else (0.884, 0.781, 0.386, 0.0048)
    series = 1 + a[0] * chi + a[1] * chi**2 + a[2] * chi**3 + a[3] * chi**4
    return 16.0 * E / 9.0 * np.sqrt(radius) * d**1.5 * series


def depth_guess(force: float, radius: float, E: float, thickness: float) -> float:
    """Depth at which the bonded-layer formula (:func:`dimitriadis_force`) gives a force.

    Bisection on [0, 0.95 radius]; the solver's first guess of an indenter's depth.

    Parameters
    ----------
    force : float
        Normal force (N).
    radius, thickness : float
        Sphere radius and layer thickness (m).
    E : float
        Young's modulus of the layer (Pa).

    Returns
    -------
    float
        Depth (m); 0 for a force <= 0.

    Examples
    --------
    >>> from fringekit.fea import depth_guess, dimitriadis_force
    >>> f = dimitriadis_force(0.1e-3, radius=1.75e-3, E=4e6, thickness=3e-3)
    >>> d = depth_guess(float(f), radius=1.75e-3, E=4e6, thickness=3e-3)
    >>> round(d * 1e3, 6)  # mm: the depth the force came from
    0.1
    """
    lo, hi = 0.0, 0.95 * radius
    if force <= 0:
        return 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if dimitriadis_force(mid, radius, E, thickness) < force:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
