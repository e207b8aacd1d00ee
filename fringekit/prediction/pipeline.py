"""``fringekit predict``: config -> mesh -> contact solution -> optics -> an output folder.

Output folder layout (``<out>/<case>/``):

- ``summary.json`` - ``max_fringe_order``, ``indenters`` (final state, one
  ``{"force_N": [x, y, z], "depth_mm", "contact_radius_mm", ...}`` per indenter),
  ``states`` (every load state), run times, versions and the effective config;
- ``config.toml`` - the effective config (re-runnable as is);
- ``state_XX/`` for each rendered load state (:func:`fringekit.prediction.render.render_state`):
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
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from fringekit.config.files import to_toml
from fringekit.config.inputs import OpticsSetup, build_inputs
from fringekit.config.model import Config, as_config
from fringekit.errors import ComputeError, Interrupted
from fringekit.fea import SolveInterrupted, SolverError, write_solution_vtu
from fringekit.fea.estimate import estimate_solve
from fringekit.fea.store import cache_entry, solve_cached
from fringekit.meshes import build_mesh, quality_report
from fringekit.output.folders import atomic_write, claim_output
from fringekit.output.numbers import significant
from fringekit.output.versions import run_versions
from fringekit.prediction.render import render_state, write_state

__all__ = [
    "Prediction",
    "PredictError",
    "PredictInterrupted",
    "predict",
    "run_predict",
    "solve_config",
    "used_config",
]

log = logging.getLogger("fringekit.predict")


class PredictError(ComputeError):
    """The solver could not reach a load; ``prediction`` holds the converged states.

    Examples
    --------
    >>> import fringekit
    >>> cfg = fringekit.Config.builtin("small").replace(
    ...     {"solver.max_iterations": 2, "solver.max_cutbacks": 0})
    >>> try:
    ...     fringekit.predict(cfg)
    ... except fringekit.PredictError as exc:
    ...     print(exc.prediction.status, len(exc.prediction.solutions))
    failed 0
    """

    def __init__(self, message: str, prediction: Prediction | None = None):
        super().__init__(message)
        self.prediction = prediction


class PredictInterrupted(PredictError, Interrupted):
    """The user stopped the solve (Ctrl-C); ``prediction`` holds the converged states."""


def _solve(inp, mesh, *, cache_dir, use_cache: bool, progress: bool):
    """Solve through the solution cache: (solutions, stats, cache file, failure text,
    interrupted); a failed solve keeps the states it reached (stats and file None)."""
    try:
        sols, stats, cache_file = solve_cached(
            mesh,
            inp.indenters,
            materials=inp.materials,
            contact=inp.contact,
            settings=inp.settings,
            cache_dir=cache_dir,
            use_cache=use_cache,
            progress=progress,
        )
        return sols, stats, cache_file, None, False
    except SolverError as exc:
        return exc.solutions, None, None, str(exc), isinstance(exc, SolveInterrupted)


def solve_config(cfg: dict, *, cache_dir=None, use_cache: bool = True, progress: bool = True):
    """Mesh and solve a config through the caches: (mesh, solutions, stats, failure text)."""
    inp = build_inputs(cfg)
    mesh = build_mesh(inp.spec, cache_dir=cache_dir, use_cache=use_cache)
    sols, stats, _, failure, _ = _solve(
        inp, mesh, cache_dir=cache_dir, use_cache=use_cache, progress=progress
    )
    return mesh, sols, stats, failure


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


def estimate_text(mesh, inp, *, cache_dir=None, use_cache: bool = True) -> str:
    """One line before solving: model size and the expected increments and time
    (:func:`fringekit.fea.estimate.estimate_solve`), or that the states are cached."""
    if use_cache:
        entry = cache_entry(
            mesh,
            inp.indenters,
            materials=inp.materials,
            contact=inp.contact,
            settings=inp.settings,
            cache_dir=cache_dir,
        )
        if entry.exists():
            return f"{mesh.n_dofs:,} DOF; the states are in the solution cache ({entry.name})"
    est = estimate_solve(
        mesh.n_dofs,
        inp.indenters,
        E=inp.materials[0].E,
        h=mesh.spec.layers.sheet_thickness,
        contact=inp.contact,
    )
    return f"{mesh.n_cells:,} cells, {est.text()}"


@dataclass(frozen=True)
class Prediction:
    """What a config predicts: the contact solution of every load state and the optics
    of the rendered ones, in memory. :meth:`write` puts it into a folder.

    Attributes
    ----------
    config : Config
        The checked config it was computed from.
    mesh : fringekit.meshes.Mesh
        The model's mesh (a half or quarter model where symmetry allows).
    solutions : tuple of fringekit.fea.Solution
        Every converged load state, in order.
    states : tuple of RenderedState
        The rendered load states (``optics.render``: the last, or all): fringe order,
        isoclinic, mask, the six phase-stepped, dark-field and white-light images.
    summary : dict
        What ``summary.json`` holds: status, maximum fringe order, each indenter's force
        (N), depth and contact radius (mm) per state, the model, times and versions.

    Examples
    --------
    >>> import tempfile, fringekit
    >>> pred = fringekit.predict("small")
    >>> pred.status, pred.states[-1].fringe_order.shape
    ('ok', (64, 64))
    >>> folder = pred.write(tempfile.mkdtemp())
    >>> sorted(p.name for p in (folder / "state_01").iterdir())[:4]
    ['dark_field.png', 'fringe_image.png', 'fringe_order.png', 'isoclinic.png']
    """

    config: Config
    mesh: object
    solutions: tuple
    states: tuple
    summary: dict
    optics: OpticsSetup = field(repr=False)

    @property
    def status(self) -> str:
        """``"ok"``, or ``"failed"`` / ``"interrupted"`` for the converged part of a run."""
        return self.summary["status"]

    def write(self, folder: str | os.PathLike) -> Path:
        """Write ``config.toml``, ``summary.json`` and one ``state_XX/`` per rendered state
        (VTU, maps, images, figures) into ``folder``, created if missing; return it.

        Files of the same names are replaced; other files in ``folder`` are left alone (the
        ``fringekit`` command writes into a fresh folder and swaps it in).
        """
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        atomic_write(out / "config.toml", to_toml(self.config.data))
        rendered = {rs.state for rs in self.states}
        for k, sol in enumerate(self.solutions):  # states not rendered still get their VTU
            if k + 1 not in rendered and self.status == "interrupted":
                (out / f"state_{k + 1:02d}").mkdir(exist_ok=True)
                write_solution_vtu(sol, out / f"state_{k + 1:02d}" / "solution.vtu")
        for rs in self.states:
            write_state(out, rs, self.config.data, self.optics)
        summary = copy.deepcopy(self.summary)
        summary["times_s"]["write_s"] = time.perf_counter() - t0
        text = json.dumps(significant(summary), indent=2, allow_nan=False)
        atomic_write(out / "summary.json", text)
        return out


def predict(
    config: Config | dict | str | os.PathLike | None = None,
    *,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    progress: bool = False,
    echo: Callable[[str], None] = print,
) -> Prediction:
    """Mesh, solve and render a config: the fringes a load makes.

    Parameters
    ----------
    config : Config, dict, path or str, optional
        A :class:`~fringekit.Config`, a dict shaped like the TOML file, a TOML file, or a
        built-in case name; default the reference case.
    cache_dir : path, optional
        Mesh and solution cache root (default ``$FRINGEKIT_CACHE_DIR`` or the user cache).
    use_cache : bool
        False re-meshes and re-solves and writes no cache.
    progress : bool
        A progress bar over load states and one line per stage through ``echo``.
    echo : callable
        Where the stage lines go.

    Returns
    -------
    Prediction
        Solutions, rendered maps and images, and the summary; nothing is written.

    Raises
    ------
    ConfigError
        A bad config, before anything is computed.
    PredictError
        The solver could not reach a load; ``exc.prediction`` holds the converged states
        (a :class:`PredictInterrupted` when the user pressed Ctrl-C).

    Examples
    --------
    The small built-in case (a 20 mm sheet, a coarse mesh, 64 x 64 pixels) in a few
    seconds; the reference case the same way takes about 20 s.

    >>> import fringekit
    >>> pred = fringekit.predict("small")
    >>> ind = pred.summary["indenters"][0]
    >>> round(ind["force_N"][2], 6), round(ind["depth_mm"], 2), round(ind["contact_radius_mm"], 2)
    (-8.0, 0.7, 1.14)
    >>> round(pred.summary["max_fringe_order"], 1)
    3.7
    """
    cfg = as_config(config)
    inp = build_inputs(cfg.data)
    say = echo if progress else (lambda s: None)
    t_all = time.perf_counter()
    say(f"mesh: {inp.spec.symmetry} model")
    t0 = time.perf_counter()
    mesh = build_mesh(inp.spec, cache_dir=cache_dir, use_cache=use_cache)
    times = {"mesh_s": time.perf_counter() - t0}
    rep = quality_report(mesh.points, mesh.cells, mesh.regions)
    say(f"mesh: {rep}")
    say(f"solve: {estimate_text(mesh, inp, cache_dir=cache_dir, use_cache=use_cache)}")
    t0 = time.perf_counter()
    sols, stats, cache_file, failure, interrupted = _solve(
        inp, mesh, cache_dir=cache_dir, use_cache=use_cache, progress=progress
    )
    times["solve_s"] = time.perf_counter() - t0
    cached = stats is None and failure is None
    say(f"solve: {len(sols)} load state(s) in {times['solve_s']:.1f} s" + " (from cache)" * cached)
    states = _render_states(cfg, sols, inp.optics, say, progress, interrupted)
    final = sols[-1] if sols else None
    summary = {
        "case": cfg.case,
        "status": "interrupted" if interrupted else "failed" if failure else "ok",
        "error": failure,
        "max_fringe_order": states[-1].max_fringe_order if states else None,
        "indenters": [i.as_dict() for i in final.indenters] if final else [],
        "states": [
            {
                "state": k + 1,
                "load_factor": s.load_factor,
                "indenters": [i.as_dict() for i in s.indenters],
            }
            for k, s in enumerate(sols)
        ],
        "rendered": [rs.entry() for rs in states],
        "model": _model_summary(inp.spec, mesh, rep, stats, failure, cache_file),
        "times_s": {**times, "total_s": time.perf_counter() - t_all},
        "versions": run_versions(),
        "config": used_config(cfg.data),
    }
    pred = Prediction(cfg, mesh, tuple(sols), tuple(states), summary, inp.optics)
    if failure:
        error = PredictInterrupted if interrupted else PredictError
        raise error(failure, prediction=pred)
    return pred


def _render_states(cfg: Config, sols, optics, say, progress, interrupted) -> list:
    """The optics of the states ``optics.render`` asks for (none when interrupted: the
    user wants to stop)."""
    if interrupted or not sols:
        return []
    todo = range(len(sols)) if cfg["optics.render"] == "all" else [len(sols) - 1]
    states = []
    for k in todo:
        say(f"optics: state {k + 1} of {len(sols)}")
        states.append(render_state(sols[k], k, cfg.data, optics, say, progress))
    return states


def run_predict(
    cfg: dict | Config,
    out: str | os.PathLike,
    *,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    progress: bool = True,
    echo: Callable[[str], None] = print,
    inputs=(),
) -> dict:
    """``fringekit predict``: :func:`predict`, then write the folder ``out``; the summary.

    The run is written into a fresh folder beside ``out`` and swapped in when it ends, so
    ``out`` always holds exactly one run. A run that fails to converge keeps its converged
    states; when ``out`` already holds an earlier run, that run is kept and the failed
    one goes to ``<out>-failed`` (``<out>-interrupted`` after Ctrl-C during the solve). A
    run stopped by an error or an interrupt elsewhere leaves ``out`` as it was. ``out`` is
    claimed by :func:`fringekit.output.folders.claim_output`: a folder that holds anything
    but an earlier prediction, or holds ``inputs`` (the config file), is refused.

    Raises
    ------
    ConfigError
        Bad inputs, before anything expensive runs.
    PredictError, PredictInterrupted
        As :func:`predict`, after the converged states are written.
    """
    out = Path(out)
    cfg = as_config(cfg)
    build_inputs(cfg.data)  # a bad config fails before the output folder is touched
    claim = claim_output(out, command="predict", inputs=inputs)
    with claim as work:
        try:
            pred, error = (
                predict(
                    cfg, cache_dir=cache_dir, use_cache=use_cache, progress=progress, echo=echo
                ),
                None,
            )
        except PredictError as exc:
            pred, error = exc.prediction, exc
            claim.divert(pred.status)  # an earlier run in out is kept
        pred.write(work)
    dest = claim.dest
    if error is not None:
        raise type(error)(
            f"{pred.summary['error']}; the {len(pred.solutions)} converged state(s) are "
            f"written to {dest}"
            + (f" (the earlier run in {claim.out} is kept)" if dest != claim.out else ""),
            prediction=pred,
        ) from error
    return pred.summary
