"""``fringekit predict``: config -> mesh -> contact solution -> optics -> an output folder.

Output folder layout (``<out>/<case>/``):

- ``summary.json`` - ``max_fringe_order``, ``indenters`` (final state, one
  ``{"force_N": [x, y, z], "depth_mm", "contact_radius_mm", ...}`` per indenter),
  ``states`` (every load state), run times, versions and the effective config;
- ``config.toml`` - the effective config (re-runnable as is);
- ``state_XX/`` for each rendered load state: ``solution.vtu`` (deformed quadratic tets,
  stresses in Pa), ``maps.npz`` (fringe order, simple order, isoclinic, mask, pixel x/y in
  m), ``fringe_order.png`` and ``isoclinic.png`` (figures with a colour bar),
  ``six_step/step1..6.png`` (monochrome, DESIGN.md six-step table), ``white_light.png``
  (dark-field circular, the light and camera of the config), ``fringe_image.png`` (the
  white-light image with axes in mm) and ``profile.png`` / ``profile.csv`` (fringe order
  along x through the first indenter).

Meshes and solutions are cached (:func:`meshes.build_mesh`, :func:`fea.store.solve_cached`),
so a second run with other optics settings only re-renders.
"""

from __future__ import annotations

import json
import logging
import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from .config import ConfigError, normal_path, to_toml

__all__ = [
    "PredictError",
    "choose_symmetry",
    "build_inputs",
    "solve_config",
    "fringe_order_map",
    "run_predict",
]

log = logging.getLogger("fringekit.predict")


class PredictError(RuntimeError):
    """The pipeline could not finish; converged states were written before raising."""


def _pkg_version(name: str, missing: str = "unknown") -> str:
    """Installed version of a distribution, ``missing`` when it is not installed."""
    try:
        return version(name)
    except PackageNotFoundError:  # e.g. fringekit run from a source tree
        return missing


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


def build_inputs(cfg: dict):
    """Mesh spec, solver inputs and optics settings in SI units from an effective config.

    Returns
    -------
    spec : meshes.MeshSpec
    indenters : list of fea.Indenter (those in the modelled part)
    materials : dict region -> fea.Material
    contact : fea.ContactSettings
    settings : fea.SolverSettings
    """
    from fea import ContactSettings, Indenter, SolverSettings, material_from_dict
    from meshes import IndenterSite, Layers, MeshSpec, Sizing

    mm = 1e-3
    sh, sub, m = cfg["sheet"], cfg["substrate"], cfg["mesh"]
    symmetry = choose_symmetry(cfg)
    try:
        spec = MeshSpec(
            layers=Layers(
                sheet_thickness=sh["thickness_mm"] * mm,
                substrate_thickness=sub["thickness_mm"] * mm,
                width=sh["width_mm"] * mm,
                length=sh["length_mm"] * mm,
            ),
            indenters=tuple(
                IndenterSite(d["x_mm"] * mm, d["y_mm"] * mm, d["diameter_mm"] * 0.5 * mm)
                for d in cfg["indenter"]
            ),
            sizing=Sizing(
                h_contact=m["h_contact_mm"] * mm,
                refine_radius=m["refine_radius_mm"] * mm,
                h_far=m["h_far_mm"] * mm,
                h_sheet=m["h_sheet_mm"] * mm,
                growth=m["growth"],
            ),
            symmetry=symmetry,
        )
    except ValueError as exc:  # geometry errors speak SI; say which config part it is
        raise ConfigError(f"geometry: {exc}") from None
    indenters = []
    for d in cfg["indenter"]:
        x, y = d["x_mm"] * mm, d["y_mm"] * mm
        if symmetry in ("half", "quarter") and y < 0:
            continue
        if symmetry == "quarter" and x < 0:
            continue
        indenters.append(
            Indenter(
                x=x,
                y=y,
                radius=d["diameter_mm"] * 0.5 * mm,
                normal_force=tuple(d["load_N"]) if d["load_N"] is not None else None,
                depth=tuple(v * mm for v in d["depth_mm"]) if d["depth_mm"] is not None else None,
                shear_force=tuple(tuple(p) for p in d["shear_N"]) if d["shear_N"] else None,
            )
        )
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
    c = cfg["contact"]
    contact = ContactSettings(
        friction=math.inf if c["friction"] == "stick" else c["friction"],
        penalty_factor=c["penalty_factor"],
    )
    s = cfg["solver"]
    settings = SolverSettings(
        force_tol=s["force_tol"],
        max_iterations=s["max_iterations"],
        max_cutbacks=s["max_cutbacks"],
        backend=s["backend"],
    )
    return spec, indenters, materials, contact, settings


@dataclass(frozen=True)
class OpticsSetup:
    """The optics of a config in SI: the sheet's law, the pixel grid, the camera, the
    polariscope element errors (rad) and, when the PC is in the light path, its law."""

    law: object
    grid: object
    camera: object
    errors: dict
    substrate_law: object | None = None


def _optics_setup(cfg: dict) -> OpticsSetup:
    from optics import Camera, PixelGrid, StressOpticLaw

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


def _integrate(
    sol, cfg: dict, optics: OpticsSetup, wavelengths, *, progress: bool = False, samples=None
):
    """Sample (once) and integrate the sheet, and the PC first when configured.

    Returns (q (P, W, 4), simple (P,), valid (P,), samples) with ``samples`` reusable
    for other wavelengths.
    """
    from optics import FEMStressField, integrate_layers, sample_rays

    o = cfg["optics"]
    pc = optics.substrate_law is not None
    if samples is None:
        step = o["lateral_step_mm"] * 1e-3 or None
        kw = {"lateral_step": step, "progress": progress}
        samples = [sample_rays(FEMStressField(sol), optics.grid, o["samples_per_ray"], **kw)]
        if pc:
            field = FEMStressField(sol, region="substrate")
            n_pc = o["substrate_samples_per_ray"]
            samples.insert(0, sample_rays(field, optics.grid, n_pc, **kw))
    laws = [optics.substrate_law, optics.law] if pc else [optics.law]
    q, simple, valid = integrate_layers(samples, laws, wavelengths)
    return q, simple, valid, samples


def _mono_map(sol, cfg: dict, optics: OpticsSetup, *, progress: bool = False):
    """(OpticalMap at the reference wavelength, the ray samples for reuse)."""
    from optics.opticalmap import OpticalMap

    law, grid = optics.law, optics.grid
    q, simple, valid, samples = _integrate(
        sol, cfg, optics, [law.wavelength_ref], progress=progress
    )
    rows, cols = grid.shape
    omap = OpticalMap(
        grid=grid,
        wavelengths=np.array([law.wavelength_ref]),
        q=q.reshape(rows, cols, 1, 4),
        simple_order=np.where(valid, simple, np.nan).reshape(rows, cols),
        mask=valid.reshape(rows, cols),
        reflection=True,
        law=law,
    )
    return omap, samples


def _centres_rc(sol, grid) -> np.ndarray:
    """(m, 2) each indenter's current axis in pixels (row, col)."""
    return np.array([grid.xy_to_pixel(i.centre[0], i.centre[1]) for i in sol.indenters], float)


def fringe_order_map(sol, cfg: dict, optics: OpticsSetup | None = None):
    """Monochrome fringe-order map of one solution on the config's pixel grid.

    Returns
    -------
    order : (rows, cols) total fringe order at ``optics.wavelength_nm``, NaN outside the
        sheet and in contact zones
    grid : optics.PixelGrid
    centres_rc : (m, 2) each indenter's current axis in pixels (row, col)
    """
    optics = optics or _optics_setup(cfg)
    omap, _ = _mono_map(sol, cfg, optics)
    return omap.fringe_order(), optics.grid, _centres_rc(sol, optics.grid)


def solve_config(cfg: dict, *, cache_dir=None, use_cache: bool = True, progress: bool = True):
    """Mesh and solve a config through the caches: (mesh, solutions, stats, failure text)."""
    from fea import SolverError
    from fea.store import solve_cached
    from meshes import build_mesh

    spec, indenters, materials, contact, settings = build_inputs(cfg)
    mesh = build_mesh(spec, cache_dir=cache_dir, use_cache=use_cache)
    try:
        sols, stats, _ = solve_cached(
            mesh, indenters, materials=materials, contact=contact, settings=settings,
            cache_dir=cache_dir, use_cache=use_cache, progress=progress,
        )  # fmt: skip
        return mesh, sols, stats, None
    except SolverError as exc:
        return mesh, exc.solutions, None, str(exc)


def _write_map_figure(path, data, grid, title, label, cmap) -> None:
    """:func:`analysis.analyze.map_figure` on the sheet's x, y (mm) of ``grid``."""
    from .analyze import map_figure

    x0, y0 = grid.pixel_to_xy(np.array([0, grid.shape[0] - 1]), np.array([0, grid.shape[1] - 1]))
    extent = (x0[0] * 1e3, x0[1] * 1e3, y0[1] * 1e3, y0[0] * 1e3)
    map_figure(path, data, title, label, cmap, extent=extent, axis_labels=("x (mm)", "y (mm)"))


def _render_state(
    sol, k: int, cfg: dict, out: Path, optics, progress, show_bars: bool = False
) -> dict:
    """Write the VTU, maps, images and figures of one load state; return its figures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fea import write_solution_vtu
    from optics import (
        dark_field_circular,
        light_source,
        monochrome_image,
        six_step_arrangements,
        white_light_image,
        write_image,
    )

    from .compare import line_profile

    law, grid, camera, err = optics.law, optics.grid, optics.camera, optics.errors
    o = cfg["optics"]
    d = out / f"state_{k + 1:02d}"
    (d / "six_step").mkdir(parents=True, exist_ok=True)
    times = {}
    t0 = time.perf_counter()
    write_solution_vtu(sol, d / "solution.vtu")
    times["vtu_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    omap, samples = _mono_map(sol, cfg, optics, progress=show_bars)
    if not omap.mask.any():
        raise ConfigError(
            f"optics: the field of view (centre {o['center_mm']} mm, width "
            f"{o['field_of_view_mm']} mm) has no pixel over the sheet outside the contact zone"
        )
    times["locate_integrate_s"] = time.perf_counter() - t0
    progress("optics: rays located and integrated")

    t0 = time.perf_counter()
    rows, cols = grid.shape
    order = omap.fringe_order()
    theta = omap.principal_angle()
    xy = grid.xy().reshape(rows, cols, 2)
    np.savez_compressed(
        d / "maps.npz",
        fringe_order=order,
        simple_order=omap.simple_order,
        isoclinic_rad=theta,
        mask=omap.mask,
        x_m=xy[..., 0],
        y_m=xy[..., 1],
        pixel_size_m=grid.pixel_size,
        indenter_rc=_centres_rc(sol, grid),
        wavelength_m=law.wavelength_ref,
    )
    times["maps_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    arrs = six_step_arrangements(**err)
    q_img = omap.q[:, :, 0]
    for a in arrs:
        img = monochrome_image(q_img, a, camera, seed=o["seed"])
        write_image(d / "six_step" / f"{a.name}.png", img)
    times["six_step_s"] = time.perf_counter() - t0
    progress("optics: six phase-stepped images")

    t0 = time.perf_counter()
    lam = law.wavenumber_grid(o["white_light_wavelengths"])
    qw, _, _, _ = _integrate(sol, cfg, optics, lam, samples=samples)
    spec = light_source(o["light"], lam)
    rgb = white_light_image(
        qw.reshape(rows, cols, len(lam), 4), spec, camera, dark_field_circular(**err),
        seed=o["seed"],
    )  # fmt: skip
    rgb_path = d / ("white_light.png" if camera.bit_depth == 8 else "white_light.tif")
    write_image(rgb_path, rgb)
    times["white_light_s"] = time.perf_counter() - t0
    progress("optics: white-light image")

    t0 = time.perf_counter()
    _write_map_figure(
        d / "fringe_order.png", order, grid, f"fringe order at {o['wavelength_nm']:g} nm",
        "fringe order", "turbo",
    )  # fmt: skip
    _write_map_figure(
        d / "isoclinic.png", np.degrees(theta), grid, "isoclinic", "angle (deg)", "twilight"
    )
    shown = rgb if rgb.dtype == np.uint8 else (rgb / 257).astype(np.uint8)
    _write_map_figure(
        d / "fringe_image.png", shown, grid,
        f"white light ({o['light']}), dark-field circular", "", None,
    )  # fmt: skip
    # fringe order along x through the first indenter (the seed paper's a-b line)
    ind = sol.indenters[0]
    r, _ = grid.xy_to_pixel(ind.centre[0], ind.centre[1])
    row = int(np.clip(np.round(r), 0, rows - 1))
    prof = line_profile(order, (row, 0.0), (row, cols - 1.0), n=cols)
    x_prof = grid.pixel_to_xy(np.full(cols, row), np.arange(cols))[0]
    np.savetxt(
        d / "profile.csv",
        np.column_stack([x_prof * 1e3, prof.values]),
        delimiter=",",
        header="x_mm,fringe_order",
        comments="",
    )
    fig, ax = plt.subplots(figsize=(6, 3.4), dpi=120)
    ax.plot(x_prof * 1e3, prof.values, "-", lw=1.5)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("fringe order")
    ax.set_title(f"fringe order along y = {ind.centre[1] * 1e3:.2f} mm (contact zone masked)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(d / "profile.png")
    plt.close(fig)
    times["figures_s"] = time.perf_counter() - t0
    valid = np.isfinite(order)
    return {
        "state": k + 1,
        "folder": d.name,
        "max_fringe_order": float(np.nanmax(order)) if valid.any() else None,
        "max_simple_order": float(np.nanmax(omap.simple_order)) if valid.any() else None,
        "valid_pixel_fraction": float(valid.mean()),
        "times_s": times,
    }


def run_predict(
    cfg: dict,
    out: str | os.PathLike,
    *,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    progress: bool = True,
    echo: Callable[[str], None] = print,
) -> dict:
    """Run the whole prediction for an effective config; return the summary dict.

    Parameters
    ----------
    cfg : dict
        From :func:`analysis.config.load_config` / :func:`effective_config`.
    out : path
        Output folder of this case (created).
    cache_dir : path, optional
        Mesh and solution cache root (default: ``$FRINGEKIT_CACHE_DIR`` or the user cache).
    use_cache : bool
        False re-meshes and re-solves and writes no cache.
    progress : bool
        Progress bar over load states and one line per stage.
    echo : callable
        Where stage lines go.

    Raises
    ------
    ConfigError
        Bad inputs (before anything expensive runs where possible).
    PredictError
        The solver failed; the states it reached are in ``out`` (``summary.json`` says so).
    """
    from fea import SolverError
    from fea.store import solve_cached
    from meshes import build_mesh, quality_report

    say = echo if progress else (lambda s: None)
    out = Path(out)
    t_all = time.perf_counter()
    spec, indenters, materials, contact, settings = build_inputs(cfg)
    optics = _optics_setup(cfg)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.toml").write_text(to_toml(cfg))
    times: dict[str, float] = {}

    say(f"mesh: {spec.symmetry} model")
    t0 = time.perf_counter()
    mesh = build_mesh(spec, cache_dir=cache_dir, use_cache=use_cache)
    times["mesh_s"] = time.perf_counter() - t0
    rep = quality_report(mesh.points, mesh.cells, mesh.regions)
    say(f"mesh: {rep}")

    t0 = time.perf_counter()
    failure = None
    stats = None
    try:
        sols, stats, cache_file = solve_cached(
            mesh, indenters, materials=materials, contact=contact, settings=settings,
            cache_dir=cache_dir, use_cache=use_cache, progress=progress,
        )  # fmt: skip
    except SolverError as exc:
        sols, failure, cache_file = exc.solutions, str(exc), None
    times["solve_s"] = time.perf_counter() - t0
    say(
        f"solve: {len(sols)} load state(s) in {times['solve_s']:.1f} s"
        + (" (from cache)" if stats is None and failure is None else "")
    )

    render = (
        range(len(sols))
        if cfg["optics"]["render"] == "all"
        else range(max(len(sols) - 1, 0), len(sols))  # nothing when no state converged
    )
    rendered = []
    for k in render:
        say(f"optics: state {k + 1} of {len(sols)}")
        rendered.append(_render_state(sols[k], k, cfg, out, optics, say, progress))

    final = sols[-1] if sols else None
    summary = {
        "case": cfg["case"],
        "status": "failed" if failure else "ok",
        "error": failure,
        "max_fringe_order": rendered[-1]["max_fringe_order"] if rendered else None,
        "indenters": [i.as_dict() for i in final.indenters] if final else [],
        "states": [
            {
                "state": k + 1,
                "load_factor": s.load_factor,
                "indenters": [i.as_dict() for i in s.indenters],
            }
            for k, s in enumerate(sols)
        ],
        "rendered": rendered,
        "model": {
            "symmetry": spec.symmetry,
            "points": int(mesh.n_points),
            "cells": int(len(mesh.cells)),
            "dofs": int(stats.dofs) if stats else 3 * int(mesh.n_points),
            "mesh_quality": rep.as_dict(),
            "solution_from_cache": stats is None and failure is None,
            "solution_cache": str(cache_file) if cache_file else None,
            "newton_iterations": list(stats.iterations_per_state) if stats else None,
            "linear_solver": stats.backend if stats else None,
        },
        "times_s": {**times, "total_s": time.perf_counter() - t_all},
        "versions": {
            "fringekit": _pkg_version("fringekit"),
            "python": platform.python_version(),
            **{
                p: _pkg_version(p)
                for p in ("numpy", "scipy", "pytetwild", "pyvista", "colour-science")
            },
        },
        "config": cfg,
    }
    tmp = out / "summary.json.part"
    tmp.write_text(json.dumps(summary, indent=2))
    os.replace(tmp, out / "summary.json")
    if failure:
        raise PredictError(f"{failure}; the {len(sols)} converged state(s) are written to {out}")
    return summary
