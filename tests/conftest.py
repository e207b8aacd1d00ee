"""Shared fixtures: small, fast meshes (a few seconds each), generated once per session."""

from __future__ import annotations

import os

import pytest

from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh

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


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fringekit-cache")


@pytest.fixture(scope="session")
def small_meshes(cache_dir):
    """Full, half and quarter meshes of the small block, keyed by symmetry."""
    return {s: build_mesh(small_spec(s), cache_dir=cache_dir) for s in ("full", "half", "quarter")}


@pytest.fixture(scope="session")
def test_library(cache_dir, tmp_path_factory):
    """The coarse library of tests/library_fixtures.py (built once, in this process)."""
    from library_fixtures import LOADS, RATIOS, sensor_config

    from fringekit.library.build import build_library
    from fringekit.library.store import load_library

    out = tmp_path_factory.mktemp("library") / "lib"
    build_library(
        sensor_config(), out, loads=LOADS, ratios=RATIOS, cache_dir=cache_dir, progress=False
    )
    return load_library(out)


@pytest.fixture(scope="session")
def tiny_library(cache_dir, tmp_path_factory):
    """The tiny library of tests/library_fixtures.py (2 loads x 2 ratios, coarse mesh):
    the fast tier's library, built in a few seconds."""
    from library_fixtures import TINY, TINY_LOADS, TINY_RATIOS, sensor_config

    from fringekit.library.build import build_library
    from fringekit.library.store import load_library

    out = tmp_path_factory.mktemp("tiny-library") / "lib"
    build_library(
        sensor_config(**TINY),
        out,
        loads=TINY_LOADS,
        ratios=TINY_RATIOS,
        cache_dir=cache_dir,
        progress=False,
    )
    return load_library(out)
