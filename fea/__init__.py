"""fea stage: hyperelastic large-deformation FEM with rigid spherical indenters.

Quadratic tets with mean dilatation (fea.assembly), neo-Hookean and Mooney-Rivlin solids
and their Cauchy stress (fea.materials), augmented-Lagrangian sphere contact with Coulomb
friction or full stick (fea.contact), the discrete problem (fea.model), Newton with line
search (fea.newton), load stepping with cut-back (fea.solver) and its cost before it
starts (fea.estimate), stress and contact recovery (fea.recovery) with the contact edge
fitted to the open gap (fea.contact_edge), one :class:`Solution` per load state
(fea.solution), and the closed-form checks (fea.analytic).
"""

from .analytic import depth_guess, dimitriadis_force, hertz_force
from .contact import FRICTION_STICK
from .contact_edge import edge_radius
from .estimate import SolveEstimate, estimate_solve
from .linsolve import LinearSolver, available_backends
from .materials import (
    POLYCARBONATE_DEFAULT,
    SHEET_DEFAULT,
    Material,
    MooneyRivlin,
    NeoHookean,
    material_from_dict,
)
from .problem import ContactSettings, Indenter, SolverSettings
from .solution import IndenterState, Solution, write_solution_vtu
from .solver import SolveInterrupted, SolverError, SolveStats, solve

__all__ = [
    "FRICTION_STICK",
    "LinearSolver",
    "available_backends",
    "Material",
    "NeoHookean",
    "MooneyRivlin",
    "SHEET_DEFAULT",
    "POLYCARBONATE_DEFAULT",
    "material_from_dict",
    "Indenter",
    "ContactSettings",
    "SolverSettings",
    "IndenterState",
    "Solution",
    "write_solution_vtu",
    "SolveInterrupted",
    "SolverError",
    "SolveStats",
    "solve",
    "SolveEstimate",
    "estimate_solve",
    "depth_guess",
    "dimitriadis_force",
    "hertz_force",
    "edge_radius",
]
