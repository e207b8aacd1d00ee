"""Caches heal themselves: a damaged mesh or solution file is logged with its path and
rebuilt, and concurrent writers of one entry never leave a mixed or partial file."""

from __future__ import annotations

import logging
import shutil
import threading

import numpy as np
import pytest

from fringekit.fea import Indenter, SolverSettings
from fringekit.fea.materials import POLYCARBONATE_DEFAULT, SHEET_DEFAULT
from fringekit.fea.problem import ContactSettings
from fringekit.fea.store import load_solutions, save_solutions, solve_cached
from fringekit.meshes import build_mesh, cache_path

DAMAGE = {
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "empty": lambda p: p.write_bytes(b""),
    "text": lambda p: p.write_text("not a cache file\n"),
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_a_damaged_mesh_cache_entry_is_rebuilt(small_meshes, cache_dir, tmp_path, caplog, damage):
    spec = small_meshes["quarter"].spec
    root = tmp_path / "cache"
    shutil.copytree(cache_dir / "meshes", root / "meshes")
    path = cache_path(spec, root)
    DAMAGE[damage](path)
    with caplog.at_level(logging.WARNING, logger="fringekit.meshes"):
        mesh = build_mesh(spec, cache_dir=root)
    assert str(path) in caplog.text and "unreadable" in caplog.text
    assert mesh.n_cells > 0
    assert build_mesh(spec, cache_dir=root).same_as(mesh)  # the entry was rewritten whole


def test_a_mesh_cache_entry_of_another_spec_is_meshed_again(small_meshes, cache_dir, tmp_path):
    half, quarter = small_meshes["half"].spec, small_meshes["quarter"].spec
    root = tmp_path / "cache"
    shutil.copytree(cache_dir / "meshes", root / "meshes")
    shutil.copyfile(cache_path(half, root), cache_path(quarter, root))
    assert build_mesh(quarter, cache_dir=root).same_as(small_meshes["quarter"])


def _solve(mesh, root, load=1.0):
    return solve_cached(
        mesh,
        [Indenter(normal_force=(load,))],
        materials={0: SHEET_DEFAULT, 1: POLYCARBONATE_DEFAULT},
        contact=ContactSettings(),
        settings=SolverSettings(),
        cache_dir=root,
    )


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_a_damaged_solution_cache_entry_is_solved_again(small_meshes, tmp_path, caplog, damage):
    mesh = small_meshes["quarter"]
    root = tmp_path / "cache"
    sols, stats, path = _solve(mesh, root)
    assert stats is not None and path.is_file()
    DAMAGE[damage](path)
    with caplog.at_level(logging.WARNING, logger="fringekit.fea"):
        again, stats2, _ = _solve(mesh, root)
    assert str(path) in caplog.text and "unreadable" in caplog.text
    assert stats2 is not None  # solved, not read
    # the same state to the solver's force tolerance (1e-8): threaded PARDISO with
    # mixed-precision refinement reproduces a solve to about 1e-10, not bit for bit
    assert again[0].indenters[0].depth == pytest.approx(sols[0].indenters[0].depth, rel=1e-8)
    _, stats3, _ = _solve(mesh, root)
    assert stats3 is None  # and the rewritten entry reads back


def test_an_entry_under_another_key_is_solved_again(small_meshes, tmp_path, caplog):
    """The 0.5 N states copied onto the 1 N entry's name are not read as 1 N (they gave
    the 4 N answer for an 8 N config): the entry's stored key differs, so it is logged
    with its path and solved again, and the rewritten entry reads back."""
    mesh = small_meshes["quarter"]
    root = tmp_path / "cache"
    low, _, low_path = _solve(mesh, root, 0.5)
    high, _, high_path = _solve(mesh, root, 1.0)
    assert low_path != high_path
    shutil.copyfile(low_path, high_path)
    with caplog.at_level(logging.WARNING, logger="fringekit.fea"):
        again, stats, _ = _solve(mesh, root, 1.0)
    assert str(high_path) in caplog.text and "not this solve's" in caplog.text
    assert stats is not None  # solved, not read
    fz = again[0].indenters[0].force[2]
    assert fz == pytest.approx(high[0].indenters[0].force[2], rel=1e-6)
    assert fz != pytest.approx(low[0].indenters[0].force[2], rel=0.1)
    assert _solve(mesh, root, 1.0)[1] is None


def test_concurrent_writers_of_one_entry_leave_a_whole_file(small_meshes, tmp_path):
    """Two writers of different states to one path (two runs of one case): every read
    sees one writer's file whole, and no temporary file is left behind."""
    mesh = small_meshes["quarter"]
    sols, _, _ = _solve(mesh, tmp_path / "c")
    path = tmp_path / "s.npz"
    errors = []

    def write(k):
        try:
            for _ in range(5):
                save_solutions(path, sols * k)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=write, args=(k,)) for k in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    back = load_solutions(path, mesh)
    assert len(back) in (1, 2)
    np.testing.assert_array_equal(back[0].displacement, sols[0].displacement)
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == ["s.npz"]
