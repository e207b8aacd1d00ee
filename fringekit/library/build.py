"""``fringekit library build``: a sensor's response library from FEM solves, on Dask.

For each indenter diameter, one continuation solve of the sensor with a single indenter
at the centre of its sheet, full stick, whose load path is a tree: a chain of normal
loads through the grid, and from each normal-load state a branch of tangential loads
along +x at that normal load through the ratios of the grid (the seed paper's protocol,
normal load first, then shear at constant normal load). Each normal state is reached
from the one before (4-6 Newton iterations) instead of from the unloaded sheet (20-50
with cut-backs). The half model about y = 0 holds that loading. Every converged state is
sampled on the polar ray lattice (:mod:`fringekit.library.lattice`).

A branch (one normal load and its tangential states) is written to
``branches/<id>.npz`` atomically as soon as its last state converges, so a killed build
resumes where it stopped: branches whose settings match are not solved again (the
normal states below them are, as the way there, so a resumed build follows the same
path as an uninterrupted one). When all branches exist the field files and
``manifest.json`` (written last) are assembled; a folder without ``manifest.json`` is
not a library.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np

from fringekit._cluster import run_tasks
from fringekit._memory import check_memory
from fringekit.config.files import to_toml
from fringekit.config.model import as_config
from fringekit.errors import ComputeError, ConfigError
from fringekit.library.chain import branch_file, save_npz, solve_chain
from fringekit.library.lattice import default_lattice
from fringekit.library.store import (
    FIELD_KEYS,
    FORMAT,
    Library,
    diameter_id,
    field_file,
    load_library,
    manifest_checksum,
    sensor_key,
    sha256,
)
from fringekit.meshes import default_cache_dir
from fringekit.meshes.build import MESHER_VERSION
from fringekit.output.folders import atomic_write, claim_output
from fringekit.output.versions import run_versions

__all__ = [
    "DEFAULT_LOADS_N",
    "DEFAULT_RATIOS",
    "MAX_RATIO",
    "build_library",
    "library_lattice",
]

#: Normal loads of the default grid (N): steps of about 1.4x, 0.25-12 N.
DEFAULT_LOADS_N = (0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.0, 6.3, 8.0, 10.0, 12.0)
#: Tangential / normal load ratios of the default grid (full stick).
DEFAULT_RATIOS = (0.0, 0.2, 0.4, 0.6, 0.8)
#: The largest tangential / normal load ratio a library is built for. Full stick beyond
#: it needs a friction coefficient above 1, and the solver leaves its range soon after:
#: a build with ratio 1.5 failed after 122 s on a folded contact surface (issue 36), and
#: the small sensor at 4 N converges to 1.5 but no further than 1.56 (2 is not reached).
MAX_RATIO = 1.0
#: The load path of a branch, stored with its settings (a branch solved another way is
#: solved again).
PATH = "normal-load chain, tangential branch at constant normal load"


def library_lattice(cfg: dict, n_slabs: int = 16):
    """The lattice for a config's sheet: out to 12 mm or 0.4 of the sheet's smaller side,
    0.1 mm radial steps out to twice the refined-zone radius, then growing by 8 % per
    node; 5 deg in angle."""
    sh = cfg["sheet"]
    r_max = min(12e-3, 0.4e-3 * min(sh["width_mm"], sh["length_mm"]))
    fine = min(2e-3 * cfg["mesh"]["refine_radius_mm"], 0.6 * r_max)
    return default_lattice(r_max, fine_step=0.1e-3, fine_radius=fine, n_slabs=n_slabs)


def _branch_id(diameter_mm: float, load_n: float) -> str:
    return f"{diameter_id(diameter_mm)}_F{int(round(load_n * 1000)):06d}"


def _finished(path: Path, settings: dict) -> bool:
    try:
        with np.load(path) as z:
            return json.loads(str(z["settings"])) == settings
    except (OSError, ValueError, KeyError):
        return False


def _cache_entry(cache: Path, settings: dict) -> Path:
    """Where a branch of these settings is kept in the cache: named by a hash of the
    settings and the library format."""
    text = json.dumps({"format": FORMAT, **settings}, sort_keys=True)
    return cache / "library-branches" / f"{hashlib.sha256(text.encode()).hexdigest()[:32]}.npz"


def _keep(src: Path, dst: Path) -> None:
    """Copy a branch file whole or not at all (a concurrent build may write the same)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(dst, lambda tmp: shutil.copyfile(src, tmp))


def _from_cache(cache: Path, out: Path, branch: dict) -> bool:
    """Copy the cached branch into ``out`` when the cache holds it (with the same
    settings: a hash collision or a stale file is solved again)."""
    hit = _cache_entry(cache, branch["settings"])
    if not _finished(hit, branch["settings"]):
        return False
    _keep(hit, branch_file(out, branch["id"]))
    return True


def library_bytes(cfg: dict, n_diameters: int, n_loads: int, n_ratios: int, n_slabs: int):
    """Memory (bytes) of a library's largest arrays and what they are, before any solve:
    the larger of one state's sampling on the lattice (R x F rays x S slabs x 72 bytes:
    the slab pairs a, b and their polar A, B in float64, their stack and its filled copy
    of two float64 each, the float32 result) and the assembled library (every diameter,
    load including zero, and ratio: R x F x S x 2 float32)."""
    lat = library_lattice(cfg, 1)
    rays = lat.shape[0] * lat.shape[1]
    state = 72.0 * rays * n_slabs
    stored = 8.0 * rays * n_slabs * n_diameters * (n_loads + 1) * n_ratios
    grid = f"{lat.shape[0]} x {lat.shape[1]} rays x {n_slabs} slabs"
    if state >= stored:
        return state, f"one state on the lattice ({grid})"
    states = n_diameters * (n_loads + 1) * n_ratios
    return stored, f"the library's {states} states ({grid} each)"


def _check_grid(loads, ratios, diameters) -> None:
    loads, ratios = np.asarray(loads, float), np.asarray(ratios, float)
    if len(loads) < 2 or np.any(loads <= 0) or np.any(np.diff(loads) <= 0):
        raise ConfigError(
            f"--load-N = {list(loads)} is not allowed; give at least 2 increasing loads > 0 (N)"
        )
    if len(ratios) < 2 or ratios[0] != 0 or np.any(np.diff(ratios) <= 0) or ratios[-1] > MAX_RATIO:
        shown = " ".join(f"{v:g}" for v in ratios)
        raise ConfigError(
            f"--shear-ratio {shown} is not allowed; give at least 2 increasing ratios from 0 "
            f"in the allowed range [0, {MAX_RATIO:g}] (tangential over normal load)"
        )
    if not diameters or any(not d > 0 for d in diameters):
        raise ConfigError(
            f"--diameter-mm = {list(diameters)} is not allowed; give diameters > 0 (mm)"
        )


def build_library(
    config,
    out,
    *,
    diameters=None,
    loads=DEFAULT_LOADS_N,
    ratios=DEFAULT_RATIOS,
    n_slabs: int = 16,
    scheduler=None,
    workers=None,
    cache_dir=None,
    use_cache: bool = True,
    progress=False,
    echo=print,
    inputs=(),
) -> Library:
    """Solve a sensor over a grid of loads once: a response library for :func:`invert`
    and fast predictions.

    Parameters
    ----------
    config : Config, dict, path or str
        The sensor (sheet, substrate, mesh, solver, optics); its indenters give the
        default diameters.
    out : path
        The library folder: created, or resumed when it holds an unfinished build of the
        same sensor (finished branches are not solved again).
    diameters : sequence of float, optional
        Indenter diameters (mm); default the config's.
    loads : sequence of float
        Normal loads (N), increasing.
    ratios : sequence of float
        Tangential over normal load, from 0 (full stick, along x; other directions are
        rotations).
    n_slabs : int
        Through-thickness slabs of the stored retarder fields.
    scheduler : str, optional
        A Dask scheduler address; default a local cluster (``workers`` processes).
    workers : int, optional
        Local single-threaded worker processes, one diameter's chain each; default one
        diameter is solved in this process on every core; 0 always in this process.
    cache_dir : path, optional
        Mesh and solution cache root (default ``$FRINGEKIT_CACHE_DIR`` or the user
        cache). Every solved branch is kept there too, named by a hash of all it depends
        on (sensor, mesh, solver, lattice, library format, diameter, load and the loads
        below it), and a build into another folder, or with loads added above, takes it
        from there instead of solving it again.
    use_cache : bool
        False: solve every branch not in ``out`` (and keep nothing in the cache).
    progress : bool
        A progress bar with an ETA and one line per stage through ``echo`` (default off).
    echo : callable
        Where the stage lines go.
    inputs : sequence of paths
        Files the build reads (the config), which ``out`` may not be or hold.

    Returns
    -------
    Library
        The assembled library, read back and checked.

    Raises
    ------
    ConfigError
        A bad config or grid, or ``out`` a folder the build may not write (another
        sensor's library, files fringekit did not write), before anything is solved.
    ComputeError
        A solve that failed; the branches solved are kept and a re-run resumes.

    Examples
    --------
    The small built-in sensor over 4, 8 and 12 N and tangential ratios 0 and 0.4 (about
    20 s on 2 cores; the default grid on the reference sensor takes about 9 min):

    >>> import tempfile, fringekit
    >>> lib = fringekit.build_library("small", tempfile.mkdtemp() + "/lib",
    ...                               loads=[4, 8, 12], ratios=[0, 0.4], progress=False)
    >>> lib.diameters_mm, lib.max_load_N, [float(r) for r in lib.shear_ratio]
    ([3.5], 12.0, [0.0, 0.4])
    """
    cfg = as_config(config).data
    diameters = sorted(
        {float(d["diameter_mm"]) for d in cfg["indenter"]}
        if diameters is None
        else {float(d) for d in diameters}
    )
    _check_grid(loads, ratios, diameters)
    need, what = library_bytes(cfg, len(diameters), len(loads), len(ratios), n_slabs)
    check_memory(need, what, f"--slabs {n_slabs}", hint="give fewer --slabs (default 16)")
    if cfg["optics"]["include_substrate"]:
        raise ConfigError(
            "optics.include_substrate = true is not supported by a library "
            "(it stores the sheet's stress only); set it to false"
        )
    out = Path(out)
    given = [config] if isinstance(config, (str, os.PathLike)) else []
    with claim_output(out, command="library build", inputs=[*given, *inputs], resume=True):
        _same_sensor(out, sensor_key(cfg))
        return _build(
            cfg,
            out,
            diameters,
            loads,
            ratios,
            n_slabs,
            scheduler,
            workers,
            Path(cache_dir or default_cache_dir()),
            use_cache,
            progress,
            echo,
        )


def _same_sensor(out: Path, key: dict) -> None:
    """A library folder is resumed only by a build of its own sensor (the manifest's, or
    a finished branch's when the build was stopped): another is refused before solving."""
    try:
        built = json.loads((out / "manifest.json").read_text())["sensor"]
    except (OSError, ValueError, KeyError, TypeError):
        built = None
    for f in [] if built else sorted((out / "branches").glob("*.npz"))[:1]:
        try:
            with np.load(f) as z:
                built = json.loads(str(z["settings"]))["sensor"]
        except (OSError, ValueError, KeyError):
            pass
    if not isinstance(built, dict):
        return
    have = json.loads(json.dumps(key))  # as stored: lists, not tuples
    for table in sorted(set(built) | set(have)):
        a, b = built.get(table), have.get(table)
        pairs = (
            [(f"{table}.{k}", a.get(k), b.get(k)) for k in sorted(set(a) | set(b))]
            if (isinstance(a, dict) and isinstance(b, dict))
            else [(table, a, b)]
        )
        for name, was, now in pairs:
            if was != now:
                raise ConfigError(
                    f"--out {out} is the library of another sensor: built for {name} = "
                    f"{json.dumps(was)}, this config has {json.dumps(now)}; give an empty or "
                    "new folder, or the sensor the library was built for"
                )


def _build(
    cfg,
    out,
    diameters,
    loads,
    ratios,
    n_slabs,
    scheduler,
    workers,
    cache,
    use_cache,
    progress,
    echo,
) -> Library:
    """Solve the unfinished branches into the claimed folder ``out`` (those in the cache
    copied instead), then assemble it."""
    lat = library_lattice(cfg, n_slabs)
    key = sensor_key(cfg)
    mesh = dict(cfg["mesh"], symmetry="half")
    settings = {
        "sensor": key,
        "mesh": mesh,
        "mesher": MESHER_VERSION,  # a mesher that meshes the same config otherwise
        "solver": cfg["solver"],
        "ratios": list(ratios),
        "lattice_r_mm": list(lat.r * 1e3),
        "n_slabs": n_slabs,
        "path": PATH,
    }
    branches, chains = [], []
    (out / "branches").mkdir(parents=True, exist_ok=True)
    for d in diameters:
        mine = []
        for f in loads:
            below = [float(v) for v in loads if v < f]  # the way there is part of the path
            b = {
                "id": _branch_id(d, f),
                "load_N": float(f),
                "settings": dict(settings, diameter_mm=d, load_N=float(f), loads_below=below),
            }
            b["todo"] = not _finished(branch_file(out, b["id"]), b["settings"])
            b["cached"] = b["todo"] and use_cache and _from_cache(cache, out, b)
            b["todo"] = b["todo"] and not b["cached"]
            mine.append(b)
        branches += mine
        if any(b["todo"] for b in mine):
            chains.append(
                {
                    "id": diameter_id(d),
                    "diameter_mm": d,
                    "config": cfg,
                    "branches": mine,
                    "ratios": list(ratios),
                    "r": lat.r,
                    "phi": lat.phi,
                    "n_slabs": n_slabs,
                }
            )
    (out / "manifest.json").unlink(missing_ok=True)  # not a library until assembled again
    n_todo = sum(b["todo"] for b in branches)
    say = echo if progress else (lambda s: None)
    say(
        f"library: {len(branches)} branches ({len(diameters)} diameter(s) x {len(loads)} "
        f"loads, {len(ratios)} states each), {len(branches) - n_todo} already solved "
        f"({sum(b['cached'] for b in branches)} from the cache)"
    )
    t0 = time.perf_counter()
    failed = _run_chains(chains, out, str(cache), scheduler, workers, progress, say)
    if use_cache:
        for b in branches:  # what this build solved, for the next one
            solved = branch_file(out, b["id"])
            if b["todo"] and _finished(solved, b["settings"]):
                _keep(solved, _cache_entry(cache, b["settings"]))
    if failed:
        raise ComputeError(
            f"library: the solve failed for diameter {failed[0]['id']}: "
            f"{failed[0]['error']}; the {failed[0]['n_done']} branch(es) "
            "solved are kept, re-run to resume"
        )
    build_s = time.perf_counter() - t0
    _assemble(cfg, out, branches, diameters, loads, ratios, lat, mesh, build_s)
    return load_library(out)


def _run_chains(chains, out: Path, cache: str, scheduler, workers, progress, say) -> list:
    """Solve the chains: in this process (all cores to one solve, a bar over its load
    states) when there is one and no scheduler or ``workers=0``, else one Dask task
    per chain. Returns the failed chains' results."""
    failed = []

    def report(res: dict) -> None:
        if res["error"]:
            failed.append(dict(res, n_done=len(res["done"])))
            say(f"library: diameter {res['id']} failed: {res['error']}")

    inline = not scheduler and (workers == 0 or (workers is None and len(chains) == 1))
    if inline:
        for t in chains:
            report(solve_chain(t, str(out.resolve()), cache, progress))
    else:
        run_tasks(
            solve_chain,
            chains,
            [f"chain-{t['id']}" for t in chains],
            str(out.resolve()),
            cache,
            scheduler=scheduler,
            workers=workers,
            progress=progress,
            desc="library diameters",
            unit="diameter",
            on_result=report,
        )
    return failed


#: The stored field is tapered to zero over this outer fraction of the lattice radius
#: (cos^2), so a synthesised image has no step where one indenter's lattice ends.
TAPER = 0.25


def condition_fields(AB: np.ndarray, lat) -> np.ndarray:
    """What is stored from the sampled fields AB (nF, nS, R, F, S, 2).

    - The normal-load states (ratio 0) are averaged over the angle, with sigma_rp = 0:
      that loading is axisymmetric, and what the mesh leaves of the angle dependence
      (up to 10-25 % of the ray integral on a coarse mesh) would make a tangential load
      turned about the axis jump as its magnitude goes to zero.
    - The outer TAPER of the lattice radius is tapered to zero (cos^2).
    """
    out = AB.astype(np.float64)
    out[:, 0, ..., 0] = out[:, 0, ..., 0].mean(axis=2, keepdims=True)  # (nF, R, F, S): over F
    out[:, 0, ..., 1] = 0.0
    t = np.clip((lat.r - (1 - TAPER) * lat.r_max) / (TAPER * lat.r_max), 0.0, 1.0)
    w = np.cos(0.5 * np.pi * t) ** 2
    return (out * w[:, None, None, None]).astype(np.float32)


def _assemble(cfg, out: Path, tasks, diameters, loads, ratios, lat, mesh, build_s) -> dict:
    files = {}
    for d in diameters:
        parts = []
        for t in tasks:
            if t["settings"]["diameter_mm"] == d:
                with np.load(branch_file(out, t["id"])) as z:
                    parts.append({k: z[k] for k in FIELD_KEYS})
        name = field_file(d)
        arrays = {k: np.stack([p[k] for p in parts]) for k in FIELD_KEYS}
        arrays["AB"] = condition_fields(arrays["AB"], lat)
        save_npz(out / name, **arrays)
        files[name] = {"diameter_mm": d, "sha256": sha256(out / name)}
    atomic_write(out / "config.toml", to_toml(cfg))
    manifest = {
        "format": FORMAT,
        "sensor": sensor_key(cfg),
        "grid": {
            "diameters_mm": diameters,
            "load_N": [float(v) for v in loads],
            "shear_ratio": [float(v) for v in ratios],
            "friction": "stick",
        },
        "lattice": {
            "r_mm": [float(v) for v in lat.r * 1e3],
            "phi_deg": [float(v) for v in np.degrees(lat.phi)],
            "n_slabs": lat.n_slabs,
        },
        "mesh": mesh,
        "mesher": MESHER_VERSION,  # a mesher that meshes the same config otherwise
        "solver": cfg["solver"],
        "files": files,
        "build_s": build_s,
        "versions": run_versions(),
    }
    manifest = json.loads(json.dumps(manifest))  # as it reads back: lists, not tuples
    manifest["manifest_sha256"] = manifest_checksum(manifest)
    atomic_write(out / "manifest.json", json.dumps(manifest, indent=1))
    return manifest
