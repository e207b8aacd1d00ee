"""The config schema: every key with its default, unit, allowed range and a line of help.

The defaults are the stage dataclasses' defaults in field units (``tests/test_inputs.py``
pins each one to its dataclass), so ``fringekit predict``, the Python API and
``fringekit config show`` describe one reference sensor.

Built-in cases (:data:`BUILTIN_CASES`): ``reference`` (3 mm PSM-4-class sheet on 15 mm
polycarbonate, one 3.5 mm indenter, 8 N vertical; the seed paper's Fig. 3a), ``shear``
(the same, then 6.4 N shear along x with full stick, 0.8 of the normal load: its Fig. 3b
pushes with 8 N, but at 1.0 the stuck sheet folds a tet at the trailing edge on the
default mesh, docs/validation.md) and ``small`` (the
reference sensor cut to a 20 mm sheet on 4 mm polycarbonate, a coarse mesh and a 64-pixel
image of 12 mm: the whole pipeline in seconds, for examples and tests; not
mesh-converged).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fringekit.errors import ConfigError

__all__ = ["BUILTIN_CASES", "ConfigError", "INDENTER_SCHEMA", "Key", "SCHEMA", "schema_key"]


@dataclass(frozen=True)
class Key:
    """One config key: default, unit, allowed values and a line of help."""

    default: Any
    help: str
    unit: str = ""
    kind: str = "float"  # float | int | str | bool | floats | pairs | friction | point
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple | None = None

    def allowed(self) -> str:
        """What is allowed, in words: ``allowed range (0, 100] mm`` (or the choices)."""
        if self.choices is not None:
            return f"allowed values {list(self.choices)}"
        lo = "(" if self.lo_open else "["
        return f"allowed range {lo}{self.lo:g}, {self.hi:g}]" + (
            f" {self.unit}" if self.unit else ""
        )


def _f(default, help, unit="", lo=None, hi=None, lo_open=False):
    return Key(default, help, unit, "float", lo, hi, lo_open)


#: Per-indenter keys (``[[indenter]]`` tables).
INDENTER_SCHEMA: dict[str, Key] = {
    "x_mm": _f(0.0, "indenter axis x on the undeformed contact face", "mm", -1e3, 1e3),
    "y_mm": _f(0.0, "indenter axis y", "mm", -1e3, 1e3),
    "diameter_mm": _f(3.5, "sphere diameter (seed paper: 3.5 mm head)", "mm", 0, 100, True),
    "load_N": Key(
        [8.0],
        "normal force per load state (a number or a list; force control)",
        "N",
        "floats",
        0,
        1e4,
    ),
    "depth_mm": Key(
        None,
        "prescribed depth per load state instead of load_N (displacement control)",
        "mm",
        "floats",
        0,
        100,
    ),
    "shear_N": Key(
        None,
        "tangential force [fx, fy] per load state (needs friction); one pair = every state",
        "N",
        "pairs",
        -1e4,
        1e4,
    ),
}

#: Table -> key -> Key. ``case`` is top level.
SCHEMA: dict[str, Any] = {
    "case": Key("reference", "case name: the output folder is <out>/<case>", kind="str"),
    "sheet": {
        "thickness_mm": _f(
            3.0,
            "photoelastic sheet thickness (seed paper: 3 mm; from a 10 um film, which keeps "
            "a stress from an order finite)",
            "mm",
            0.01,
            100,
        ),
        "width_mm": _f(40.0, "sheet size along x (assumed 40 mm)", "mm", 1, 2000),
        "length_mm": _f(40.0, "sheet size along y", "mm", 1, 2000),
        "model": Key(
            "neo-hookean",
            "hyperelastic model",
            kind="str",
            choices=("neo-hookean", "mooney-rivlin"),
        ),
        "E_MPa": _f(4.0, "Young's modulus (PSM-4 class, assumed)", "MPa", 0, 1e6, True),
        "nu": _f(0.49, "Poisson's ratio (neo-hookean)", "", 0, 0.4999),
        "C10_MPa": _f(0.6, "Mooney-Rivlin C10 (mooney-rivlin only)", "MPa", 0, 1e5),
        "C01_MPa": _f(0.07, "Mooney-Rivlin C01 (mooney-rivlin only)", "MPa", 0, 1e5),
        "K_MPa": _f(66.7, "bulk modulus (mooney-rivlin only)", "MPa", 0, 1e7, True),
    },
    "substrate": {
        "thickness_mm": _f(
            15.0, "polycarbonate thickness; 0 = sheet on a rigid base", "mm", 0, 500
        ),
        "E_MPa": _f(
            2300.0, "polycarbonate Young's modulus (datasheet, assumed)", "MPa", 0, 1e6, True
        ),
        "nu": _f(0.37, "polycarbonate Poisson's ratio", "", 0, 0.4999),
    },
    "mesh": {
        "symmetry": Key(
            "auto",
            "model part: auto picks the smallest part the indenters and loads allow",
            kind="str",
            choices=("auto", "full", "half", "quarter"),
        ),
        "mesher": Key(
            "layered",
            "layered: graded plane triangulation extruded through the layers, the same mesh "
            "on every run; tetwild: fTetWild, a different mesh on every run",
            kind="str",
            choices=("layered", "tetwild"),
        ),
        "h_contact_mm": _f(
            0.3,
            "edge length under each indenter (0.3 on 0.6 mm layers gives the 8 N order "
            "1.5-6 mm out to 0.015 fringe and the contact radius to 1.5 %, "
            "docs/validation.md; for much smaller contacts lower h_layer_mm too)",
            "mm",
            0,
            50,
            True,
        ),
        "refine_radius_mm": _f(
            2.0, "radius of the refined zone about each axis", "mm", 0, 500, True
        ),
        "h_sheet_mm": _f(2.0, "largest edge in the sheet", "mm", 0, 100, True),
        "h_far_mm": _f(8.0, "largest edge anywhere", "mm", 0, 500, True),
        "growth": _f(0.4, "size grading per unit distance", "", 0, 10, True),
        "h_layer_mm": _f(
            0.6,
            "thinnest element layer of the sheet: layers are max(h_contact, h_layer) thick, "
            "so 0 follows h_contact (layered mesher)",
            "mm",
            0,
            100,
        ),
    },
    "contact": {
        "friction": Key(
            0.0,
            'Coulomb coefficient >= 0, or "stick" for full stick',
            kind="friction",
            lo=0,
            hi=100,
        ),
        "penalty_factor": _f(100.0, "normal penalty / (E_sheet / h)", "", 0, 1e6, True),
        "penetration_tol": _f(
            0.01,
            "largest penetration as a fraction of the depth: multiplier updates run until "
            "the contact is within it (lower it on coarse meshes under stick, where the "
            "answer then moves less with the load steps; docs/validation.md)",
            "",
            0,
            0.1,
            True,
        ),
    },
    "solver": {
        "backend": Key(
            "auto", "sparse direct solver", kind="str", choices=("auto", "pardiso", "scipy")
        ),
        "precision": Key(
            "mixed",
            "pardiso factorization: single precision refined to double accuracy (2x faster), "
            "or double",
            kind="str",
            choices=("mixed", "double"),
        ),
        "force_tol": _f(1e-8, "residual tolerance relative to the applied force", "", 0, 0.1, True),
        "max_iterations": Key(30, "Newton iterations per attempt", kind="int", lo=2, hi=500),
        "max_cutbacks": Key(8, "load-increment halvings before giving up", kind="int", lo=0, hi=30),
    },
    "optics": {
        "f_sigma_N_per_m": _f(
            386.0,
            "material fringe value at wavelength_nm (PSM-4 class, assumed)",
            "N/m",
            0,
            1e8,
            True,
        ),
        "wavelength_nm": _f(575.0, "reference and monochrome wavelength", "nm", 360, 830),
        "dispersion": Key(
            "none",
            "dispersion of the stress-optic coefficient",
            kind="str",
            choices=("none", "cauchy", "power"),
        ),
        "dispersion_coefficient": _f(0.0, "Cauchy B (m^2) or power-law exponent", "", -1e3, 1e3),
        "field_of_view_mm": _f(20.0, "square field of view", "mm", 0, 2000, True),
        "center_mm": Key([0.0, 0.0], "field-of-view centre [x, y]", "mm", "point", -1e3, 1e3),
        "pixels": Key(256, "image size (pixels x pixels)", kind="int", lo=8, hi=4096),
        "samples_per_ray": Key(64, "slabs per ray through the sheet", kind="int", lo=4, hi=4096),
        "lateral_step_mm": _f(
            0.4,
            "pitch of the ray lattice the stress is sampled on and interpolated from, halved "
            "where its error check fails (0 = sample every pixel's ray)",
            "mm",
            0,
            100,
        ),
        "include_substrate": Key(
            False,
            "also integrate through the polycarbonate (light enters from the PC side)",
            kind="bool",
        ),
        "substrate_f_sigma_N_per_m": _f(
            7000.0,
            "polycarbonate fringe value at wavelength_nm (handbook, assumed)",
            "N/m",
            0,
            1e9,
            True,
        ),
        "substrate_samples_per_ray": Key(
            32, "slabs per ray through the polycarbonate", kind="int", lo=2, hi=4096
        ),
        "light": Key("LED", "white-light source", kind="str", choices=("LED", "A", "D65")),
        "white_light_wavelengths": Key(
            31,
            "wavelengths 400-700 nm for white light (even steps of the sheet's 2 pi C / lam)",
            kind="int",
            lo=4,
            hi=301,
        ),
        "camera": Key("CIE1931", "observer or colour-science camera name", kind="str"),
        "bit_depth": Key(8, "image bit depth", kind="int", choices=(8, 16)),
        "exposure": _f(
            0.9,
            "grey level of a fully transmitting pixel / full scale (< 1 keeps the brightest "
            "fringes unsaturated, as an experimenter exposes)",
            "",
            0,
            1e3,
            True,
        ),
        "full_well_e": _f(0.0, "electrons at full scale (shot noise; 0 = none)", "e-", 0, 1e7),
        "read_noise_e": _f(0.0, "read noise (needs full_well_e)", "e-", 0, 1e4),
        "seed": Key(0, "noise seed", kind="int", lo=0, hi=2**32 - 1),
        "qwp_error_deg": _f(0.0, "quarter-wave plate retardance error", "deg", -45, 45),
        "qwp_in_error_deg": _f(0.0, "input quarter-wave plate angle error", "deg", -45, 45),
        "qwp_out_error_deg": _f(0.0, "output quarter-wave plate angle error", "deg", -45, 45),
        "analyser_error_deg": _f(0.0, "analyser angle error", "deg", -45, 45),
        "render": Key(
            "last", "which load states get maps and images", kind="str", choices=("last", "all")
        ),
    },
}


def schema_key(name: str) -> Key:
    """The :class:`Key` of a dotted config key: ``"sheet.thickness_mm"``,
    ``"indenter.load_N"`` (a KeyError for an unknown one)."""
    table, _, key = name.partition(".")
    return INDENTER_SCHEMA[key] if table == "indenter" else SCHEMA[table][key]


_REFERENCE: dict[str, Any] = {"case": "reference"}
_SHEAR: dict[str, Any] = {
    "case": "shear",
    "contact": {"friction": "stick"},
    "indenter": [{"load_N": [8.0, 8.0], "shear_N": [[0.0, 0.0], [6.4, 0.0]]}],
}
_SMALL: dict[str, Any] = {
    "case": "small",
    "sheet": {"width_mm": 20.0, "length_mm": 20.0},
    "substrate": {"thickness_mm": 4.0},
    "mesh": {
        "h_contact_mm": 0.6,
        "refine_radius_mm": 1.5,
        "h_sheet_mm": 1.5,
        "h_far_mm": 4.0,
        "growth": 0.5,
    },
    "optics": {
        "field_of_view_mm": 12.0,
        "pixels": 64,
        "samples_per_ray": 24,
        "white_light_wavelengths": 9,
    },
}
#: Built-in cases by name (partial configs; defaults fill the rest).
BUILTIN_CASES: dict[str, dict] = {"reference": _REFERENCE, "shear": _SHEAR, "small": _SMALL}
