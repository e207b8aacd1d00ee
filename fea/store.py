"""Solutions on disk: a load path's states in one ``.npz``, and a solve cache keyed by inputs.

Re-rendering optics with other polariscope, light or camera settings must not re-solve
(issue 6): :func:`solve_cached` hashes everything the states depend on (mesh spec, mesher
salt, materials, indenters, contact and Newton settings, this module's format version)
and stores the converged states next to the mesh cache. Each entry holds its whole key
and the inputs it was hashed from; an entry read under another key (a file copied or
renamed onto this key's name) is not used: it is logged with its path and solved again,
as a damaged entry is (a cache holds derived data the solver can always make again, so a
wrong entry is replaced rather than refused).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from fringekit.meshes import UNREADABLE, Mesh, default_cache_dir

from .materials import Material
from .problem import ContactSettings, Indenter, SolverSettings
from .solution import IndenterState, Solution
from .solver import SolveStats, solve

__all__ = [
    "KeyMismatch",
    "save_solutions",
    "load_solutions",
    "cache_entry",
    "solution_inputs",
    "solution_key",
    "solve_cached",
]

log = logging.getLogger("fringekit.fea")

#: Bump when the stored arrays or the solver's converged answer change meaning.
#: 2: every entry holds its key and the inputs it was hashed from.
#: 3: under friction a point sticks where it first touches (fea.contact.first_touch_anchors).
#: 4: the contact radius is the edge fitted to the open gap (fea.contact_edge), with its sd.
STORE_VERSION = 4

_IND_ARRAYS = ("centre", "force", "points", "pressure")
_IND_SCALARS = ("radius", "depth", "contact_radius", "max_penetration", "contact_radius_sd")


class KeyMismatch(ValueError):
    """A cache entry holds the states of other inputs than its key's."""


def save_solutions(
    path: str | os.PathLike, solutions: Sequence[Solution], *, key: str = "", inputs: str = ""
) -> Path:
    """Write the states of one load path to ``path`` (.npz, written atomically).

    The mesh is not stored; :func:`load_solutions` takes it back as an argument.
    ``key`` and ``inputs`` (:func:`solution_key` and the JSON it hashes) are stored with
    the states, so a reader can check the entry is the one it asked for.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {
        "n_states": np.array(len(solutions)),
        "key": np.array(key),
        "inputs": np.array(inputs),
    }
    for k, s in enumerate(solutions):
        p = f"s{k}_"
        arrays[p + "displacement"] = s.displacement
        arrays[p + "stress_qp"] = s.stress_qp
        arrays[p + "jbar"] = s.jbar
        arrays[p + "base_reaction"] = s.base_reaction
        arrays[p + "model_fraction"] = np.asarray(s.model_fraction, float)
        arrays[p + "load_factor"] = np.array(s.load_factor)
        arrays[p + "log"] = np.array(json.dumps(s.log, default=float))
        arrays[p + "n_ind"] = np.array(len(s.indenters))
        for j, ind in enumerate(s.indenters):
            for name in _IND_ARRAYS + _IND_SCALARS:
                arrays[f"{p}i{j}_{name}"] = np.asarray(getattr(ind, name))
    # a temporary file of this process alone, renamed over the target: two runs of one
    # case never write into each other's file, and a reader sees a whole file or none
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.stem + ".", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


def load_solutions(path: str | os.PathLike, mesh: Mesh, *, key: str = "") -> list[Solution]:
    """Read what :func:`save_solutions` wrote; ``mesh`` must be the mesh it was solved on.

    With ``key``, the entry must have been written under that key (else
    :class:`KeyMismatch`, a ValueError).
    """
    with np.load(path, allow_pickle=False) as z:
        if key and str(z["key"]) != key:
            stored = str(z["key"])[:16] or "none"
            raise KeyMismatch(
                f"it holds the states of other inputs (its key {stored}..., this solve's "
                f"{key[:16]}...)"
            )
        n = int(z["n_states"])
        out = []
        for k in range(n):
            p = f"s{k}_"
            if z[p + "displacement"].shape != mesh.points.shape:
                raise ValueError(
                    f"{path}: stored displacement has shape {z[p + 'displacement'].shape} but "
                    f"the mesh has {mesh.points.shape}; it was solved on another mesh"
                )
            inds = []
            for j in range(int(z[p + "n_ind"])):
                kw = {name: np.array(z[f"{p}i{j}_{name}"]) for name in _IND_ARRAYS}
                kw.update({name: float(z[f"{p}i{j}_{name}"]) for name in _IND_SCALARS})
                inds.append(IndenterState(**kw))
            out.append(
                Solution(
                    mesh=mesh,
                    displacement=np.array(z[p + "displacement"]),
                    stress_qp=np.array(z[p + "stress_qp"]),
                    jbar=np.array(z[p + "jbar"]),
                    indenters=tuple(inds),
                    base_reaction=np.array(z[p + "base_reaction"]),
                    model_fraction=tuple(float(v) for v in z[p + "model_fraction"]),
                    load_factor=float(z[p + "load_factor"]),
                    log=json.loads(str(z[p + "log"])),
                )
            )
    return out


def _material_dict(m: Material) -> dict:
    return {"type": type(m).__name__, **dataclasses.asdict(m)}


def solution_inputs(
    mesh: Mesh,
    indenters: Sequence[Indenter],
    materials: dict[int, Material],
    contact: ContactSettings,
    settings: SolverSettings,
) -> str:
    """Everything the converged states depend on, as canonical JSON (what
    :func:`solution_key` hashes)."""
    if mesh.spec is None:
        raise ValueError("solve_cached needs a mesh built from a MeshSpec (mesh.spec is None)")
    payload = {
        "store": STORE_VERSION,
        "mesh": mesh.spec.to_dict(),
        "mesh_points": mesh.n_points,
        "mesh_cells": len(mesh.cells),
        "mesh_sum": float(np.round(mesh.points.sum(), 12)),
        "materials": {str(k): _material_dict(v) for k, v in sorted(materials.items())},
        "indenters": [dataclasses.asdict(i) for i in indenters],
        "contact": dataclasses.asdict(contact),
        "settings": {
            k: v
            for k, v in dataclasses.asdict(settings).items()
            if k not in ("backend", "precision")
        },  # the backend and precision change round-off, not the answer
    }
    return json.dumps(payload, sort_keys=True, default=repr)


def solution_key(
    mesh: Mesh,
    indenters: Sequence[Indenter],
    materials: dict[int, Material],
    contact: ContactSettings,
    settings: SolverSettings,
) -> str:
    """SHA-256 over everything the converged states depend on."""
    text = solution_inputs(mesh, indenters, materials, contact, settings)
    return hashlib.sha256(text.encode()).hexdigest()


def cache_entry(
    mesh: Mesh,
    indenters: Sequence[Indenter],
    *,
    materials: dict[int, Material],
    contact: ContactSettings,
    settings: SolverSettings,
    cache_dir: str | os.PathLike | None = None,
) -> Path:
    """Where :func:`solve_cached` keeps (or would keep) the states of these inputs.

    Examples
    --------
    >>> from fringekit.fea import ContactSettings, Indenter, SolverSettings
    >>> from fringekit.fea.materials import POLYCARBONATE_DEFAULT, SHEET_DEFAULT
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> path = cache_entry(mesh, [Indenter(radius=1e-3, normal_force=[0.2])],
    ...                    materials={0: SHEET_DEFAULT, 1: POLYCARBONATE_DEFAULT},
    ...                    contact=ContactSettings(), settings=SolverSettings(), cache_dir="c")
    >>> path.parent.as_posix(), path.suffix
    ('c/solutions', '.npz')
    """
    return _entry_path(cache_dir, solution_key(mesh, indenters, materials, contact, settings))


def _entry_path(cache_dir, key: str) -> Path:
    """The cache file of solution key ``key`` under ``cache_dir`` (default cache if None)."""
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return root / "solutions" / f"{key[:32]}.npz"


def solve_cached(
    mesh: Mesh,
    indenters: Sequence[Indenter],
    *,
    materials: dict[int, Material],
    contact: ContactSettings,
    settings: SolverSettings,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    progress: bool | Callable = False,
) -> tuple[list[Solution], SolveStats | None, Path]:
    """:func:`fea.solve` through an on-disk cache.

    Returns
    -------
    solutions : list of Solution
    stats : SolveStats, or None when the states came from the cache
    path : where the states are (or would be) cached
    """
    inputs = solution_inputs(mesh, indenters, materials, contact, settings)
    key = hashlib.sha256(inputs.encode()).hexdigest()
    path = _entry_path(cache_dir, key)
    if use_cache and path.exists():
        try:
            sols = load_solutions(path, mesh, key=key)
            log.info("solution cache hit: %s", path)
            return sols, None, path
        except KeyMismatch as exc:  # another solve's states under this name: solve again
            log.warning("solution cache %s is not this solve's: %s; solving again", path, exc)
        except UNREADABLE as exc:  # a stale, truncated or empty file: solve again
            log.warning("solution cache %s is unreadable (%s); solving again", path, exc)
    sols, stats = solve(
        mesh, indenters, materials=materials, contact=contact, settings=settings, progress=progress
    )
    if use_cache:
        save_solutions(path, sols, key=key, inputs=inputs)
        log.info("solution cached: %s", path)
    return sols, stats, path
