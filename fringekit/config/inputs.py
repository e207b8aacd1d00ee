"""A config turned into the pipeline's inputs: frozen SI dataclasses, built in one place.

:func:`build_inputs` is the one road from an effective config (field units, dicts) to
the objects the stages take (SI): the :class:`meshes.MeshSpec`, the :class:`fea.Indenter`
set of the modelled part, the materials, the contact and solver settings and the optics
(:class:`OpticsSetup`). ``fringekit predict``, ``calibrate``, ``sweep`` and ``mesh`` all
go through it, so a config default and the stage defaults cannot drift apart unnoticed
(``tests/test_inputs.py`` pins them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fringekit.config.files import ConfigError, normal_path
from fringekit.config.memory import check_mesh_memory, check_ray_memory
from fringekit.fea import ContactSettings, Indenter, Material, SolverSettings, material_from_dict
from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing
from fringekit.optics import Camera, PixelGrid, StressOpticLaw

__all__ = [
    "OpticsSetup",
    "RunInputs",
    "build_inputs",
    "check_layout",
    "choose_symmetry",
    "mesh_spec",
    "optics_setup",
]

MM = 1e-3


def _load_path(d: dict) -> tuple[tuple, tuple]:
    normal = tuple(normal_path(d))
    shear = tuple(tuple(p) for p in d["shear_N"]) if d["shear_N"] is not None else None
    return normal, shear


def _mirror_ok(inds: list[dict], axis: int) -> bool:
    """True when the indenter set with its loads maps onto itself under x_axis -> -x_axis."""
    for d in inds:
        pos = [d["x_mm"], d["y_mm"]]
        normal, shear = _load_path(d)
        mpos = list(pos)
        mpos[axis] = -mpos[axis]
        mshear = None
        if shear is not None:
            mshear = tuple(tuple(-p[a] if a == axis else p[a] for a in range(2)) for p in shear)
        found = False
        for e in inds:
            n2, s2 = _load_path(e)
            if (
                abs(e["x_mm"] - mpos[0]) < 1e-9
                and abs(e["y_mm"] - mpos[1]) < 1e-9
                and abs(e["diameter_mm"] - d["diameter_mm"]) < 1e-12
                and (e["load_N"] is None) == (d["load_N"] is None)
                and np.allclose(n2, normal)
                and np.allclose(s2 if s2 is not None else 0.0, mshear if mshear else 0.0)
            ):
                found = True
                break
        if not found:
            return False
    return True


def choose_symmetry(cfg: dict) -> str:
    """The model part: the config's, or for ``auto`` the smallest one the loads allow.

    Quarter needs the indenter set, with its load paths, mirror-symmetric about x = 0 and
    y = 0; half about y = 0 (shear along x allowed). A requested part the loads do not
    allow is a :class:`ConfigError`.
    """
    inds = cfg["indenter"]
    ok = {"full": True, "half": _mirror_ok(inds, 1)}
    ok["quarter"] = ok["half"] and _mirror_ok(inds, 0)
    want = cfg["mesh"]["symmetry"]
    if want == "auto":
        return "quarter" if ok["quarter"] else "half" if ok["half"] else "full"
    if not ok[want]:
        raise ConfigError(
            f"mesh.symmetry = {want!r} is not allowed for these indenters and loads: they are "
            "not mirror-symmetric about "
            + ("y = 0" if want == "half" or not ok["half"] else "x = 0")
            + '; use "full" or "auto"'
        )
    return want


def check_layout(cfg: dict) -> None:
    """Refuse indenters whose heads reach off the sheet or overlap one another
    (:class:`ConfigError` naming the config keys, in mm): the checks of FEM ``predict``'s
    mesh, for every path that places heads (``predict --library`` too).

    Examples
    --------
    >>> import fringekit
    >>> cfg = fringekit.Config.reference().replace({"indenter[0].x_mm": 18.5}).data
    >>> check_layout(cfg)
    Traceback (most recent call last):
    ...
    fringekit.errors.ConfigError: indenter[0] at x_mm = 18.5, y_mm = 0 with diameter_mm = 3.5
    reaches off the 40 x 40 mm sheet; allowed: |x_mm| + diameter_mm / 2 <= 20 and
    |y_mm| + diameter_mm / 2 <= 20
    """
    sh, inds = cfg["sheet"], cfg["indenter"]
    w, h = sh["width_mm"] / 2, sh["length_mm"] / 2
    for i, d in enumerate(inds):
        r = d["diameter_mm"] / 2
        if abs(d["x_mm"]) + r > w or abs(d["y_mm"]) + r > h:
            raise ConfigError(
                f"indenter[{i}] at x_mm = {d['x_mm']:g}, y_mm = {d['y_mm']:g} with diameter_mm = "
                f"{d['diameter_mm']:g} reaches off the {2 * w:g} x {2 * h:g} mm sheet; allowed: "
                f"|x_mm| + diameter_mm / 2 <= {w:g} and |y_mm| + diameter_mm / 2 <= {h:g}"
            )
    for i, a in enumerate(inds):
        for j in range(i + 1, len(inds)):
            b = inds[j]
            dist = math.hypot(a["x_mm"] - b["x_mm"], a["y_mm"] - b["y_mm"])
            if dist < (a["diameter_mm"] + b["diameter_mm"]) / 2:
                raise ConfigError(
                    f"indenter[{i}] and indenter[{j}] overlap: their centres are {dist:.4g} mm "
                    f"apart; allowed: at least the sum of their radii, "
                    f"{(a['diameter_mm'] + b['diameter_mm']) / 2:g} mm"
                )


def mesh_spec(cfg: dict, symmetry: str | None = None) -> MeshSpec:
    """The :class:`meshes.MeshSpec` (SI) of an effective config.

    ``symmetry`` defaults to :func:`choose_symmetry`. Geometry errors (an indenter off
    the sheet, ...) and a mesh too large for the memory free
    (:func:`fringekit.config.memory.check_mesh_memory`) become a :class:`ConfigError`.
    """
    check_layout(cfg)
    sh, sub, m = cfg["sheet"], cfg["substrate"], cfg["mesh"]
    try:
        spec = MeshSpec(
            layers=Layers(
                sheet_thickness=sh["thickness_mm"] * MM,
                substrate_thickness=sub["thickness_mm"] * MM,
                width=sh["width_mm"] * MM,
                length=sh["length_mm"] * MM,
            ),
            indenters=tuple(
                IndenterSite(d["x_mm"] * MM, d["y_mm"] * MM, d["diameter_mm"] * 0.5 * MM)
                for d in cfg["indenter"]
            ),
            sizing=Sizing(
                h_contact=m["h_contact_mm"] * MM,
                refine_radius=m["refine_radius_mm"] * MM,
                h_far=m["h_far_mm"] * MM,
                h_sheet=m["h_sheet_mm"] * MM,
                growth=m["growth"],
                h_layer=m["h_layer_mm"] * MM,
            ),
            symmetry=symmetry or choose_symmetry(cfg),
            mesher=m["mesher"],
        )
    except ValueError as exc:  # geometry errors speak SI; say which config part it is
        raise ConfigError(f"geometry: {exc}") from None
    check_mesh_memory(cfg, spec)
    return spec


def _indenters(cfg: dict, symmetry: str) -> tuple[Indenter, ...]:
    """The config's indenters that lie in the modelled part (x, y >= 0 on mirror planes)."""
    out = []
    for d in cfg["indenter"]:
        x, y = d["x_mm"] * MM, d["y_mm"] * MM
        if symmetry in ("half", "quarter") and y < 0:
            continue
        if symmetry == "quarter" and x < 0:
            continue
        out.append(
            Indenter(
                x=x,
                y=y,
                radius=d["diameter_mm"] * 0.5 * MM,
                normal_force=tuple(d["load_N"]) if d["load_N"] is not None else None,
                depth=tuple(v * MM for v in d["depth_mm"]) if d["depth_mm"] is not None else None,
                shear_force=tuple(tuple(p) for p in d["shear_N"]) if d["shear_N"] else None,
            )
        )
    return tuple(out)


def _materials(cfg: dict) -> dict[int, Material]:
    """Region -> material: 0 the sheet, 1 the polycarbonate (absent on a rigid base)."""
    sh, sub = cfg["sheet"], cfg["substrate"]
    if sh["model"] == "neo-hookean":
        sheet = {"model": "neo-hookean", "E": sh["E_MPa"] * 1e6, "nu": sh["nu"]}
    else:
        sheet = {
            "model": "mooney-rivlin",
            "c10": sh["C10_MPa"] * 1e6,
            "c01": sh["C01_MPa"] * 1e6,
            "K": sh["K_MPa"] * 1e6,
        }
    materials = {0: material_from_dict(sheet)}
    if sub["thickness_mm"] > 0:
        materials[1] = material_from_dict(
            {"model": "neo-hookean", "E": sub["E_MPa"] * 1e6, "nu": sub["nu"]}
        )
    return materials


@dataclass(frozen=True)
class OpticsSetup:
    """The optics of a config in SI: the sheet's law, the pixel grid, the camera, the
    polariscope element errors (rad) and, when the PC is in the light path, its law."""

    law: StressOpticLaw
    grid: PixelGrid
    camera: Camera
    errors: dict
    substrate_law: StressOpticLaw | None = None


def optics_setup(cfg: dict) -> OpticsSetup:
    """The optics of an effective config in SI; an unknown camera name fails here."""
    o = cfg["optics"]
    law = StressOpticLaw(
        f_sigma=o["f_sigma_N_per_m"],
        wavelength_ref=o["wavelength_nm"] * 1e-9,
        dispersion=o["dispersion"],
        coefficient=o["dispersion_coefficient"],
    )
    grid = PixelGrid.from_field_of_view(
        o["field_of_view_mm"] * 1e-3,
        (o["pixels"], o["pixels"]),
        center=tuple(v * 1e-3 for v in o["center_mm"]),
    )
    camera = Camera(
        sensitivities=o["camera"],
        exposure=o["exposure"],
        full_well=o["full_well_e"],
        read_noise=o["read_noise_e"],
        bit_depth=o["bit_depth"],
    )
    camera.responses(np.array([550e-9]))  # an unknown camera name fails here, before solving
    err = {
        "qwp_error": math.radians(o["qwp_error_deg"]),
        "qwp_in": math.radians(o["qwp_in_error_deg"]),
        "qwp_out": math.radians(o["qwp_out_error_deg"]),
        "analyser": math.radians(o["analyser_error_deg"]),
    }
    err = {k: v for k, v in err.items() if v != 0.0}
    pc_law = None
    if o["include_substrate"]:
        if cfg["substrate"]["thickness_mm"] == 0:
            raise ConfigError(
                "optics.include_substrate = true needs a substrate (substrate.thickness_mm > 0)"
            )
        pc_law = StressOpticLaw(
            f_sigma=o["substrate_f_sigma_N_per_m"], wavelength_ref=o["wavelength_nm"] * 1e-9
        )
    return OpticsSetup(law, grid, camera, err, pc_law)


@dataclass(frozen=True)
class RunInputs:
    """Everything the stages need for one config, in SI units.

    Attributes
    ----------
    spec : meshes.MeshSpec
    indenters : tuple of fea.Indenter
        Those in the modelled part.
    materials : dict region -> fea.Material
    contact : fea.ContactSettings
    settings : fea.SolverSettings
    optics : OpticsSetup
    """

    spec: MeshSpec
    indenters: tuple
    materials: dict
    contact: ContactSettings
    settings: SolverSettings
    optics: OpticsSetup


def build_inputs(cfg: dict) -> RunInputs:
    """Mesh spec, solver inputs and optics settings in SI units from an effective config.

    Raises
    ------
    ConfigError
        A geometry or optics value the stages reject, or a mesh or ray samples larger
        than the memory free, named by its config keys.
    """
    spec = mesh_spec(cfg)
    check_ray_memory(cfg, spec.symmetry)
    c, s = cfg["contact"], cfg["solver"]
    contact = ContactSettings(
        friction=math.inf if c["friction"] == "stick" else c["friction"],
        penalty_factor=c["penalty_factor"],
        penetration_tol=c["penetration_tol"],
    )
    settings = SolverSettings(
        force_tol=s["force_tol"],
        max_iterations=s["max_iterations"],
        max_cutbacks=s["max_cutbacks"],
        backend=s["backend"],
        precision=s["precision"],
    )
    return RunInputs(
        spec=spec,
        indenters=_indenters(cfg, spec.symmetry),
        materials=_materials(cfg),
        contact=contact,
        settings=settings,
        optics=optics_setup(cfg),
    )
