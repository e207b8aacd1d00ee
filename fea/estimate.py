"""What a solve will cost, before it starts: its load increments, Newton iterations and time.

The increments are those :func:`fea.solve` takes when no increment is cut back: the first
one from the unloaded sheet ends at :func:`fea.solver.first_fraction` of the load and the
next ones double, and with friction no normal load rises by more than
:data:`fea.solver.FRICTION_STEP` per increment and no tangential load changes by more
than :data:`fea.solver.TANGENT_STEP` of the normal one (:func:`fea.solver.friction_limit`). The
Newton iterations and the time per iteration are rates measured with ``bench/fea.py`` on
2 cores (:data:`RATES`); the time per iteration grows with the DOF as a power
(sparse factorization of a 3-D mesh, George & Liu, *Computer Solution of Large Sparse
Positive Definite Systems*, 1981: O(n^2) work for nested dissection, less in practice
for these flat meshes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .problem import ContactSettings, Indenter
from .solver import first_fraction, friction_limit

__all__ = ["RATES", "SolveEstimate", "estimate_solve", "increment_schedule"]

#: Measured on 2 cores (bench/fea.py --mesh coarse, 2026-11-25): Newton iterations of
#: the first increment from the unloaded sheet and of each later one, frictionless
#: (vertical 43 for 8 increments, reference 18 for 3, plate4 21 for 3) and with friction
#: (shear 126 for 25 increments); seconds per Newton iteration at ``dofs_ref`` mesh DOF
#: and the exponent of its growth with the DOF; seconds of set-up and recovery per 1k
#: DOF. The time per iteration was set again on 2026-11-27 (bench/fea.py --quick on a
#: quiet machine: 0.41 s at 36.8k DOF, the reference; 2.27 s at 83.4k, the plate, a
#: growth of 2.1 between them; 0.52-0.81 s on the reference beside other jobs): 0.6 s
#: and a growth of 1.5 had put the reference at 15 s against 8.7 s taken (1.7 times).
#: Now 13 s against 9.5 s (ratio 0.75) and 47 s against 55 s (1.17), rerun.
RATES = {
    "first_its": 9.0,
    "later_its": 4.8,
    "first_its_friction": 9.0,
    "later_its_friction": 4.9,
    "s_per_it": 0.5,
    "dofs_ref": 37.26e3,
    "growth": 1.75,
    "s_fixed_per_kdof": 0.05,
}


@dataclass(frozen=True)
class SolveEstimate:
    """The expected cost of one solve without cut-backs.

    Parameters
    ----------
    dofs : int
        Degrees of freedom of the mesh.
    states : int
        Load states.
    increments : tuple of int
        Load increments per state.
    newton_iterations : int
        Expected Newton iterations in all.
    seconds : float
        Expected wall time on 2 cores (s).

    Examples
    --------
    >>> est = SolveEstimate(dofs=34_500, states=1, increments=(3,), newton_iterations=22,
    ...                     seconds=11.6)
    >>> est.text()[:51]
    '34,500 DOF, 1 load state(s) in 3 increment(s); abou'
    """

    dofs: int
    states: int
    increments: tuple
    newton_iterations: int
    seconds: float

    def text(self) -> str:
        """One line: size, increments, iterations and time."""
        return (
            f"{self.dofs:,} DOF, {self.states} load state(s) in {sum(self.increments)} "
            f"increment(s); about {max(self.seconds, 1.0):.0f} s to solve on 2 cores "
            f"(~{self.newton_iterations} Newton iterations at the measured rate; within "
            "a factor of 1.5 on the benchmark cases)"
        )


def _loads(indenters: Sequence[Indenter]) -> tuple[np.ndarray, np.ndarray]:
    """(S + 1, m) whole normal loads per state (row 0 unloaded; 0 under depth control)
    and (S + 1, m, 2) tangential ones."""
    S = indenters[0].n_states
    normal, shear = np.zeros((S + 1, len(indenters))), np.zeros((S + 1, len(indenters), 2))
    for j, ind in enumerate(indenters):
        if ind.force_control:
            normal[1:, j] = ind.normal_targets()
        shear[1:, j] = ind.shear_targets()
    return normal, shear


def increment_schedule(
    indenters: Sequence[Indenter],
    *,
    E: float,
    h: float,
    friction: float,
    parents: Sequence[int] | None = None,
) -> tuple[int, ...]:
    """The load increments :func:`fea.solve` takes to each state when none is cut back.

    Parameters
    ----------
    indenters : sequence of Indenter
        The indenters and their load paths (whole loads).
    E : float
        The sheet's Young's modulus (Pa).
    h : float
        Sheet thickness (m).
    friction : float
        Friction coefficient (0 frictionless, ``inf`` full stick).
    parents : sequence of int, optional
        The state each state starts from (as in :func:`fea.solve`; default the previous).

    Returns
    -------
    tuple of int, increments per load state.

    Examples
    --------
    8 N on the reference sheet in one state, frictionless and under full stick:

    >>> from fringekit.fea import Indenter
    >>> ind = [Indenter(normal_force=(8.0,))]
    >>> increment_schedule(ind, E=4e6, h=3e-3, friction=0.0)
    (3,)
    >>> increment_schedule(ind, E=4e6, h=3e-3, friction=float("inf"))
    (15,)
    """
    L, T = _loads(indenters)
    S = len(L) - 1
    parents = list(parents) if parents is not None else list(range(S))
    radii = [ind.radius for ind in indenters]
    counts, s_done = [], 0.0
    for k in range(1, S + 1):
        p = parents[k - 1]
        if p != k - 1:
            s_done = float(k - 1)
        if p == 0:
            ds = first_fraction(L[k], radii, E, h, friction)
        else:
            ds = float(k) - s_done
        n = 0
        while s_done < k - 1e-12:
            cap = np.inf
            if friction > 0:
                t = s_done - (k - 1)
                here, there = L[p] + t * (L[k] - L[p]), T[p] + t * (T[k] - T[p])
                cap = friction_limit(here, L[k], s_done, k, there, T[k])
            s_done = min(s_done + ds, float(k), cap)
            ds = min(2 * ds, float(k) - s_done) if s_done < k else ds
            n += 1
        counts.append(n)
    return tuple(counts)


def estimate_solve(
    dofs: int,
    indenters: Sequence[Indenter],
    *,
    E: float,
    h: float,
    contact: ContactSettings | None = None,
    parents: Sequence[int] | None = None,
) -> SolveEstimate:
    """The expected increments, Newton iterations and time of a solve.

    Parameters
    ----------
    dofs : int
        Degrees of freedom of the mesh (``mesh.n_dofs``).
    indenters : sequence of Indenter
    E : float
        The sheet's Young's modulus (Pa).
    h : float
        Sheet thickness (m).
    contact : ContactSettings, optional
        Its friction sets the stepping and the iteration rates.
    parents : sequence of int, optional
        As in :func:`fea.solve`.

    Returns
    -------
    SolveEstimate

    Examples
    --------
    >>> from fringekit.fea import Indenter
    >>> est = estimate_solve(34_500, [Indenter(normal_force=(8.0,))], E=4e6, h=3e-3)
    >>> est.increments, est.newton_iterations
    ((3,), 19)
    """
    friction = (contact or ContactSettings()).friction
    incs = increment_schedule(indenters, E=E, h=h, friction=friction, parents=parents)
    parents = list(parents) if parents is not None else list(range(len(incs)))
    tag = "_friction" if friction > 0 else ""
    firsts = sum(1 for p in parents if p == 0)
    its = firsts * RATES["first_its" + tag] + (sum(incs) - firsts) * RATES["later_its" + tag]
    per_it = RATES["s_per_it"] * (dofs / RATES["dofs_ref"]) ** RATES["growth"]
    seconds = its * per_it + RATES["s_fixed_per_kdof"] * dofs / 1e3
    return SolveEstimate(int(dofs), len(incs), incs, int(round(its)), float(seconds))
