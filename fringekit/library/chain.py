"""One diameter's continuation for a library: its config and load tree
(:func:`chain_config`) and its solve on a worker (:func:`solve_chain`), which writes each
branch's sampled states to ``branches/<id>.npz`` as soon as the branch converges."""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from fringekit.config.inputs import build_inputs
from fringekit.fea import SolveInterrupted, SolverError, solve
from fringekit.library.lattice import PolarLattice, sample_lattice
from fringekit.meshes import build_mesh
from fringekit.optics import FEMStressField
from fringekit.output.folders import atomic_write

__all__ = ["branch_file", "chain_config", "save_npz", "solve_chain"]


def branch_file(out, branch_id: str) -> Path:
    """Where a library folder ``out`` keeps the solved branch ``branch_id``.

    Examples
    --------
    >>> branch_file("lib", "d3.5-f8").as_posix()
    'lib/branches/d3.5-f8.npz'
    """
    return Path(out) / "branches" / f"{branch_id}.npz"


def chain_config(cfg: dict, diameter_mm: float, loads, ratios, todo) -> tuple[dict, list, list]:
    """The config of one diameter's chain, its parents and what each state is.

    The normal loads ``loads`` in order, each from the one before; after each load whose
    ``todo`` is true, its tangential states ``ratio * load`` along +x (ratios[1:]), each
    from the one before. Loads above the last one to do are left out.

    Returns
    -------
    config : dict, one indenter at the origin, full stick, half model
    parents : list of int, the parent of each load state (fea.solve)
    states : list of (load index, ratio index), one per load state
    """
    last = max(i for i, t in enumerate(todo) if t)
    normal, shear, parents, states = [], [], [], []
    prev = 0
    for i in range(last + 1):
        for r, ratio in enumerate(ratios if todo[i] else ratios[:1]):
            normal.append(float(loads[i]))
            shear.append([float(ratio * loads[i]), 0.0])
            parents.append(prev if r == 0 else len(states))
            states.append((i, r))
        prev = len(states) - len(ratios) + 1 if todo[i] else len(states)
    b = copy.deepcopy(cfg)
    b["case"] = f"library-d{diameter_mm:g}"
    b["indenter"] = [
        {
            "x_mm": 0.0,
            "y_mm": 0.0,
            "diameter_mm": float(diameter_mm),
            "load_N": normal,
            "depth_mm": None,
            "shear_N": shear,
        }
    ]
    b["contact"]["friction"] = "stick"
    b["mesh"]["symmetry"] = "half"
    return b, parents, states


def solve_chain(task: dict, out: str, cache_dir: str | None, progress: bool = False) -> dict:
    """Solve one diameter's chain, writing ``branches/<id>.npz`` as each branch's last
    state converges (runs on a worker, or in this process with a progress bar)."""
    lat = PolarLattice(np.array(task["r"]), np.array(task["phi"]), task["n_slabs"])
    branches, ratios = task["branches"], task["ratios"]
    cfg, parents, states = chain_config(
        task["config"],
        task["diameter_mm"],
        [b["load_N"] for b in branches],
        ratios,
        [b["todo"] for b in branches],
    )
    inp = build_inputs(cfg)
    t0 = time.perf_counter()
    mesh = build_mesh(inp.spec, cache_dir=cache_dir)
    done, samples = [], []

    def keep(k: int, S: int, sol) -> None:
        if bar is not None:
            bar.update(1)
        i, r = states[k - 1]
        if not branches[i]["todo"]:
            return  # a normal load below a branch to do: only the way there
        samples.append(_sample(sol, FEMStressField(sol), lat))
        if r == len(ratios) - 1:
            b = branches[i]
            save_npz(
                branch_file(out, b["id"]),
                **{key: np.array([s[key] for s in samples]) for key in samples[0]},
                settings=json.dumps(b["settings"]),
            )
            done.append(b["id"])
            samples.clear()

    bar = _state_bar(len(states), progress)
    try:
        solve(
            mesh,
            inp.indenters,
            materials=inp.materials,
            contact=inp.contact,
            settings=inp.settings,
            parents=parents,
            progress=keep,
        )
        error = None
    except SolveInterrupted:
        raise KeyboardInterrupt from None  # the branches written so far are kept
    except SolverError as exc:
        error = str(exc)
    finally:
        if bar is not None:
            bar.close()
    return {"id": task["id"], "error": error, "done": done, "time_s": time.perf_counter() - t0}


def _state_bar(total: int, show: bool):
    if not show:
        return None
    return tqdm(total=total, desc="library load states", unit="state")


def _sample(sol, field, lat) -> dict:
    """One converged state on the lattice, with the indenter's contact radius (m),
    centre and depth (m) and load (N, Fz positive pressing)."""
    ab, v = sample_lattice(field, lat)
    ind = sol.indenters[0]
    return {
        "AB": ab,
        "valid": v,
        "contact_radius_m": ind.contact_radius,
        "centre_m": [ind.centre[0], ind.centre[1], ind.depth],
        "force_N": [ind.force[0], ind.force[1], -ind.force[2]],
    }


def save_npz(dest: Path, **arrays) -> None:
    """``np.savez`` to ``dest``: it appears whole or not at all."""
    atomic_write(dest, lambda part: np.savez(part, **arrays))
