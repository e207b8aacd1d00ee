"""``fringekit predict``: config -> mesh -> contact solution -> optics -> an output folder.

Output folder layout (``<out>/<case>/``):

- ``summary.json`` - ``max_fringe_order``, ``indenters`` (final state, one
  ``{"force_N": [x, y, z], "depth_mm", "contact_radius_mm", ...}`` per indenter),
  ``states`` (every load state), run times, versions and the effective config;
- ``config.toml`` - the effective config (re-runnable as is);
- ``state_XX/`` for each rendered load state (:func:`fringekit.render.render_state`):
  ``solution.vtu`` (deformed quadratic tets, stresses in Pa), ``maps.npz`` (fringe order,
  simple order, isoclinic, mask, pixel x/y in m), ``fringe_order.png`` and
  ``isoclinic.png`` (figures with a colour bar), ``six_step/step1..6.png`` (monochrome,
  the six-step table of ``docs/theory.md``), ``dark_field.png`` (monochrome, dark-field
  circular: the image of ``analyze --method mono``), ``white_light.png`` (dark-field circular, the
  light and camera of the config), ``fringe_image.png`` (the white-light image with axes
  in mm) and ``profile.png`` / ``profile.csv`` (fringe order along x through the first
  indenter).

Meshes and solutions are cached (:func:`meshes.build_mesh`, :func:`fea.store.solve_cached`),
so a second run with other optics settings only re-renders.
"""

from __future__ import annotations

import copy
import json
import logging
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path

from fringekit.config.files import to_toml
from fringekit.config.inputs import build_inputs
from fringekit.errors import ComputeError, Interrupted
from fringekit.fea import SolveInterrupted, SolverError, write_solution_vtu
from fringekit.fea.store import solve_cached
from fringekit.meshes import build_mesh, quality_report
from fringekit.output.folders import swap_in, work_folder
from fringekit.output.numbers import significant
from fringekit.output.versions import run_versions
from fringekit.predict.render import render_state

__all__ = ["PredictError", "PredictInterrupted", "solve_config", "run_predict", "used_config"]

log = logging.getLogger("fringekit.predict")


class PredictError(ComputeError):
    """The pipeline could not finish; converged states were written before raising."""


class PredictInterrupted(PredictError, Interrupted):
    """The user stopped the solve; the converged states and a summary were written."""


def solve_config(cfg: dict, *, cache_dir=None, use_cache: bool = True, progress: bool = True):
    """Mesh and solve a config through the caches: (mesh, solutions, stats, failure text)."""
    inp = build_inputs(cfg)
    mesh = build_mesh(inp.spec, cache_dir=cache_dir, use_cache=use_cache)
    try:
        sols, stats, _ = solve_cached(
            mesh, inp.indenters, materials=inp.materials, contact=inp.contact,
            settings=inp.settings, cache_dir=cache_dir, use_cache=use_cache, progress=progress,
        )  # fmt: skip
        return mesh, sols, stats, None
    except SolverError as exc:
        return mesh, exc.solutions, None, str(exc)


def _model_summary(spec, mesh, rep, stats, failure, cache_file) -> dict:
    quality = rep.as_dict()
    quality.pop("n_dofs")  # "dofs" below is the one DOF figure
    quality["min_volume_mm3"] = quality.pop("min_volume_m3") * 1e9
    return {
        "symmetry": spec.symmetry,
        "mesher": spec.mesher,
        "points": int(mesh.n_points),
        "cells": int(len(mesh.cells)),
        "dofs": int(mesh.n_dofs),  # 3 per node, the same whether solved or from the cache
        "mesh_quality": quality,
        "solution_from_cache": stats is None and failure is None,
        "solution_cache": str(cache_file) if cache_file else None,
        "newton_iterations": list(stats.iterations_per_state) if stats else None,
        "linear_solver": stats.backend if stats else None,
    }


def used_config(cfg: dict) -> dict:
    """The effective config without the keys the run did not use: the other hyperelastic
    model's constants, and the polycarbonate's optics when light does not cross it."""
    used = copy.deepcopy(cfg)
    sheet = used["sheet"]
    unused = ("C10_MPa", "C01_MPa", "K_MPa") if sheet["model"] == "neo-hookean" else ("nu",)
    for key in unused:
        sheet.pop(key, None)
    if not used["optics"]["include_substrate"]:
        for key in [k for k in used["optics"] if k.startswith("substrate_")]:
            used["optics"].pop(key)
    return used


#: Measured solver cost on 2 cores (bench/fea.py, 2026-11-23): seconds per Newton iteration
#: at 34.5k DOF, the exponent of its growth with DOF (34.5k: 0.58 s, 70k: 1.5 s, 144k:
#: 5-6 s), and Newton iterations for the first load state (reference 22, four-head plate
#: 23, six-head foot at 90k DOF 32 s) and each later one (4-5 on the 1..8 N path).
_S_PER_ITERATION, _DOF_REF, _GROWTH, _FIRST_ITS, _LATER_ITS = 0.58, 34.5e3, 1.5, 20, 5


def estimate_text(mesh, indenters) -> str:
    """One line before solving: model size and a rough time estimate from measured rates."""
    states = indenters[0].n_states
    its = _FIRST_ITS + _LATER_ITS * (states - 1)  # indenters share their increments
    t = its * _S_PER_ITERATION * (mesh.n_dofs / _DOF_REF) ** _GROWTH
    return (
        f"{mesh.n_dofs:,} DOF, {mesh.n_cells:,} cells, {states} load state(s); about "
        f"{max(t, 1):.0f} s to solve on 2 cores (rough: ~{its} Newton iterations at the "
        "measured rate; cached solutions take seconds)"
    )


def _write_summary(out: Path, summary: dict) -> None:
    tmp = out / "summary.json.part"
    tmp.write_text(json.dumps(significant(summary), indent=2, allow_nan=False))
    os.replace(tmp, out / "summary.json")


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
        From :func:`fringekit.config.load_config` / :func:`effective_config`.
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

    The run is written into a fresh folder beside ``out`` and swapped in when it ends, so
    ``out`` always holds exactly one run. A run that fails to converge keeps its converged
    states; when ``out`` already holds an earlier run, that run is kept and the failed
    one goes to ``<out>-failed``. A run stopped by an error or an interrupt leaves ``out``
    as it was.

    Raises
    ------
    ConfigError
        Bad inputs (before anything expensive runs where possible).
    PredictError
        The solver failed; the states it reached are written (``summary.json`` says so).
    PredictInterrupted
        Ctrl-C during the solve: the converged states' VTU files and a summary with status
        ``"interrupted"`` are written (to ``<out>-interrupted`` when ``out`` holds a run).
        Ctrl-C elsewhere leaves ``out`` as it was.
    """
    out = Path(out)
    inp = build_inputs(cfg)
    work = work_folder(out)
    try:
        summary = _run(cfg, inp, work, cache_dir, use_cache, progress, echo)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    failed = summary["status"] != "ok"
    dest = out.with_name(f"{out.name}-{summary['status']}") if failed and out.exists() else out
    swap_in(work, dest)
    if failed:
        raise (PredictInterrupted if summary["status"] == "interrupted" else PredictError)(
            f"{summary['error']}; the {len(summary['states'])} converged state(s) are written "
            f"to {dest}" + (f" (the earlier run in {out} is kept)" if dest != out else "")
        )
    return summary


def _run(cfg, inp, out: Path, cache_dir, use_cache, progress, echo) -> dict:
    """Mesh, solve and render into the empty folder ``out``; return the summary."""
    say = echo if progress else (lambda s: None)
    t_all = time.perf_counter()
    spec = inp.spec
    (out / "config.toml").write_text(to_toml(cfg))
    times: dict[str, float] = {}

    say(f"mesh: {spec.symmetry} model")
    t0 = time.perf_counter()
    mesh = build_mesh(spec, cache_dir=cache_dir, use_cache=use_cache)
    times["mesh_s"] = time.perf_counter() - t0
    rep = quality_report(mesh.points, mesh.cells, mesh.regions)
    say(f"mesh: {rep}")

    say(f"solve: {estimate_text(mesh, inp.indenters)}")
    t0 = time.perf_counter()
    failure = None
    stats = None
    interrupted = False
    try:
        sols, stats, cache_file = solve_cached(
            mesh, inp.indenters, materials=inp.materials, contact=inp.contact,
            settings=inp.settings, cache_dir=cache_dir, use_cache=use_cache, progress=progress,
        )  # fmt: skip
    except SolverError as exc:
        sols, failure, cache_file = exc.solutions, str(exc), None
        interrupted = isinstance(exc, SolveInterrupted)
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
    if interrupted:  # the user wants to stop: keep the states, render nothing
        render = range(0)
        for k, sol in enumerate(sols):
            (out / f"state_{k + 1:02d}").mkdir()
            write_solution_vtu(sol, out / f"state_{k + 1:02d}" / "solution.vtu")
    rendered = []
    for k in render:
        say(f"optics: state {k + 1} of {len(sols)}")
        rendered.append(render_state(sols[k], k, cfg, out, inp.optics, say, progress))

    final = sols[-1] if sols else None
    summary = {
        "case": cfg["case"],
        "status": "interrupted" if interrupted else "failed" if failure else "ok",
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
        "model": _model_summary(spec, mesh, rep, stats, failure, cache_file),
        "times_s": {**times, "total_s": time.perf_counter() - t_all},
        "versions": run_versions(),
        "config": used_config(cfg),
    }
    _write_summary(out, summary)
    return summary
