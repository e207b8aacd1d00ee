"""One source of defaults: every config default equals the stage dataclass default it
becomes, and every command builds its stage inputs through ``fringekit.config.inputs``."""

from __future__ import annotations

import inspect
import math

import pytest

from fringekit.config.files import apply_overrides, load_config
from fringekit.config.inputs import build_inputs
from fringekit.config.schema import INDENTER_SCHEMA, SCHEMA
from fringekit.fea import (
    POLYCARBONATE_DEFAULT,
    SHEET_DEFAULT,
    ContactSettings,
    Indenter,
    SolverSettings,
)
from fringekit.meshes import Layers, MeshSpec, Sizing
from fringekit.optics import (
    POLYCARBONATE_ASSUMED,
    PSM4_ASSUMED,
    Camera,
    StressOpticLaw,
    sample_rays,
)

MM = 1e-3


def _default(table: str, key: str):
    return (INDENTER_SCHEMA if table == "indenter" else SCHEMA[table])[key].default


# (config table, key, dataclass default in SI, factor config unit -> SI)
PINS = [
    ("sheet", "thickness_mm", Layers().sheet_thickness, MM),
    ("sheet", "width_mm", Layers().width, MM),
    ("sheet", "length_mm", Layers().length, MM),
    ("sheet", "E_MPa", SHEET_DEFAULT.E, 1e6),
    ("sheet", "nu", SHEET_DEFAULT.nu, 1.0),
    ("substrate", "thickness_mm", Layers().substrate_thickness, MM),
    ("substrate", "E_MPa", POLYCARBONATE_DEFAULT.E, 1e6),
    ("substrate", "nu", POLYCARBONATE_DEFAULT.nu, 1.0),
    ("mesh", "mesher", MeshSpec().mesher, None),
    ("mesh", "h_contact_mm", Sizing().h_contact, MM),
    ("mesh", "refine_radius_mm", Sizing().refine_radius, MM),
    ("mesh", "h_sheet_mm", Sizing().h_sheet, MM),
    ("mesh", "h_far_mm", Sizing().h_far, MM),
    ("mesh", "growth", Sizing().growth, 1.0),
    ("mesh", "h_layer_mm", Sizing().h_layer, MM),
    ("contact", "friction", ContactSettings().friction, 1.0),
    ("contact", "penalty_factor", ContactSettings().penalty_factor, 1.0),
    ("contact", "penetration_tol", ContactSettings().penetration_tol, 1.0),
    ("solver", "force_tol", SolverSettings().force_tol, 1.0),
    ("solver", "max_iterations", SolverSettings().max_iterations, 1),
    ("solver", "max_cutbacks", SolverSettings().max_cutbacks, 1),
    ("solver", "backend", SolverSettings().backend, None),
    ("solver", "precision", SolverSettings().precision, None),
    ("optics", "f_sigma_N_per_m", PSM4_ASSUMED.f_sigma, 1.0),
    ("optics", "wavelength_nm", PSM4_ASSUMED.wavelength_ref, 1e-9),
    ("optics", "dispersion", StressOpticLaw(f_sigma=1.0).dispersion, None),
    ("optics", "dispersion_coefficient", StressOpticLaw(f_sigma=1.0).coefficient, 1.0),
    ("optics", "substrate_f_sigma_N_per_m", POLYCARBONATE_ASSUMED.f_sigma, 1.0),
    ("optics", "camera", Camera().sensitivities, None),
    ("optics", "exposure", Camera().exposure, 1.0),
    ("optics", "bit_depth", Camera().bit_depth, 1),
    ("optics", "full_well_e", Camera().full_well, 1.0),
    ("optics", "read_noise_e", Camera().read_noise, 1.0),
    ("indenter", "diameter_mm", 2 * Indenter().radius, MM),
    ("indenter", "x_mm", Indenter().x, MM),
    ("indenter", "y_mm", Indenter().y, MM),
]


@pytest.mark.parametrize(("table", "key", "expected", "unit"), PINS, ids=lambda v: str(v))
def test_config_default_is_the_dataclass_default(table, key, expected, unit):
    value = _default(table, key)
    if unit is None:
        assert value == expected
    else:
        # f_sigma of PSM4_ASSUMED is derived from K, E, nu (385.9 N/m); the config shows 386
        assert value * unit == pytest.approx(expected, rel=1e-3, abs=1e-15)


def test_ray_sampling_and_load_defaults():
    params = inspect.signature(sample_rays).parameters
    assert SCHEMA["optics"]["samples_per_ray"].default > 0
    assert params["lateral_step"].default is None  # the config's 0.4 mm is a speed choice
    assert _default("indenter", "load_N") == list(Indenter().normal_targets())
    assert _default("contact", "friction") == 0.0 and math.isfinite(ContactSettings().friction)


def test_reference_config_builds_the_default_mesh_spec():
    """The built-in reference case meshes exactly as MeshSpec() in quarter symmetry."""
    inp = build_inputs(load_config())
    assert inp.spec == MeshSpec(symmetry="quarter")
    assert inp.optics.camera == Camera()
    assert inp.contact == ContactSettings() and inp.settings == SolverSettings()
    assert inp.materials[0] == SHEET_DEFAULT and inp.materials[1] == POLYCARBONATE_DEFAULT


def test_contact_keys_reach_the_contact_settings():
    """Each contact key becomes its ContactSettings field (a key dropped on the way would
    leave the default in place and pass the test above)."""
    cfg = apply_overrides(
        load_config(),
        {
            "contact.friction": "stick",
            "contact.penalty_factor": 50.0,
            "contact.penetration_tol": 0.002,
        },
    )
    assert build_inputs(cfg).contact == ContactSettings(
        friction=math.inf, penalty_factor=50.0, penetration_tol=0.002
    )
