"""Shared fixtures: small, fast meshes (a few seconds each), generated once per session.

The suite runs in several processes (pytest-xdist): the session's cache and libraries are
made once for all of them, in the session's shared temporary folder, by the first worker
that needs them (the others wait on a file lock, then read what it wrote). A test must not
change what they hold: copy them first. Each worker runs on its own share of the cores
(:func:`_own_cores`).
"""

from __future__ import annotations

import os
from pathlib import Path


def _own_cores() -> None:
    """Pin an xdist worker to its share of the cores (worker i of n takes every n-th core,
    or one core when there are more workers than cores) and its BLAS and OpenMP pools to
    as many threads, before numpy is loaded: the workers' thread pools then do not contend
    for the same cores (two workers on two cores, each with two threads of its own, ran
    every test about 1.5 times slower than one process did)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if not worker or count < 2 or not hasattr(os, "sched_setaffinity"):
        return
    cores = sorted(os.sched_getaffinity(0))
    i = int(worker.removeprefix("gw"))
    mine = cores[i::count] or [cores[i % len(cores)]]
    os.sched_setaffinity(0, mine)
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = str(len(mine))


_own_cores()

import pytest  # noqa: E402
from filelock import FileLock  # noqa: E402

from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh  # noqa: E402

# Headless VTK: pyvista writes VTU without a display when VTK uses its EGL window.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

SMALL_LAYERS = Layers(sheet_thickness=3e-3, substrate_thickness=4e-3, width=12e-3, length=12e-3)
SMALL_SIZING = Sizing(
    h_contact=0.6e-3, refine_radius=1.5e-3, h_far=3e-3, h_sheet=1.5e-3, growth=0.5
)


CENTRE = (IndenterSite(),)

#: Fixtures that take many seconds to set up: every test that needs one is in the slow
#: tier (``pytest -m "not slow"`` leaves it out) whether or not it is marked itself. The
#: coarse test library (below, ~20 s); the README's first command, ``fringekit predict``
#: of the reference case (tests/test_readme.py, ~16 s, then its blocks ~30 s).
SLOW_FIXTURES = {"test_library", "after_first_command"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        if SLOW_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)


def small_spec(symmetry="full", indenters=CENTRE, **kw) -> MeshSpec:
    return MeshSpec(
        layers=kw.pop("layers", SMALL_LAYERS),
        indenters=indenters,
        sizing=kw.pop("sizing", SMALL_SIZING),
        symmetry=symmetry,
        mesher=kw.pop("mesher", "layered"),
    )


def _shared_root(tmp_path_factory) -> Path:
    """The temporary folder of the whole run: the workers' common parent under xdist."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def _made_once(tmp_path_factory, name: str, make) -> Path:
    """``root / name``, made by ``make(folder)`` in the first process that asks for it;
    the others wait for it (the mesh and solution caches write atomically, so the
    workers also share a cache)."""
    folder = _shared_root(tmp_path_factory) / name
    with FileLock(f"{folder}.lock"):
        if not (folder / ".made").is_file():
            folder.mkdir(exist_ok=True)
            make(folder)
            (folder / ".made").touch()
    return folder


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory):
    return _made_once(tmp_path_factory, "fringekit-cache", lambda folder: None)


@pytest.fixture(scope="session")
def small_meshes(cache_dir):
    """Full, half and quarter meshes of the small block, keyed by symmetry."""
    return {s: build_mesh(small_spec(s), cache_dir=cache_dir) for s in ("full", "half", "quarter")}


def _library(tmp_path_factory, name: str, cache_dir, cfg: dict, loads, ratios):
    """A library of ``loads`` x ``ratios`` built once for the run (:func:`_made_once`)."""
    from fringekit.library.build import build_library
    from fringekit.library.store import load_library

    def make(folder):
        kw = {"loads": loads, "ratios": ratios, "cache_dir": cache_dir, "progress": False}
        build_library(cfg, folder / "lib", **kw)

    return load_library(_made_once(tmp_path_factory, name, make) / "lib")


@pytest.fixture(scope="session")
def test_library(cache_dir, tmp_path_factory):
    """The coarse library of tests/library_fixtures.py (built once for the run)."""
    from library_fixtures import LOADS, RATIOS, sensor_config

    return _library(tmp_path_factory, "library", cache_dir, sensor_config(), LOADS, RATIOS)


@pytest.fixture(scope="session")
def tiny_library(cache_dir, tmp_path_factory):
    """The tiny library of tests/library_fixtures.py (2 loads x 2 ratios, coarse mesh):
    the fast tier's library, built in a few seconds."""
    from library_fixtures import TINY, TINY_LOADS, TINY_RATIOS, sensor_config

    cfg = sensor_config(**TINY)
    return _library(tmp_path_factory, "tiny-library", cache_dir, cfg, TINY_LOADS, TINY_RATIOS)
