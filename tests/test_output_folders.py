"""An output folder describes exactly one run: runs are written beside it and swapped in
when they end; a failed solve never replaces an earlier run; an error leaves it as it was."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_cli import tiny_predict

from fringekit.cli.main import main


@pytest.fixture(scope="module")
def folder(tmp_path_factory, cache_dir):
    root = tmp_path_factory.mktemp("folders")
    _, out, args = tiny_predict(root, cache_dir)

    def run(*sets: str) -> int:
        return main(args + [a for s in sets for a in ("--set", s)])

    return root, out, run


def _summary(out):
    return json.loads((out / "summary.json").read_text())


def _leftovers(root):
    return sorted(p.name for p in root.iterdir() if p.name.startswith("."))


@pytest.mark.slow
def test_a_rerun_replaces_the_earlier_run_whole(folder):
    root, out, run = folder
    assert run("indenter.load_N=[4.0, 8.0]", "optics.render=all") == 0
    assert sorted(p.name for p in out.glob("state_*")) == ["state_01", "state_02"]
    assert run() == 0
    assert sorted(p.name for p in out.glob("state_*")) == ["state_01"]  # no stale state_02
    assert _summary(out)["status"] == "ok" and len(_summary(out)["states"]) == 1
    assert _leftovers(root) == []


@pytest.mark.slow
def test_a_failed_solve_keeps_the_earlier_run(folder, capsys):
    root, out, run = folder
    assert run() == 0
    before = (out / "summary.json").read_bytes()
    code = run("indenter.load_N=[1.0, 400.0]", "solver.max_cutbacks=2", "solver.max_iterations=20")
    assert code == 1
    err = capsys.readouterr().err
    assert "out-failed" in err and "earlier run" in err and "Traceback" not in err
    assert (out / "summary.json").read_bytes() == before
    failed = root / "out-failed"
    assert _summary(failed)["status"] == "failed" and (failed / "state_01").is_dir()
    assert _leftovers(root) == []


def test_an_error_after_solving_leaves_the_folder_as_it_was(folder, capsys):
    root, out, run = folder
    assert run() == 0
    before = sorted(p.name for p in out.rglob("*"))
    summary = (out / "summary.json").read_bytes()
    assert run("optics.field_of_view_mm=0.5") == 2  # every pixel in the contact zone
    assert "field of view" in capsys.readouterr().err
    assert sorted(p.name for p in out.rglob("*")) == before
    assert (out / "summary.json").read_bytes() == summary
    assert _leftovers(root) == []


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["indenter.shear_N=[8.0, 0.0]"], 'contact.friction > 0 (Coulomb) or "stick"'),
        (["optics.center_mm=[500.0, 0.0]"], "optics.center_mm = [500.0, 0.0]"),
    ],
)
def test_checks_that_need_no_solve_come_before_any_work(tmp_path, capsys, sets, message):
    """Shear without friction and a field of view off the sheet stop the run before it
    meshes or writes anything (they were found after meshing or solving)."""
    out = tmp_path / "o"
    args = ["predict", "--out", str(out), "--cache-dir", str(tmp_path / "c")]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "inf" not in err
    assert not out.exists() and not (tmp_path / "c").exists()


def test_ctrl_c_during_the_solve_keeps_the_converged_states(folder, capsys, monkeypatch):
    """Ctrl-C on the way to the second state: exit 130, the first state's VTU and a
    summary saying "interrupted" go to out-interrupted; the earlier run stays."""
    import fringekit.fea.watchdog

    root, out, run = folder
    assert run() == 0
    before = (out / "summary.json").read_bytes()
    real = fringekit.fea.watchdog.Watchdog.check

    def ctrl_c(self, iteration, residual, max_iterations):
        if "7 N" in self.target:
            raise KeyboardInterrupt
        return real(self, iteration, residual, max_iterations)

    monkeypatch.setattr(fringekit.fea.watchdog.Watchdog, "check", ctrl_c)
    assert run("indenter.load_N=[3.0, 7.0]") == 130
    err = capsys.readouterr().err
    assert "interrupted by the user" in err and "Traceback" not in err
    assert (out / "summary.json").read_bytes() == before
    got = root / "out-interrupted"
    s = _summary(got)
    assert s["status"] == "interrupted" and len(s["states"]) == 1
    assert "load state 2 of 2" in s["error"]
    assert (got / "state_01" / "solution.vtu").stat().st_size > 0
    assert _leftovers(root) == []


def test_predict_says_the_model_size_and_an_estimate_before_solving(folder, capsys):
    root, out, _ = folder
    cfg = root / "tiny.toml"
    fresh = root / "fresh-cache"  # a solve, not a cache hit
    code = main(["predict", str(cfg), "--out", str(root / "loud"), "--cache-dir", str(fresh)])
    said = capsys.readouterr().out
    assert code == 0
    line = next(x for x in said.splitlines() if x.startswith("solve:") and "DOF" in x)
    assert "cells" in line and "about" in line and "s to solve" in line
    assert "quarter model" in said


# -- Every command claims its output folder: nothing a user owns is ever lost ----------
#
# A folder is replaced (or resumed) only when it holds an earlier run of the same command
# and nothing that run did not write; a missing or empty one is used; anything else is
# refused with one line and exit 2 before any work.

#: Each command: its arguments before --out (placeholders: the kit's folders), the
#: command its runs are marked with, and the kit folder holding its first input.
COMMANDS = {
    "predict": ("predict {cfg}/tiny.toml --cache-dir {cache}", "predict", "cfg"),
    "predict --library": ("predict {cfg}/tiny.toml --library {lib}", "predict", "lib"),
    "invert": ("invert {img}/img.png --library {lib} --pixel-mm 0.1", "invert", "img"),
    "analyze": ("analyze {img}/img.png", "analyze", "img"),
    "compare": ("compare {maps}/maps.npz {maps}/maps.npz", "compare", "maps"),
    "calibrate": ("calibrate {cfg}/cal.toml --cache-dir {cache}", "calibrate", "cfg"),
    "calibrate --disc photo": (
        "calibrate --disc {disc}/disc.png --load-N 300 --diameter-mm 40 --thickness-mm 5",
        "calibrate",
        "disc",
    ),
    "calibrate --disc map": (
        "calibrate --disc {disc}/disc.npz --load-N 300 --diameter-mm 40 --thickness-mm 5",
        "calibrate",
        "disc",
    ),
    "estimate": (
        "estimate {maps}/maps.npz --calibration {cal}/cal.json --centre 31.5 31.5",
        "estimate",
        "maps",
    ),
    "sweep": ("sweep {sweep}/sweep.toml --cache-dir {cache}", "sweep", "sweep"),
    "library build": (
        "library build {cfg}/tiny.toml --load-N 4 8 --shear-ratio 0 0.5 --cache-dir {cache}",
        "library build",
        "cfg",
    ),
    "mesh": ("mesh {cfg}/tiny.toml --cache-dir {cache}", "mesh", "cfg"),
}
#: Commands that finish in about a second here: run for real into folders.
QUICK = ["analyze", "compare", "calibrate --disc map", "estimate", "mesh"]


@pytest.fixture(scope="module")
def kit(tmp_path_factory, cache_dir):
    """Small inputs of every command, each kind in its own folder."""
    import imageio.v3 as iio
    import numpy as np
    from test_cli import TINY

    from fringekit.optics import PSM4_ASSUMED, DiametralDisc, PixelGrid, optical_map

    root = tmp_path_factory.mktemp("kit")
    d = {k: root / k for k in ("cfg", "img", "maps", "cal", "disc", "sweep", "lib")}
    for p in d.values():
        p.mkdir()
    (d["cfg"] / "tiny.toml").write_text(TINY)
    (d["cfg"] / "cal.toml").write_text(TINY.replace("[8.0]", "[2.0, 4.0, 6.0]"))
    order = np.fromfunction(lambda r, c: np.hypot(r - 31.5, c - 31.5) / 10, (64, 64))
    np.savez(d["maps"] / "maps.npz", fringe_order=order, pixel_size_m=np.array(1e-4))
    fit = {"a": 1.0, "b": 1.5, "sigma_logF": 0.1, "n": 5, "range": [0.1, 5.0]}
    (d["cal"] / "cal.json").write_text(
        json.dumps({"version": 2, "normal_fits": {"order_at_2mm": fit}})
    )
    rings = np.fromfunction(lambda r, c: np.hypot(r - 15.5, c - 15.5), (32, 32))
    iio.imwrite(d["img"] / "img.png", (127 + 100 * np.cos(rings)).astype(np.uint8))
    iio.imwrite(d["disc"] / "disc.png", (127 + 100 * np.cos(rings)).astype(np.uint8))
    n, D = 61, 0.04
    grid = PixelGrid((n, n), D / n)
    disc = optical_map(
        DiametralDisc(P=300.0, D=D, t=5e-3), grid, PSM4_ASSUMED, n_samples=3, reflection=False
    )
    np.savez(d["disc"] / "disc.npz", fringe_order=disc.fringe_order(), pixel_size_m=grid.pixel_size)
    (d["sweep"] / "sweep.toml").write_text(
        f'base = "{d["cfg"] / "tiny.toml"}"\n[grid]\n"indenter.load_N" = [[4.0]]\n'
    )
    (d["lib"] / "manifest.json").write_text("{}")  # refused before it is read
    return root, {**{k: str(v) for k, v in d.items()}, "cache": str(cache_dir)}


def _argv(kit, name: str, out) -> list[str]:
    args = [a.format(**kit[1]) for a in COMMANDS[name][0].split()]
    return [*args, "--quiet", "--out", str(out)]


def _slug(name: str) -> str:
    return name.replace(" --", "-").replace(" ", "-")


def _mark(folder, command: str, files=None) -> None:
    """Plant the marker of an earlier run of ``command`` that wrote ``files``."""
    from fringekit.output.folders import MARKER

    mark = {"command": command, "fringekit": "0", "time": "", "files": files}
    (folder / MARKER).write_text(json.dumps(mark))


def _snapshot(folder) -> dict:
    """Every path under ``folder`` (hidden ones too) with the bytes of each file."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() if p.is_file() else None
        for p in sorted(folder.rglob("*"))
    }


def _refused(code: int, capsys, out, *words: str) -> str:
    """Exit 2 with one line naming --out and the folder (as given) and ``words``."""
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "--out" in err and str(out) in err, err
    assert "PosixPath(" not in err and "np.float64(" not in err, err
    for w in words:
        assert w in err, err
    return err


def _no_leftovers(out) -> None:
    """Nothing of a run beside ``out``: no lock file, no run folder."""
    beside = [p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}.")]
    assert beside == [], beside


@pytest.mark.parametrize("name", COMMANDS)
def test_a_folder_with_files_fringekit_did_not_write_is_refused(kit, name, capsys):
    out = kit[0] / f"planted-{_slug(name)}"
    (out / "raw").mkdir(parents=True)
    (out / "thesis.txt").write_text("three years of work")
    (out / "raw" / "data.bin").write_bytes(b"\x00\x01")
    before = _snapshot(out)
    err = _refused(main(_argv(kit, name, out)), capsys, out, "thesis.txt", "raw/")
    assert "did not write" in err and f"`fringekit {COMMANDS[name][1]}` run" in err
    assert _snapshot(out) == before
    _no_leftovers(out)


@pytest.mark.parametrize("name", COMMANDS)
def test_an_existing_file_is_refused(kit, name, capsys):
    out = kit[0] / f"file-{_slug(name)}.txt"
    out.write_text("mine")
    _refused(main(_argv(kit, name, out)), capsys, out, "is a file")
    assert out.read_text() == "mine"
    _no_leftovers(out)


@pytest.mark.parametrize("name", COMMANDS)
def test_the_folder_of_an_input_and_its_parents_are_refused(kit, name, capsys):
    """--out the config's, the image's or the maps' own folder, the library, or a folder
    above one of them: the inputs would go with the folder."""
    root, folders = kit
    inputs = Path(folders[COMMANDS[name][2]])
    for out in (inputs, root):
        before = _snapshot(inputs)
        _refused(main(_argv(kit, name, out)), capsys, out, "an input of this run")
        assert _snapshot(inputs) == before
        _no_leftovers(out)


@pytest.mark.parametrize("name", COMMANDS)
def test_the_current_directory_and_its_parents_are_refused(kit, name, capsys, monkeypatch):
    here = kit[0] / f"cwd-{_slug(name)}" / "here"
    here.mkdir(parents=True)
    monkeypatch.chdir(here)
    _refused(main(_argv(kit, name, ".")), capsys, ".", "is the current directory")
    _refused(main(_argv(kit, name, "..")), capsys, "..", "holds the current directory")
    assert here.is_dir() and not any(here.iterdir())
    assert [p.name for p in here.parent.iterdir()] == ["here"]


@pytest.mark.parametrize("name", COMMANDS)
def test_a_run_of_another_command_is_refused(kit, name, capsys):
    other = "analyze" if COMMANDS[name][1] != "analyze" else "predict"
    out = kit[0] / f"other-{_slug(name)}"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    _mark(out, other, ["summary.json"])
    before = _snapshot(out)
    _refused(main(_argv(kit, name, out)), capsys, out, f"earlier `fringekit {other}` run")
    assert _snapshot(out) == before
    _no_leftovers(out)


@pytest.mark.parametrize("name", COMMANDS)
def test_a_second_writer_is_refused_not_raced(kit, name, capsys):
    """A run holds the lock beside the folder (here: this process): the second waits for
    nothing and writes nothing."""
    out = kit[0] / f"busy-{_slug(name)}"
    lock = out.with_name(f".{out.name}.lock")
    lock.write_text(f"{os.getpid()}\n")
    try:
        _refused(
            main(_argv(kit, name, out)),
            capsys,
            out,
            "being written by another run",
            f"pid {os.getpid()}",
        )
        assert not out.exists() and lock.read_text() == f"{os.getpid()}\n"
    finally:
        lock.unlink()


@pytest.mark.parametrize("name", QUICK)
def test_an_empty_folder_is_used_and_an_earlier_run_replaced(kit, name, capsys):
    out = kit[0] / f"runs-{_slug(name)}"
    out.mkdir()
    assert main(_argv(kit, name, out)) == 0
    mark = json.loads((out / ".fringekit-run.json").read_text())
    assert mark["command"] == COMMANDS[name][1] and mark["fringekit"] and mark["time"]
    first = _snapshot(out)
    wrote = {k + "/" * (v is None) for k, v in first.items() if k != ".fringekit-run.json"}
    assert sorted(wrote) == mark["files"]
    assert main(_argv(kit, name, out)) == 0  # the earlier run is replaced
    assert sorted(_snapshot(out)) == sorted(first)
    _no_leftovers(out)
    # files added to a run folder are the user's: the run is no longer replaced
    (out / "notes.txt").write_text("mine")
    capsys.readouterr()
    err = _refused(main(_argv(kit, name, out)), capsys, out, "notes.txt")
    assert "files it did not write" in err and (out / "notes.txt").read_text() == "mine"


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_what_killed_runs_left_is_removed_by_the_next_run(kit, capsys):
    out = kit[0] / "killed"
    dead = _dead_pid()
    stale = [
        out.with_name(f".killed.{dead}-0123abcd.part"),
        out.with_name(f".killed.{dead}-4567cdef.old"),
    ]
    live = out.with_name(f".killed.{os.getpid()}-89abcdef.part")
    for p in (*stale, live):
        (p / "state_01").mkdir(parents=True)
    lock = out.with_name(".killed.lock")
    lock.write_text(f"{dead}\n")  # the lock of a killed run is taken over
    assert main(_argv(kit, "estimate", out)) == 0
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if "killed runs" in x)
    assert "removed 2" in line and all(p.name in line for p in stale), err
    assert not any(p.exists() for p in stale) and live.is_dir()  # a live run's is kept
    assert not lock.exists() and (out / "estimate.json").is_file()
    shutil.rmtree(live)


@pytest.mark.parametrize("where", ["manifest", "branch"])
def test_library_build_refuses_another_sensors_library_before_solving(kit, where, capsys):
    """A finished library (its manifest) or a killed build (a finished branch) of the
    sheet at 4 MPa is not resumed by a build at 6 MPa: refused, the key named."""
    import numpy as np

    from fringekit.config.files import load_config
    from fringekit.library.store import sensor_key

    root, folders = kit
    lib = root / f"lib-{where}"
    (lib / "branches").mkdir(parents=True)
    sensor = sensor_key(load_config(Path(folders["cfg"]) / "tiny.toml"))
    if where == "manifest":
        (lib / "manifest.json").write_text(json.dumps({"sensor": sensor}))
    else:
        np.savez(lib / "branches" / "d03500_F004000.npz", settings=json.dumps({"sensor": sensor}))
    _mark(lib, "library build")
    before = _snapshot(lib)
    argv = _argv(kit, "library build", lib) + ["--set", "sheet.E_MPa=6"]
    _refused(main(argv), capsys, lib, "another sensor", "sheet.E_MPa", "4", "6")
    assert _snapshot(lib) == before


def test_an_analysis_into_a_state_folder_of_a_prediction_is_refused(kit, capsys):
    pred = kit[0] / "pred"
    (pred / "state_01").mkdir(parents=True)
    shutil.copy(Path(kit[1]["maps"]) / "maps.npz", pred / "state_01" / "maps.npz")
    (pred / "summary.json").write_text("{}")
    _mark(pred, "predict", ["state_01/", "state_01/maps.npz", "summary.json"])
    before = _snapshot(pred)
    out = pred / "state_01"
    _refused(main(_argv(kit, "analyze", out)), capsys, out, "earlier `fringekit predict` run")
    # compare PRED AN --out PRED: the prediction is an input
    argv = ["compare", str(pred), str(Path(kit[1]["maps"]) / "maps.npz"), "--out", str(pred)]
    _refused(main(argv), capsys, pred, "an input of this run")
    assert _snapshot(pred) == before


# -- The helper itself ----------------------------------------------------------------


def test_claim_output_swaps_in_marks_and_keeps_an_earlier_run_on_error(tmp_path):
    from fringekit.output.folders import MARKER, claim_output

    out = tmp_path / "o"
    with claim_output(out, command="x") as work:
        assert work.parent == tmp_path and work.name.startswith(".o.") and not out.exists()
        (work / "a.txt").write_text("1")
    assert json.loads((out / MARKER).read_text())["files"] == ["a.txt"]
    before = _snapshot(out)
    with pytest.raises(RuntimeError), claim_output(out, command="x") as work:
        (work / "a.txt").write_text("2")
        raise RuntimeError("stop")
    assert _snapshot(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["o"]
    # a failed run goes beside an earlier run; an earlier one there is replaced, a folder
    # of anything else is kept and the next free name is used
    for expect, then_add_a_file in (("o-failed", False), ("o-failed", True), ("o-failed-2", False)):
        claim = claim_output(out, command="x")
        with claim as work:
            (work / "b.txt").write_text("3")
            claim.divert("failed")
        assert claim.dest == tmp_path / expect and (claim.dest / "b.txt").is_file()
        if then_add_a_file:
            (claim.dest / "mine.txt").write_text("mine")
    assert (tmp_path / "o-failed" / "mine.txt").read_text() == "mine"
    assert _snapshot(out) == before
    # a file put into the folder while the run works is kept: the run goes beside it
    claim = claim_output(out, command="x", say=lambda line: said.append(line))
    said = []
    with claim as work:
        (work / "c.txt").write_text("4")
        (out / "thesis.txt").write_text("mine")
    assert claim.dest == tmp_path / "o-2" and (claim.dest / "c.txt").is_file()
    assert _snapshot(out) == {**before, "thesis.txt": b"mine"}
    assert "changed during the run" in said[0] and "thesis.txt" in said[0]


def test_atomic_write_writes_whole_or_not_at_all(tmp_path):
    from fringekit.output.folders import atomic_write

    f = tmp_path / "t.json"
    atomic_write(f, "text")
    atomic_write(tmp_path / "b.bin", b"\x00")
    atomic_write(tmp_path / "c.npz", lambda p: p.write_bytes(p.suffix.encode()))
    assert f.read_text() == "text" and (tmp_path / "c.npz").read_bytes() == b".npz"

    def half(p):
        p.write_text("half")
        raise OSError("disk full")

    with pytest.raises(OSError):
        atomic_write(f, half)
    assert f.read_text() == "text"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin", "c.npz", "t.json"]


def test_the_lock_of_a_killed_but_unreaped_run_is_taken_over(kit, capsys):
    """A killed run's process may linger as a zombie (nobody reaps it in a container whose
    first process reaps nothing): signal 0 still reaches it, yet it writes nothing more."""
    if not Path("/proc/self/stat").exists():
        pytest.skip("needs /proc to tell an unreaped process from a running one")
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    for _ in range(200):  # ended, not reaped: a zombie
        if Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
            break
        time.sleep(0.05)
    try:
        out = kit[0] / "zombie"
        lock = out.with_name(".zombie.lock")
        lock.write_text(f"{proc.pid}\n")
        assert main(_argv(kit, "estimate", out)) == 0, capsys.readouterr().err
        assert not lock.exists() and (out / "estimate.json").is_file()
    finally:
        proc.wait()
