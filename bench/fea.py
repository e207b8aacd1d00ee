"""Benchmark the contact solver on the reference cases.

Usage: python bench/fea.py [--quick] [--mesh default coarse fine]
       [--case vertical shear reference plate4] [--json FILE]

Meshes: default (0.3 mm under the indenter on 0.6 mm sheet layers, the config default),
coarse (0.6 mm, the default before 2026-11-27), fine (0.4 mm through the whole sheet).
--quick runs the reference and plate4 cases on the default mesh only. Before it
starts, the script lists the cases with their expected time (fringekit.fea.estimate_solve);
each case then prints the estimate against the time it took.

vertical:  one 3.5 mm indenter, load path 1..8 N, quarter model.
shear:     8 N vertical then 6.4 N shear along x with full stick, half model (the built-in
           shear case; 8 N, a ratio of 1.0, until 2026-11-27).
reference: 8 N in one load state, quarter model (what ``fringekit predict`` solves).
plate4:    the seed paper's loading plate, four 3.5 mm heads on a 16 mm square pitch at
           8 N each, quarter model (one head at (8, 8) mm).
Prints DOF, Newton iterations per state, time split, tangent assemblies and residual
evaluations per Newton iteration, factorizations, peak memory, depth and contact radius
per state, the 8 N depth against Hertz and Dimitriadis, and S(r) (centred cases).
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import time
from pathlib import Path

import numpy as np

from fringekit.fea import (
    SHEET_DEFAULT,
    ContactSettings,
    Indenter,
    dimitriadis_force,
    estimate_solve,
    hertz_force,
    solve,
)
from fringekit.meshes import IndenterSite, MeshSpec, Sizing, build_mesh

MESHES = {
    "default": Sizing(),
    "coarse": Sizing(h_contact=0.6e-3, refine_radius=2e-3, h_sheet=2e-3, h_far=8e-3),
    "fine": Sizing(
        h_contact=0.4e-3, refine_radius=2e-3, h_sheet=1.5e-3, h_far=6e-3, h_layer=0.4e-3
    ),
}
RADII_MM = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0)


def _invert(fun, F):
    lo, hi = 0.0, 1.5e-3
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fun(mid) < F else (lo, mid)
    return 0.5 * (lo + hi)


def through_thickness_S(sol, radii_mm, angle_deg=0.0):
    """S(r) = integral over the deformed sheet thickness of (s_rr - s_tt) dz (N/mm).

    Sampled along the ray at (r cos a, r sin a) for the polar angle a = ``angle_deg``
    (0..90 deg lies in every quarter model) by probing the nodal stress on the deformed
    quadratic mesh through pyvista. In the polar frame at angle a,
    s_rr - s_tt = (s_xx - s_yy) cos 2a + 2 s_xy sin 2a (Mohr's circle); for an
    axisymmetric load S does not depend on a, so its spread over a is discretisation error.
    """
    import pyvista as pv

    cells = sol.mesh.cells[sol.mesh.regions == 0]
    grid = pv.UnstructuredGrid(
        np.hstack([np.full((len(cells), 1), 10), cells]).ravel(),
        np.full(len(cells), pv.CellType.QUADRATIC_TETRA, dtype=np.uint8),
        sol.points,
    )
    grid.point_data["s"] = sol.stress_nodes.reshape(-1, 9)
    out = {}
    t = sol.mesh.spec.layers.sheet_thickness
    a = np.radians(angle_deg)
    c2, s2 = np.cos(2 * a), np.sin(2 * a)
    for r in radii_mm:
        z = np.linspace(0.0, t * 1.2, 241)
        # at least 1e-7 m off the symmetry planes, so that a probe falls inside a cell
        x, y = (max(r * 1e-3 * f(a), 1e-7) for f in (np.cos, np.sin))
        pts = np.column_stack([np.full_like(z, x), np.full_like(z, y), z])
        probe = pv.PolyData(pts).sample(grid)
        ok = np.asarray(probe.point_data["vtkValidPointMask"], dtype=bool)
        s = np.asarray(probe.point_data["s"]).reshape(-1, 3, 3)
        diff = (s[:, 0, 0] - s[:, 1, 1]) * c2 + 2 * s[:, 0, 1] * s2
        diff = np.where(ok, diff, 0.0)
        out[f"{r:.1f}"] = float(np.trapezoid(diff, z) * 1e-3)  # N/m * 1e-3 -> N/mm
    return out


PITCH = 16e-3  # the loading plate's heads: an (assumed) 16 mm square pitch


def _problem(case: str, mesh_name: str):
    """(mesh, indenters of the modelled part, contact settings) of a benchmark case."""
    sizing = MESHES[mesh_name]
    contact = ContactSettings()
    if case == "plate4":
        s = PITCH / 2
        sites = tuple(IndenterSite(x, y, 1.75e-3) for x in (-s, s) for y in (-s, s))
        mesh = build_mesh(MeshSpec(indenters=sites, sizing=sizing, symmetry="quarter"))
        return mesh, [Indenter(x=s, y=s, normal_force=(8.0,))], contact
    sym = "half" if case == "shear" else "quarter"
    mesh = build_mesh(MeshSpec(sizing=sizing, symmetry=sym))
    if case == "vertical":
        ind = Indenter(normal_force=tuple(float(f) for f in range(1, 9)))
    elif case == "reference":
        ind = Indenter(normal_force=(8.0,))
    else:
        ind = Indenter(normal_force=(8.0, 8.0), shear_force=((0.0, 0.0), (6.4, 0.0)))
        contact = ContactSettings(friction=math.inf)
    return mesh, [ind], contact


def _eight_newton(sol, centred: bool) -> dict:
    """The 8 N depth against the closed forms, and S(r) for a centred indenter."""
    E, R, h = SHEET_DEFAULT.E, 1.75e-3, 3e-3
    out = {
        "depth_8N_mm": sol.indenters[0].depth * 1e3,
        "depth_8N_hertz_mm": _invert(lambda d: hertz_force(d, R, E, SHEET_DEFAULT.nu), 8.0) * 1e3,
        "depth_8N_dimitriadis_mm": _invert(lambda d: dimitriadis_force(d, R, E, h), 8.0) * 1e3,
    }
    if centred:
        out["S_r_N_per_mm"] = through_thickness_S(sol, RADII_MM)
    return out


def _estimate(mesh, inds, contact):
    return estimate_solve(
        mesh.n_dofs, inds, E=SHEET_DEFAULT.E, h=mesh.spec.layers.sheet_thickness, contact=contact
    )


def run(case: str, mesh_name: str) -> dict:
    mesh, inds, contact = _problem(case, mesh_name)
    est = _estimate(mesh, inds, contact)
    t0 = time.perf_counter()
    sols, stats = solve(mesh, inds, contact=contact, progress=True)
    elapsed = time.perf_counter() - t0
    states = [
        {
            "force_N": [float(v) for v in s.indenters[0].force],
            "depth_mm": s.indenters[0].depth * 1e3,
            "contact_radius_mm": s.indenters[0].contact_radius * 1e3,
        }
        for s in sols
    ]
    res = {
        "name": case,
        "mesh": mesh_name,
        "dofs": stats.dofs,
        "time_s": elapsed,
        "time_assembly_s": stats.time_assembly,
        "time_contact_s": stats.time_contact,
        "time_analysis_s": stats.time_analysis,
        "time_factorize_s": stats.time_factorize,
        "time_solve_s": stats.time_solve,
        "newton_iterations": stats.iterations_per_state,
        "al_updates": stats.al_updates,
        "tangent_assemblies": stats.tangent_assemblies,
        "residual_evaluations": stats.residual_evaluations,
        "factorizations": stats.factorizations,
        "factor_reuses": stats.factor_reuses,
        "cutbacks": stats.cutbacks,
        "increments": stats.increments,
        "estimate_s": est.seconds,
        "estimate_increments": sum(est.increments),
        "estimate_newton_iterations": est.newton_iterations,
        "peak_mem_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "states": states,
    }
    res.update(_eight_newton(sols[0] if case == "shear" else sols[-1], case != "plate4"))
    _split(res, stats)
    _report(res, stats, elapsed)
    return res


def _split(res: dict, stats) -> None:
    """The time outside the factorization, over the run and per Newton iteration."""
    # the target is per Newton iteration: the one-off setup (gradients, sparsity pattern,
    # solver library load) is reported apart
    iters = stats.time_total - stats.time_setup
    outside = iters - stats.time_factorize
    res["time_setup_s"] = stats.time_setup
    res["outside_factorization_fraction_run"] = outside / max(iters, 1e-9)
    it = np.array(stats.iteration_times).reshape(-1, 2)
    frac = 1.0 - it[:, 1] / np.maximum(it[:, 0], 1e-12)
    res["outside_factorization_fraction_per_iteration"] = {
        "median": float(np.median(frac)),
        "max": float(frac.max()),
        "mean_weighted": float(1.0 - it[:, 1].sum() / it[:, 0].sum()),
    }


def _report(res: dict, stats, elapsed: float) -> None:
    n_it = max(sum(stats.iterations_per_state), 1)
    iters = stats.time_total - stats.time_setup
    outside = iters - stats.time_factorize
    print(
        f"{res['name']:9s} {res['mesh']:6s} DOF {stats.dofs:7d}  time {elapsed:6.1f} s  "
        f"(setup {stats.time_setup:.1f}, assembly {stats.time_assembly:.1f}, contact "
        f"{stats.time_contact:.1f}, analysis {stats.time_analysis:.1f}, factorize "
        f"{stats.time_factorize:.1f}, solve {stats.time_solve:.1f}); per Newton iteration "
        f"{iters / n_it:.2f} s, of which outside the factorization {outside / n_it:.2f} s = "
        f"{100 * outside / max(iters, 1e-9):.0f} % (with setup "
        f"{100 * (outside + stats.time_setup) / max(stats.time_total, 1e-9):.0f} %)"
    )
    pf = res["outside_factorization_fraction_per_iteration"]
    print(
        f"   inside each Newton iteration (tangent + linear solve + line search): "
        f"outside the factorization median {100 * pf['median']:.0f} %, max "
        f"{100 * pf['max']:.0f} %, time-weighted {100 * pf['mean_weighted']:.0f} %; the rest "
        "of the run is per load state (predictor, multiplier updates, stress recovery)"
    )
    print(f"   iterations per state {stats.iterations_per_state}, peak {res['peak_mem_mb']:.0f} MB")
    print(
        f"   estimate {res['estimate_s']:.0f} s against {elapsed:.0f} s taken (ratio "
        f"{elapsed / max(res['estimate_s'], 1e-9):.2f}); increments {res['estimate_increments']} "
        f"expected, {stats.increments} taken; Newton iterations "
        f"{res['estimate_newton_iterations']} expected, {n_it} taken"
    )
    print(
        f"   per Newton iteration: {stats.tangent_assemblies / n_it:.2f} tangent assemblies, "
        f"{stats.residual_evaluations / n_it:.2f} residual evaluations "
        f"({stats.tangent_assemblies} and {stats.residual_evaluations} over {n_it} "
        f"iterations); factorizations {stats.factorizations} (+ {stats.factor_reuses} "
        f"Newton steps solved on an earlier factor); cut-backs {stats.cutbacks}"
    )
    for s in res["states"]:
        print(
            f"   F = {s['force_N']} N  depth {s['depth_mm']:.4f} mm  "
            f"contact radius {s['contact_radius_mm']:.4f} mm"
        )
    print(
        f"   8 N depth {res['depth_8N_mm']:.4f} mm; Hertz {res['depth_8N_hertz_mm']:.4f}, "
        f"Dimitriadis {res['depth_8N_dimitriadis_mm']:.4f}; S(r) N/mm "
        f"{res.get('S_r_N_per_mm', '(not for the plate)')}"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--mesh", nargs="+", default=["default", "coarse", "fine"], choices=list(MESHES))
    cases = ["vertical", "shear", "reference", "plate4"]
    p.add_argument("--case", nargs="+", default=cases, choices=cases)
    p.add_argument("--json", type=Path)
    p.add_argument(
        "--quick", action="store_true", help="the reference and plate4 cases, default mesh only"
    )
    a = p.parse_args()
    if a.quick:
        a.case, a.mesh = ["reference", "plate4"], ["default"]
    plan = [(c, m) for c in a.case for m in a.mesh]
    total = 0.0
    print("will run:")
    for c, m in plan:
        mesh, inds, contact = _problem(c, m)
        est = _estimate(mesh, inds, contact)
        total += est.seconds
        print(f"   {c} on the {m} mesh: {est.text()}")
    print(f"about {total / 60:.1f} min in all (2 cores; meshing not included)", flush=True)
    cases = [run(c, m) for c, m in plan]
    if a.json:
        a.json.write_text(json.dumps({"cases": cases}, indent=2))


if __name__ == "__main__":
    main()
