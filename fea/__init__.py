"""fea stage: hyperelastic large-deformation FEM with rigid spherical indenters.

Quadratic tets with mean dilatation (fea.assembly), neo-Hookean and Mooney-Rivlin solids
(fea.materials), augmented-Lagrangian sphere contact with Coulomb friction or full stick
(fea.contact), force- or displacement-controlled load paths solved by Newton continuation
(fea.solver), one :class:`Solution` per load state (fea.solution).
"""

from .contact import FRICTION_STICK
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
from .solver import SolverError, SolveStats, dimitriadis_force, hertz_force, solve

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
    "SolverError",
    "SolveStats",
    "solve",
    "dimitriadis_force",
    "hertz_force",
]
