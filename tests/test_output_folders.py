"""An output folder describes exactly one run: runs are written beside it and swapped in
when they end; a failed solve never replaces an earlier run; an error leaves it as it was."""

from __future__ import annotations

import json

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


def test_a_rerun_replaces_the_earlier_run_whole(folder):
    root, out, run = folder
    assert run("indenter.load_N=[4.0, 8.0]", "optics.render=all") == 0
    assert sorted(p.name for p in out.glob("state_*")) == ["state_01", "state_02"]
    assert run() == 0
    assert sorted(p.name for p in out.glob("state_*")) == ["state_01"]  # no stale state_02
    assert _summary(out)["status"] == "ok" and len(_summary(out)["states"]) == 1
    assert _leftovers(root) == []


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
    code = main(["predict", str(cfg), "--out", str(root / "loud")])
    said = capsys.readouterr().out
    assert code == 0
    line = next(x for x in said.splitlines() if x.startswith("solve:") and "DOF" in x)
    assert "cells" in line and "about" in line and "s to solve" in line
    assert "quarter model" in said
