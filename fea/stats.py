"""What a solve cost: time per stage and iteration counts."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SolveStats"]


@dataclass
class SolveStats:
    """Where the time of a solve went (s) and how many iterations it took.

    Returned by :func:`solve` next to the solutions; filled in while the solve runs (the
    one mutable record of the fea stage). Times in s.

    Parameters
    ----------
    dofs : int
        Free degrees of freedom.
    backend : str
        The linear solver used (``"pardiso"`` or ``"scipy"``).
    time_setup, time_assembly, time_contact : float
        Wall time of the setup, element assembly and contact terms (s).
    time_analysis, time_factorize, time_solve, time_total : float
        Wall time of the symbolic analyses, numeric factorizations, triangular solves
        and the whole solve (s).
    newton_iterations : int
        Newton iterations over all load states.
    iterations_per_state : list of int
        Newton iterations of each load state.
    iteration_times : list of (float, float)
        Per Newton iteration: (wall time, factorization time) (s).
    increments, cutbacks, al_updates, cycle_breaks : int
        Converged load increments, halved increments, augmented-Lagrangian multiplier
        updates, and updates made to break a two-value cycle.
    tangent_assemblies, residual_evaluations : int
        Element tangents formed, and body evaluations of energy and residual.
    factorizations, factor_reuses : int
        Sparse factorizations, and Newton steps solved on an earlier factor.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, stats = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.2, 0.5])])
    >>> stats.dofs, len(stats.iterations_per_state)
    (525, 2)
    >>> stats.time_total > 0, sorted(stats.as_dict())[:2]
    (True, ['al_updates', 'backend'])
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
    increments: int = 0
    cutbacks: int = 0
    al_updates: int = 0
    #: multiplier updates made to break a two-value cycle of the Newton iterates
    cycle_breaks: int = 0
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
