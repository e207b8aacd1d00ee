"""Inputs of the contact solver: indenters with load paths, contact and Newton settings.

Loads are the PHYSICAL loads on the whole indenter, whatever symmetry the mesh uses; the
solver applies the share of the modelled part and reports physical values back.
Lengths in m, forces in N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Indenter", "ContactSettings", "SolverSettings"]


def _finite_array(name: str, value, shape_tail: tuple[int, ...] = ()) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.ndim == 0 and not shape_tail:
        a = a[None]
    if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail or len(a) == 0:
        raise ValueError(
            f"{name} = {value!r} is not allowed; give a non-empty sequence of "
            + ("numbers" if not shape_tail else f"{shape_tail[0]}-vectors")
            + " (one per load state)"
        )
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} = {value!r} is not allowed; every value must be finite")
    return a


@dataclass(frozen=True)
class Indenter:
    """A rigid sphere with its load path.

    Loads are the physical loads on the whole indenter, whatever symmetry the mesh uses.

    Parameters
    ----------
    x, y : float
        Axis position on the undeformed contact face (m).
    radius : float
        Sphere radius (m). Reference: 1.75 mm (3.5 mm diameter head, seed paper Fig. 3).
    normal_force : sequence of float, optional
        Target normal force at each load state (N, >= 0, pressing). Force control: the
        solver finds the indenter's vertical position. Default (neither this nor
        ``depth`` given): the reference 8 N.
    depth : sequence of float, optional
        Prescribed indentation depth at each load state instead (m, >= 0, measured from
        first touch of the undeformed face). Give exactly one of ``normal_force``/``depth``.
    shear_force : sequence of (fx, fy), optional
        Target tangential force at each load state (N). Needs friction; without it the
        indenter does not move sideways.

    Raises
    ------
    ValueError
        Both or neither of ``normal_force`` and ``depth`` after the default, negative or
        non-finite loads, a depth beyond the radius, or load paths of different lengths.

    Examples
    --------
    >>> from fringekit.fea import Indenter
    >>> Indenter().normal_force  # the reference load
    (8.0,)
    >>> ind = Indenter(normal_force=[2, 4], shear_force=[(0, 0), (1, 0)])
    >>> ind.n_states, ind.force_control, ind.shear_targets().tolist()
    (2, True, [[0.0, 0.0], [1.0, 0.0]])
    >>> Indenter(depth=[0.2e-3]).normal_targets().tolist()  # m
    [0.0002]
    """

    x: float = 0.0
    y: float = 0.0
    radius: float = 1.75e-3
    normal_force: tuple[float, ...] | None = None
    depth: tuple[float, ...] | None = None
    shear_force: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self) -> None:
        for name in ("x", "y"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"indenter.{name} = {v!r} is not allowed; it must be finite (m)")
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(
                f"indenter.radius = {self.radius!r} is not allowed; it must be > 0 (m)"
            )
        if self.normal_force is None and self.depth is None:
            object.__setattr__(self, "normal_force", (8.0,))  # the reference load
        if (self.normal_force is None) == (self.depth is None):
            raise ValueError(
                "indenter: give exactly one of normal_force (N, force control) and depth "
                f"(m, displacement control); got normal_force = {self.normal_force!r}, "
                f"depth = {self.depth!r}"
            )
        if self.normal_force is not None:
            a = _finite_array("indenter.normal_force", self.normal_force)
            if np.any(a < 0):
                raise ValueError(
                    f"indenter.normal_force = {self.normal_force!r} is not allowed; forces must "
                    "be >= 0 N (the contact cannot pull the sheet)"
                )
            object.__setattr__(self, "normal_force", tuple(float(v) for v in a))
        if self.depth is not None:
            a = _finite_array("indenter.depth", self.depth)
            if np.any(a < 0) or np.any(a >= self.radius):
                raise ValueError(
                    f"indenter.depth = {self.depth!r} is not allowed; depths must be >= 0 and "
                    f"< the radius {self.radius!r} m"
                )
            object.__setattr__(self, "depth", tuple(float(v) for v in a))
        if self.shear_force is not None:
            a = _finite_array("indenter.shear_force", self.shear_force, (2,))
            object.__setattr__(self, "shear_force", tuple((float(u), float(v)) for u, v in a))
            if len(a) != self.n_states:
                raise ValueError(
                    f"indenter.shear_force has {len(a)} load states but the normal load has "
                    f"{self.n_states}; give one shear vector per load state"
                )

    @property
    def n_states(self) -> int:
        return len(self.normal_force if self.normal_force is not None else self.depth)

    @property
    def force_control(self) -> bool:
        return self.normal_force is not None

    def normal_targets(self) -> np.ndarray:
        """(S,) normal force (N) or depth (m) per state."""
        return np.asarray(self.normal_force if self.force_control else self.depth, dtype=float)

    def shear_targets(self) -> np.ndarray:
        """(S, 2) tangential force per state (N); zeros when no shear is given."""
        if self.shear_force is None:
            return np.zeros((self.n_states, 2))
        return np.asarray(self.shear_force, dtype=float)


@dataclass(frozen=True)
class ContactSettings:
    """Contact enforcement (augmented Lagrangian, Coulomb friction).

    Parameters
    ----------
    friction : float
        Coulomb coefficient (>= 0); 0 is frictionless, ``math.inf``
        (:data:`FRICTION_STICK`) full stick.
    penalty_factor : float
        Normal penalty as a multiple of E_sheet / h, h the mean contact facet size
        (dimensionless). The augmented-Lagrangian updates remove the penetration it leaves.
        100 leaves ~0.5 % of the depth after 0-3 updates per state; 10 needs ~2 per state
        and costs ~50 % more time on the reference case for the same depth (bench/fea.py).
    tangential_factor : float
        Tangential penalty as a multiple of the normal penalty.
    penetration_tol : float
        Largest allowed penetration as a fraction of the indentation depth (issue 3: 1 %).
    max_updates : int
        Largest number of multiplier updates per load state.

    Raises
    ------
    ValueError
        A negative or NaN friction, a factor or tolerance that is not > 0, or
        ``max_updates < 1``.

    Examples
    --------
    >>> from fringekit.fea import FRICTION_STICK, ContactSettings
    >>> ContactSettings(friction=FRICTION_STICK).friction
    inf
    >>> ContactSettings(friction=0.5, penetration_tol=0.005).max_updates
    12
    """

    friction: float = 0.0
    penalty_factor: float = 100.0
    tangential_factor: float = 1.0
    penetration_tol: float = 0.01
    max_updates: int = 12

    def __post_init__(self) -> None:
        if not (self.friction >= 0) or math.isnan(self.friction):
            raise ValueError(
                f"friction = {self.friction!r} is not allowed; use a coefficient >= 0 "
                "(0 frictionless, inf full stick)"
            )
        for name in ("penalty_factor", "tangential_factor", "penetration_tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"contact.{name} = {v!r} is not allowed; it must be > 0")
        if self.max_updates < 1:
            raise ValueError(f"contact.max_updates = {self.max_updates!r}; it must be >= 1")


@dataclass(frozen=True)
class SolverSettings:
    """Newton-Raphson and load-stepping controls.

    Parameters
    ----------
    force_tol : float
        Converged when the residual norm is below ``force_tol`` times the applied force
        (dimensionless).
    energy_tol : float
        ... and the last energy norm |du . r| is below ``energy_tol`` times its first value.
    max_iterations : int
        Newton iterations per attempt before the step is cut back.
    max_cutbacks : int
        Halvings of the load increment before giving up.
    backend : {"auto", "pardiso", "scipy"}
        Sparse direct solver (:class:`LinearSolver`).
    precision : {"mixed", "double"}
        PARDISO's factorization: single precision refined to double-precision accuracy
        (about twice as fast; :mod:`fea.linsolve`), or double precision.

    Raises
    ------
    ValueError
        Tolerances outside (0, 1), ``max_iterations < 2``, ``max_cutbacks < 0`` or an
        unknown precision.

    Examples
    --------
    >>> from fringekit.fea import SolverSettings
    >>> SolverSettings(backend="scipy", max_cutbacks=4).force_tol
    1e-08
    """

    force_tol: float = 1e-8
    energy_tol: float = 1e-10
    max_iterations: int = 30
    max_cutbacks: int = 8
    backend: str = "auto"
    precision: str = "mixed"

    def __post_init__(self) -> None:
        for name in ("force_tol", "energy_tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 < v < 1):
                raise ValueError(f"solver.{name} = {v!r} is not allowed; it must lie in (0, 1)")
        if self.max_iterations < 2:
            raise ValueError(f"solver.max_iterations = {self.max_iterations!r}; it must be >= 2")
        if self.max_cutbacks < 0:
            raise ValueError(f"solver.max_cutbacks = {self.max_cutbacks!r}; it must be >= 0")
        if self.precision not in ("mixed", "double"):
            raise ValueError(
                f"solver.precision = {self.precision!r} is not allowed; use 'mixed' or 'double'"
            )
