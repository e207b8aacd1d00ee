"""What a solve cost: time per stage and iteration counts."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SolveStats"]


@dataclass
class SolveStats:
    """Where the time went (s) and how many iterations it took.

    Filled in while a solve runs (the one mutable record of the fea stage).
    """

    dofs: int = 0
    backend: str = ""
    time_setup: float = 0.0
    time_assembly: float = 0.0
    time_contact: float = 0.0
    time_analysis: float = 0.0
    time_factorize: float = 0.0
    time_solve: float = 0.0
    time_total: float = 0.0
    newton_iterations: int = 0
    iterations_per_state: list = field(default_factory=list)
    #: per Newton iteration: (wall time, factorization time) in s, from the tangent
    #: through the linear solve and the line search
    iteration_times: list = field(default_factory=list)
    cutbacks: int = 0
    al_updates: int = 0
    #: multiplier updates made to break a two-value cycle of the Newton iterates
    cycle_breaks: int = 0
    #: stalls with friction (a failed or crawling line search, a two-value cycle) after
    #: which the points that came into contact during the increment were anchored where
    #: they are (fea.newton._stalled)
    reanchors: int = 0
    #: element tangents formed (each on the kinematics of a residual evaluation, see
    #: fea.assembly.body_tangent), and body evaluations of energy and residual (the
    #: line-search trials and the unloaded start; reused by multiplier updates,
    #: increment starts and the stress recovery)
    tangent_assemblies: int = 0
    residual_evaluations: int = 0
    #: sparse factorizations, and Newton steps solved exactly on an earlier factor
    factorizations: int = 0
    factor_reuses: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)
