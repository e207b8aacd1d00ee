"""One solve in progress: the model, its linear solver, counters and reusable body
evaluation (shared by :mod:`fea.newton`, :mod:`fea.recovery` and :mod:`fea.solver`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .linsolve import LinearSolver
from .model import Model
from .stats import SolveStats
from .watchdog import Watchdog

__all__ = ["BodyCache", "Run"]


class BodyCache:
    """The body's last element evaluation and the displacements it was made at.

    The body part (energy, internal forces, element tangents) depends on the
    displacements only. A line search's accepted trial, multiplier updates, the start of
    an increment and the stress recovery happen at displacements already evaluated, so
    they reuse it (forming the tangent on it when first needed) and recompute the
    contact terms alone.
    """

    def __init__(self) -> None:
        self.u: np.ndarray | None = None
        self.body = None

    def get(self, u: np.ndarray):
        """The cached body state at ``u``, else None."""
        if self.body is None:
            return None
        return self.body if np.array_equal(u, self.u) else None

    def put(self, u: np.ndarray, body) -> None:
        self.u, self.body = u.copy(), body


@dataclass(frozen=True)
class Run:
    """One solve in progress: the model, the linear solver, the counters it fills and the
    body evaluation it may reuse."""

    model: Model
    lin: LinearSolver
    stats: SolveStats
    cache: BodyCache = field(default_factory=BodyCache)
    watch: Watchdog = field(default_factory=Watchdog)
