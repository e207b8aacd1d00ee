"""The fringekit command: configs, symmetry choice, predict end to end on a tiny case."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from fringekit.cli.main import main
from fringekit.cli.predict import UNRESOLVED_EDGE
from fringekit.config.files import (
    BUILTIN_CASES,
    ConfigError,
    effective_config,
    load_config,
    to_toml,
)
from fringekit.config.inputs import build_inputs, choose_symmetry
from fringekit.meshes import read_vtu
from fringekit.prediction.pipeline import used_config

# The small block of conftest.py (12 x 12 mm, 3 mm sheet on 4 mm PC, coarse sizes), a
# 32 x 32 image and few samples: the whole pipeline in well under a minute.
TINY = """
case = "tiny"
[sheet]
width_mm = 12
length_mm = 12
[substrate]
thickness_mm = 4
[mesh]
h_contact_mm = 0.6
refine_radius_mm = 1.5
h_sheet_mm = 1.5
h_far_mm = 3
growth = 0.5
[optics]
field_of_view_mm = 10
pixels = 32
samples_per_ray = 24
white_light_wavelengths = 7
[[indenter]]
load_N = [8.0]
"""


def test_defaults_are_the_reference_case():
    cfg = load_config()
    assert cfg["case"] == "reference"
    assert cfg["sheet"]["thickness_mm"] == 3.0 and cfg["substrate"]["thickness_mm"] == 15.0
    assert cfg["sheet"]["E_MPa"] == 4.0 and cfg["sheet"]["nu"] == 0.49
    assert len(cfg["indenter"]) == 1
    assert cfg["indenter"][0]["diameter_mm"] == 3.5 and cfg["indenter"][0]["load_N"] == [8.0]
    inp = build_inputs(cfg)
    spec, inds, mats, contact = inp.spec, inp.indenters, inp.materials, inp.contact
    assert spec.symmetry == "quarter"
    assert spec.layers.sheet_thickness == pytest.approx(3e-3)
    assert inds[0].radius == pytest.approx(1.75e-3) and inds[0].normal_force == (8.0,)
    assert mats[0].E == pytest.approx(4e6) and contact.friction == 0.0


def test_shear_case_is_a_stuck_half_model():
    cfg = load_config("shear")
    inp = build_inputs(cfg)
    spec, inds, contact = inp.spec, inp.indenters, inp.contact
    assert spec.symmetry == "half" and math.isinf(contact.friction)
    assert inds[0].shear_force == ((0.0, 0.0), (6.4, 0.0))


@pytest.mark.parametrize("name", sorted(BUILTIN_CASES) + ["depth"])
def test_toml_round_trip(name, tmp_path):
    if name == "depth":
        cfg = effective_config({"indenter": [{"depth_mm": [0.1, 0.2]}], "case": "depth"})
        assert cfg["indenter"][0]["load_N"] is None
    else:
        cfg = load_config(name)
    f = tmp_path / "c.toml"
    f.write_text(to_toml(cfg))
    assert load_config(f) == cfg


@pytest.mark.parametrize(
    "given, words",
    [
        ({"sheet": {"thickness": 3}}, ["unknown key sheet.thickness", "thickness_mm"]),
        ({"optic": {}}, ["unknown key 'optic'", "optics"]),
        ({"sheet": {"E_MPa": -1}}, ["sheet.E_MPa = -1", "allowed range (0"]),
        ({"sheet": {"nu": 0.5}}, ["sheet.nu = 0.5", "0.4999"]),
        ({"optics": {"pixels": "many"}}, ["optics.pixels = 'many'", "integer"]),
        ({"optics": {"wavelength_nm": 1000}}, ["optics.wavelength_nm = 1000", "360, 830"]),
        ({"optics": {"light": "sun"}}, ["optics.light = 'sun'", "LED"]),
        ({"contact": {"friction": "glue"}}, ["contact.friction = 'glue'", "stick"]),
        ({"contact": {"friction": -0.1}}, ["contact.friction = -0.1", "allowed range"]),
        ({"indenter": [{"load_N": [-2.0]}]}, ["indenter[0].load_N[0] = -2.0"]),
        ({"indenter": [{"load_N": [1.0, 2.0], "shear_N": [[0, 0], [1, 0], [2, 0]]}]}, ["3 load"]),
        ({"indenter": [{"load_N": [8.0], "depth_mm": [0.1]}]}, ["not both"]),
        ({"indenter": [{"load_N": [1.0]}, {"x_mm": 5, "load_N": [1.0, 2.0]}]}, ["different"]),
        ({"mesh": {"h_contact_mm": 2, "h_sheet_mm": 1}}, ["h_contact <= h_sheet"]),
        ({"case": "a/b"}, ["case = 'a/b'"]),
        ({"optics": {"read_noise_e": 5}}, ["full_well_e"]),
    ],
)
def test_bad_config_names_key_value_and_allowed(given, words):
    with pytest.raises(ConfigError) as err:
        effective_config(given)
    for w in words:
        assert w in str(err.value)


def _sym(indenters, **mesh):
    # full stick: shear needs friction (a config error before any work otherwise)
    given = {"indenter": indenters, "mesh": mesh, "contact": {"friction": "stick"}}
    return choose_symmetry(effective_config(given))


def test_symmetry_choice_follows_positions_and_loads():
    assert _sym([{}]) == "quarter"
    assert _sym([{"load_N": [8.0], "shear_N": [4.0, 0.0]}], **{}) == "half"
    assert _sym([{"load_N": [8.0], "shear_N": [0.0, 4.0]}]) == "full"
    pair = [{"x_mm": -5.0, "load_N": [2.0]}, {"x_mm": 5.0, "load_N": [2.0]}]
    assert _sym(pair) == "quarter"
    pair[1]["load_N"] = [3.0]
    assert _sym(pair) == "half"  # still mirror-symmetric about y = 0 only
    assert _sym([{"x_mm": 3.0, "y_mm": 2.0}]) == "full"
    with pytest.raises(ConfigError, match="mesh.symmetry = 'quarter' is not allowed"):
        _sym([{"load_N": [8.0], "shear_N": [4.0, 0.0]}], symmetry="quarter")
    # the model keeps y >= 0 (and x >= 0): only the indenter at y = +5 mm is solved
    cfg = effective_config({"indenter": [{"y_mm": 5.0}, {"y_mm": -5.0}]})
    inp = build_inputs(cfg)
    spec, inds = inp.spec, inp.indenters
    assert spec.symmetry == "quarter" and [i.y for i in inds] == [5e-3]


def test_geometry_errors_are_config_errors():
    with pytest.raises(ConfigError, match="reaches off the 40 x 40 mm sheet"):
        build_inputs(effective_config({"indenter": [{"x_mm": 19.0}]}))


def test_config_show_and_user_errors(tmp_path, capsys):
    assert main(["config", "show", "shear", "--set", "optics.pixels=64"]) == 0
    out = capsys.readouterr().out
    assert 'friction = "stick"' in out and "pixels = 64" in out and "[mm]" in out
    assert main(["predict", str(tmp_path / "missing.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "neither a file nor a built-in case" in err and "Traceback" not in err
    assert len(err.splitlines()) == 1
    bad = tmp_path / "bad.toml"
    bad.write_text("[sheet]\nE_MPa = 0\n")
    assert main(["predict", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "sheet.E_MPa = 0" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing written for a config that fails its checks
    assert main(["config", "show", "--set", "sheet.bogus=1"]) == 2
    assert "unknown key sheet.bogus" in capsys.readouterr().err


def tiny_predict(root, cache_dir) -> tuple:
    """The tiny config written into ``root``: (its path, the output folder, quiet
    ``predict`` arguments through the shared cache)."""
    cfg = root / "tiny.toml"
    cfg.write_text(TINY)
    out = root / "out"
    return (
        cfg,
        out,
        ["predict", str(cfg), "--out", str(out), "--cache-dir", str(cache_dir), "--quiet"],
    )


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, cache_dir):
    root = tmp_path_factory.mktemp("predict")
    _, out, args = tiny_predict(root, cache_dir)
    assert main(args) == 0
    return root, out, args


def test_predict_end_to_end(tiny_run):
    import imageio.v3 as iio
    import pyvista as pv

    _, out, _ = tiny_run
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "ok" and s["model"]["symmetry"] == "quarter"
    (ind,) = s["indenters"]
    assert ind["force_N"][2] == pytest.approx(-8.0, rel=1e-6)
    assert 0.5 < ind["depth_mm"] < 0.9 and 0.9 < ind["contact_radius_mm"] < 1.5
    assert set(s["times_s"]) >= {"mesh_s", "solve_s", "total_s"}
    assert s["versions"]["fringekit"] and s["config"]["case"] == "tiny"
    # numbers read as numbers: six significant digits, one DOF figure, one unit system,
    # only the parameters the run used (issue 20)
    assert ind["force_N"][2] == -8.0
    floats = re.findall(r"-?\d+\.\d+(?:e-?\d+)?", (out / "summary.json").read_text())
    assert max(len(re.sub(r"e.*|[-.]", "", f).lstrip("0")) for f in floats) <= 6
    assert "n_dofs" not in s["model"]["mesh_quality"] and s["model"]["dofs"] > 0
    assert "min_volume_mm3" in s["model"]["mesh_quality"]
    assert "C10_MPa" not in s["config"]["sheet"] and "nu" in s["config"]["sheet"]
    assert "substrate_f_sigma_N_per_m" not in s["config"]["optics"]
    d = out / "state_01"
    maps = np.load(d / "maps.npz")
    order = maps["fringe_order"]
    assert order.shape == (32, 32)
    amb = maps["branch_ambiguous"]  # pixels whose branch the simple order cannot choose
    assert amb.dtype == bool and not amb[np.isnan(order)].any() and amb.mean() < 0.05
    assert s["max_fringe_order"] == pytest.approx(np.nanmax(order), rel=1e-5)  # 6 digits
    # 8 N on this sheet gives ~3.5 fringes at the contact edge (bench/optics.py: 3.67)
    assert 2.5 < s["max_fringe_order"] < 5.0
    ok = maps["mask"]
    assert 0.8 < ok.mean() < 1.0 and np.all(np.isnan(order[~ok]))
    # the characteristic order follows the rotation-free integral closely, except in the
    # ring of steep pixels at the contact edge where the axes turn along the ray (up to
    # 0.11 seen there; the 99th percentile 0.02-0.06 depending on the mesh)
    gap = np.abs(order - maps["simple_order"])
    assert np.nanmedian(gap) < 0.01 and np.nanmax(gap) < 0.25
    # the pattern is centred: the map is symmetric under x -> -x to interpolation accuracy
    assert np.nanmax(np.abs(order - order[:, ::-1])) < 0.05
    for k in range(1, 7):
        img = iio.imread(d / "six_step" / f"step{k}.png")
        assert img.shape == (32, 32) and img.dtype == np.uint8
    rgb = iio.imread(d / "white_light.png")
    assert rgb.shape == (32, 32, 3) and rgb.dtype == np.uint8
    for f in ("fringe_order.png", "isoclinic.png", "fringe_image.png", "profile.png"):
        assert (d / f).stat().st_size > 1000
    prof = np.loadtxt(d / "profile.csv", delimiter=",", skiprows=1)
    assert prof.shape == (32, 2) and np.isnan(prof[16, 1])  # the contact zone is masked
    grid = pv.read(d / "solution.vtu")
    assert "cauchy_stress_Pa" in grid.point_data and grid.n_cells > 0
    assert used_config(load_config(out / "config.toml")) == s["config"]


def test_predict_rerender_uses_the_cached_solution(tiny_run, capsys):
    """A re-render with other optics takes the cached states, and says so where a solve
    would print its time estimate."""
    import imageio.v3 as iio

    root, out, args = tiny_run
    out2 = root / "out2"
    args2 = [a if a != str(out) else str(out2) for a in args if a != "--quiet"]
    capsys.readouterr()
    assert main(args2 + ["--set", "optics.qwp_error_deg=10"]) == 0
    cap = capsys.readouterr()
    said = cap.out + cap.err
    assert "in the solution cache" in said and "to solve on 2 cores" not in said, said
    s = json.loads((out2 / "summary.json").read_text())
    assert s["model"]["solution_from_cache"] is True
    # the tiny block's 1 mm facets cannot resolve the contact's edge: the radius given is
    # the contact area's, flagged, with no sd
    assert s["indenters"][0]["contact_radius_sd_mm"] is None
    assert f"mm {UNRESOLVED_EDGE}" in cap.out and "+-" not in cap.out, cap.out
    a, b = (np.load(o / "state_01" / "maps.npz")["fringe_order"] for o in (out, out2))
    np.testing.assert_array_equal(a, b)  # same solution, same optics integral
    i1, i2 = (iio.imread(o / "state_01" / "six_step" / "step3.png") for o in (out, out2))
    assert np.abs(i1.astype(int) - i2.astype(int)).max() > 5  # the plate error shows


def _predict_failing(toml: str, tmp_path, cache_dir, capsys) -> tuple[Path, str, dict]:
    """Run ``predict`` on a config that must fail, with ``--out`` given relative to the
    working directory: exit 1 and no traceback, the states written to that folder and no
    mention of an earlier run (there is none). Returns the output folder, stderr and the
    summary."""
    cfg = tmp_path / "fail.toml"
    cfg.write_text(toml)
    out = tmp_path / "out"
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp_path)
        code = main(["predict", str(cfg), "--out", "out", "--cache-dir", str(cache_dir), "--quiet"])
    assert code == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert f"written to {out}" in err and "earlier run" not in err
    return out, err, json.loads((out / "summary.json").read_text())


def test_predict_failure_keeps_converged_states(tmp_path, cache_dir, capsys):
    out, err, s = _predict_failing(
        TINY.replace("load_N = [8.0]", "load_N = [1.0, 400.0]")
        + "[solver]\nmax_iterations = 20\nmax_cutbacks = 2\n",
        tmp_path,
        cache_dir,
        capsys,
    )
    assert "could not reach load state 2" in err
    assert s["status"] == "failed" and len(s["states"]) == 1
    assert s["indenters"][0]["force_N"][2] == pytest.approx(-1.0, rel=1e-9)
    assert (out / "state_01" / "solution.vtu").exists()
    assert Path(out / "config.toml").exists()


def test_predict_failure_at_the_first_state_is_reported_not_a_crash(tmp_path, cache_dir, capsys):
    """No converged state at all: exit 1 with the solver's message and a summary saying so
    (this used to index the empty list of states and raise IndexError)."""
    _, err, s = _predict_failing(
        TINY + "[solver]\nmax_iterations = 2\nmax_cutbacks = 0\n", tmp_path, cache_dir, capsys
    )
    assert "could not reach load state 1" in err
    assert s["status"] == "failed" and s["states"] == [] and s["rendered"] == []
    assert s["max_fringe_order"] is None


@pytest.fixture(scope="module")
def tiny_images(tiny_run):
    """The tiny solution rendered at 96 x 96 pixels (0.104 mm/px) from the solve cache."""
    root, out, args = tiny_run
    out96 = root / "out96"
    args96 = [a if a != str(out) else str(out96) for a in args]
    assert main(args96 + ["--set", "optics.pixels=96"]) == 0
    d = out96 / "state_01"
    maps = np.load(d / "maps.npz")
    s = json.loads((out96 / "summary.json").read_text())
    ((r, c),) = maps["indenter_rc"]
    rad = s["indenters"][0]["contact_radius_mm"] * 1e-3 / float(maps["pixel_size_m"]) + 1.5
    border = np.concatenate([maps["fringe_order"][:3].ravel(), maps["fringe_order"][-3:].ravel()])
    geo = ["--exclude-circle", str(r), str(c), str(rad)]
    geo += ["--pixel-mm", str(float(maps["pixel_size_m"]) * 1e3)]
    return root, out96, d, geo, float(np.nanmedian(border))


def test_analyze_phase_and_compare_recover_the_prediction(tiny_images):
    root, out96, d, geo, border = tiny_images
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    an = root / "an_phase"
    code = main(
        [
            "analyze",
            *steps,
            "--out",
            str(an),
            "--anchor-order",
            str(border),
            *geo,
            "--f-sigma-N-per-m",
            "386",
            "--thickness-mm",
            "3",
            "--quiet",
        ]
    )
    assert code == 0
    s = json.loads((an / "summary.json").read_text())
    assert s["method"] == "phase" and s["phase"]["fold"] == "count"
    assert s["phase"]["info"]["ordered_bands"] == s["phase"]["info"]["bands"]
    assert s["phase"]["fold_disagreement_fraction"] < 0.01 and "warning" not in s
    m = np.load(an / "maps.npz")
    for k in ("isoclinic_rad", "delta_eq3_rad", "modulation", "stress_difference_Pa"):
        assert m[k].shape == (96, 96)
    np.testing.assert_allclose(
        m["stress_difference_Pa"], m["fringe_order"] * 386 / 6e-3, rtol=1e-12
    )  # seed eq. 4 in reflection
    for f in ("fringe_order.png", "phasemap_eq3.png", "isoclinic.png", "profile.png"):
        assert (an / f).stat().st_size > 1000
    cmp = root / "cmp_phase"
    assert main(["compare", str(out96), str(an), "--out", str(cmp), "--quiet"]) == 0
    c = json.loads((cmp / "summary.json").read_text())
    # 8-bit images of the exact Jones model: the six-step order matches the prediction
    assert c["rms_fringe"] < 0.02 and c["pixels"] > 0.5 * 96 * 96  # 0.003-0.006 seen
    assert (cmp / "comparison.png").stat().st_size > 1000


def test_analyze_rgb_refined_from_a_far_field_seed(tiny_images):
    root, out96, d, geo, border = tiny_images
    an = root / "an_rgb"
    seed = ["--seed", "0", "0", str(border)]
    assert (
        main(["analyze", str(d / "white_light.png"), "--out", str(an), *geo, *seed, "--quiet"]) == 0
    )
    s = json.loads((an / "summary.json").read_text())
    assert s["method"] == "rgb" and s["rgb"]["refined"]
    cmp = root / "cmp_rgb"
    assert main(["compare", str(out96), str(an), "--out", str(cmp), "--quiet"]) == 0
    c = json.loads((cmp / "summary.json").read_text())
    assert c["rms_fringe"] < 0.05  # 0.011 seen here and at 256 px on the reference case


def test_analyze_and_compare_bad_input(tiny_images, capsys):
    root, _, d, geo, _ = tiny_images
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 6)]
    assert main(["analyze", *steps, "--method", "phase", "--out", str(root / "x")]) == 2
    assert "exactly 6 images" in capsys.readouterr().err
    grey = str(d / "six_step" / "step1.png")
    assert main(["analyze", grey, "--method", "rgb", "--out", str(root / "y")]) == 2
    assert "needs colour" in capsys.readouterr().err
    assert main(["compare", str(root / "nowhere"), str(root / "nowhere")]) == 2
    assert "no maps.npz" in capsys.readouterr().err


@pytest.mark.slow
def test_calibrate_and_estimate_end_to_end(tiny_images, cache_dir, capsys):
    """One continuation run 2..8 N calibrates; the 8 N prediction and its six-step
    analysis give 8 N back."""
    root, out96, d, geo, border = tiny_images
    cfg = root / "cal.toml"
    cfg.write_text(
        TINY.replace("load_N = [8.0]", "load_N = [2.0, 4.0, 6.0, 8.0]").replace(
            "pixels = 32", "pixels = 64"
        )
    )
    cal_dir = root / "cal"
    args = ["calibrate", str(cfg), "--out", str(cal_dir), "--cache-dir", str(cache_dir)]
    assert main([*args, "--quiet"]) == 0
    cal = json.loads((cal_dir / "calibration.json").read_text())
    assert cal["loads_N"] == pytest.approx([2, 4, 6, 8], rel=1e-6)
    fit = cal["normal_fits"]["order_at_3mm"]
    assert 0.8 < fit["b"] < 1.6 and fit["sigma_logF"] < 0.05
    assert (cal_dir / "calibration.png").stat().st_size > 1000
    feats = np.loadtxt(cal_dir / "features.csv", delimiter=",", skiprows=1)
    assert feats.shape[0] == 4
    text = (cal_dir / "features.csv").read_text()
    header = text.splitlines()[0].split(",")
    assert "radius_mm_fringe_1" in header and "integrated_order_fringe_mm2" in header
    assert max(len(v) for v in re.split(r"[,\n]", text.split("\n", 1)[1])) <= 12  # 6 digits
    calf = str(cal_dir / "calibration.json")
    assert main(["estimate", str(out96), "--calibration", calf]) == 0
    line = capsys.readouterr().out
    est = float(line.split("normal load")[1].split("N")[0])
    assert est == pytest.approx(8.0, rel=0.03)
    an = root / "an_est"
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    assert (
        main(["analyze", *steps, "--out", str(an), "--anchor-order", str(border), *geo, "--quiet"])
        == 0
    )
    centre = geo[1:3]
    assert (
        main(
            [
                "estimate",
                str(an),
                "--calibration",
                calf,
                "--centre",
                *centre,
                "--out",
                str(root / "est"),
            ]
        )
        == 0
    )
    got = json.loads((root / "est" / "estimate.json").read_text())
    assert got["normal_N"] == pytest.approx(8.0, rel=0.03)
    capsys.readouterr()
    assert main(["calibrate", str(root / "tiny.toml"), "--out", str(root / "c1")]) == 2
    assert "at least 3 different loads" in capsys.readouterr().err
    assert main(["estimate", str(an), "--calibration", str(root / "none.json")]) == 2


@pytest.mark.slow
def test_a_small_sweep_tabulates_its_cases_and_skips_finished_ones(tmp_path, cache_dir):
    """The fast tier's sweep: two loads of the tiny case in this process (no cluster), one
    row each in results.csv, more fringes under more load, and a re-run that runs nothing."""
    import csv

    from fringekit.sweep.run import load_sweep, run_sweep

    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(
        'base = "tiny.toml"\n[set]\n"mesh.h_contact_mm" = 1.0\n"optics.pixels" = 16\n'
        '"optics.samples_per_ray" = 8\n"optics.white_light_wavelengths" = 4\n'
        '[grid]\n"indenter.load_N" = [[2.0], [4.0]]\n'
    )
    sweep = load_sweep(tmp_path / "sweep.toml")
    out = tmp_path / "sweep"
    first = run_sweep(sweep, out, workers=0, cache_dir=cache_dir, progress=False)
    assert (first["cases"], first["run"], first["failed"]) == (2, 2, 0)
    with (out / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["indenter.load_N"] for r in rows] == ["[2.0]", "[4.0]"]
    assert {r["status"] for r in rows} == {"ok"}
    assert float(rows[1]["max_fringe_order"]) > float(rows[0]["max_fringe_order"])
    again = run_sweep(sweep, out, workers=0, cache_dir=cache_dir, progress=False)
    assert (again["run"], again["skipped"]) == (0, 2)


@pytest.mark.slow
def test_sweep_killed_then_resumed_matches_an_uninterrupted_run(tiny_run, cache_dir, capsys):
    import csv
    import os
    import signal
    import subprocess
    import sys
    import time

    root, _, _ = tiny_run
    (root / "sweep.toml").write_text(
        'base = "tiny.toml"\nname = "s"\n[set]\n"optics.samples_per_ray" = 16\n'
        '"optics.white_light_wavelengths" = 5\n[grid]\n'
        '"indenter.load_N" = [[4.0], [8.0]]\n"optics.wavelength_nm" = [575.0, 600.0]\n'
    )
    out = root / "sweep_a"
    cmd = [
        sys.executable,
        "-m",
        "fringekit",
        "sweep",
        str(root / "sweep.toml"),
        "--out",
        str(out),
        "--workers",
        "1",
        "--cache-dir",
        str(cache_dir),
        "--quiet",
    ]
    proc = subprocess.Popen(
        cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    t0 = time.time()
    try:
        while not list((out / "cases").glob("*/result.json")):
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.time() - t0 < 300, "no case finished within 300 s"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finished = [
        p
        for p in (out / "cases").iterdir()
        if not p.name.endswith(".part") and not p.name.startswith(".")
    ]  # a killed case's run folder and lock
    assert 1 <= len(finished) < 4
    for p in finished:  # a finished case is whole: its summary and result are readable
        assert json.loads((p / "result.json").read_text())["status"] == "ok"
        assert json.loads((p / "summary.json").read_text())["status"] == "ok"
    n_done = len(finished)
    base = ["sweep", str(root / "sweep.toml"), "--workers", "1", "--cache-dir", str(cache_dir)]
    assert main([*base, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert f"{4 - n_done} run, {n_done} already finished, 0 failed" in said
    quiet = subprocess.run(
        [sys.executable, "-m", "fringekit", *base, "--out", str(root / "sweep_b"), "--quiet"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert quiet.returncode == 0, quiet.stderr[-2000:]
    assert "distributed." not in quiet.stderr, quiet.stderr[:500]  # no cluster chatter

    def table(folder):
        with (folder / "results.csv").open() as fh:
            rows = list(csv.DictReader(fh))
        return [{k: v for k, v in r.items() if k != "time_s"} for r in rows]

    a, b = table(out), table(root / "sweep_b")
    assert len(a) == 4 and a == b
    assert {r["status"] for r in a} == {"ok"}
    f4 = [float(r["max_fringe_order"]) for r in a if r["indenter.load_N"] == "[4.0]"]
    f8 = [float(r["max_fringe_order"]) for r in a if r["indenter.load_N"] == "[8.0]"]
    assert min(f8) > max(f4)  # more load, more fringes
    assert (out / "plots").is_dir() and list((out / "plots").glob("*.png"))
    (root / "bad_sweep.toml").write_text('[grid]\n"sheet.E_MPa" = [-1.0]\n')
    assert main(["sweep", str(root / "bad_sweep.toml")]) == 2
    assert "sheet.E_MPa = -1.0" in capsys.readouterr().err


def _mesh_args(cache_dir, out):
    return [
        "mesh",
        "--width-mm",
        "12",
        "--substrate-mm",
        "4",
        "--h-contact-mm",
        "0.6",
        "--refine-radius-mm",
        "1.5",
        "--h-sheet-mm",
        "1.5",
        "--h-far-mm",
        "3",
        "--cache-dir",
        str(cache_dir),
        "--out",
        str(out),
    ]


def test_mesh_command(tmp_path, cache_dir, capsys):
    assert main(_mesh_args(cache_dir, tmp_path / "m")) == 0
    s = json.loads((tmp_path / "m" / "mesh_summary.json").read_text())
    assert s["quality"]["n_cells"] > 0 and (tmp_path / "m" / "mesh.vtu").stat().st_size > 0
    assert main(["mesh", "--thickness-mm", "-1", "--out", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err
    assert "--thickness-mm: -1 is not allowed" in err and "sheet.thickness_mm" in err


def test_mesh_command_on_a_rigid_base(tmp_path, cache_dir):
    """No substrate (substrate.thickness_mm = 0, as predict accepts): no interface facets,
    written to VTU and read back (it failed with "Array 'facets:interface' cannot have
    shape (0, 2)" before 31a8631)."""
    out = tmp_path / "m"
    args = _mesh_args(cache_dir, out)
    args[args.index("--substrate-mm") + 1] = "0"
    assert main(args) == 0
    s = json.loads((out / "mesh_summary.json").read_text())
    assert (
        s["facet_sets"]["interface"] == 0
        and s["mesh_spec_SI"]["layers"]["substrate_thickness"] == 0
    )
    back = read_vtu(out / "mesh.vtu")
    assert back.n_cells == s["quality"]["n_cells"] and len(back.facets["interface"]) == 0
    assert set(back.facets) == set(s["facet_sets"])


def test_predict_with_the_polycarbonate_in_the_light_path(tiny_run, capsys):
    root, out, args = tiny_run
    out_pc = root / "out_pc"
    args_pc = [a if a != str(out) else str(out_pc) for a in args]
    assert main(args_pc + ["--set", "optics.include_substrate=true"]) == 0
    a = np.load(out / "state_01" / "maps.npz")
    b = np.load(out_pc / "state_01" / "maps.npz")
    extra = b["simple_order"] - a["simple_order"]
    ok = np.isfinite(extra)
    # the stiff PC carries little stress difference and has an 18x larger fringe value:
    # it adds a small positive order, largest near the indenter
    assert ok.mean() > 0.8 and np.all(extra[ok] >= 0) and 0.005 < np.nanmax(extra) < 0.5
    # the characteristic order moves with it, except at steep contact-edge pixels where
    # the turning axes make it nonlinear in the path (up to 0.17 seen there)
    moved = np.abs((b["fringe_order"] - a["fringe_order"]) - extra)
    assert np.nanmedian(moved) < 0.005 and np.nanmax(moved) < 0.3
    bad = ["predict", "--set", "substrate.thickness_mm=0", "--set", "optics.include_substrate=true"]
    assert main([*bad, "--out", str(root / "x")]) == 2
    assert "needs a substrate" in capsys.readouterr().err


def test_pixels_without_data_look_the_same_everywhere(tiny_images, tmp_path):
    """The contact zone (and anything masked) is NaN in every map, the documented
    no-data grey (half of full scale, every channel) in every image, with mask.png
    beside them, and the "no data" grey in every figure (issue 20)."""
    import imageio.v3 as iio

    from fringekit.output.figures import NO_DATA_RGB, map_figure

    root, out96, d, geo, border = tiny_images
    mask = iio.imread(d / "mask.png") > 127
    assert 0 < (~mask).sum() < mask.size  # the contact zone
    maps = np.load(d / "maps.npz")
    for name in ("fringe_order", "isoclinic_rad"):
        assert np.array_equal(np.isnan(maps[name]), ~mask), name
    for img in [d / "white_light.png", *sorted((d / "six_step").glob("step*.png"))]:
        px = iio.imread(img)
        assert np.all(px[~mask] == 128), img.name
        assert not np.all(px[mask] == 128)
    # figures: a map with NaN shows the no-data grey and says so
    data = np.where(mask, 1.0, np.nan)
    map_figure(tmp_path / "m.png", data, "t", "fringe order")
    fig = iio.imread(tmp_path / "m.png")[..., :3]
    grey = np.round(np.array(NO_DATA_RGB) * 255)
    assert (np.abs(fig.astype(float) - grey).max(axis=-1) <= 1).sum() > 50
    # analyze: the isoclinic of masked or unreliable pixels is NaN, not 0 deg
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    an = tmp_path / "an"
    assert main(["analyze", *steps, "--out", str(an), *geo, "--quiet"]) == 0
    got = np.load(an / "maps.npz")
    assert np.array_equal(np.isnan(got["isoclinic_rad"]), np.isnan(got["delta_eq3_rad"]))


def test_every_figure_and_table_uses_the_sensor_frame(tiny_images, tmp_path):
    """x right, y up, mm, origin at the sensor origin: predict's and analyze's maps, the
    comparison figure and analyze's profile.csv (issue 20)."""
    from fringekit.analysis import compare_maps
    from fringekit.output.figures import comparison_figure, map_figure, sensor_extent

    # the pixel of the origin has its centre at (0, 0); rows grow downwards, y upwards
    left, right, bottom, top = sensor_extent((10, 20), 1e-4, (4.0, 8.0))
    assert left + 8.5 * 0.1 == pytest.approx(0) and top - 4.5 * 0.1 == pytest.approx(0)
    assert top > bottom and right > left and right - left == pytest.approx(2.0)
    ext = (left, right, bottom, top)
    fig = map_figure(
        tmp_path / "m.png",
        np.ones((10, 20)),
        "t",
        "l",
        extent=ext,
        axis_labels=("x (mm)", "y (mm)"),
    )
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (mm)", "y (mm)")
    assert ax.get_ylim()[1] > ax.get_ylim()[0]  # y up
    # analyze: profile.csv in the sensor frame about --origin-px (default the image centre)
    root, out96, d, geo, border = tiny_images
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    an = tmp_path / "an"
    assert (
        main(
            [
                "analyze",
                *steps,
                "--out",
                str(an),
                *geo,
                "--origin-px",
                "40",
                "50",
                "--line",
                "30",
                "0",
                "30",
                "95",
                "--quiet",
            ]
        )
        == 0
    )
    head = (an / "profile.csv").read_text().splitlines()[0]
    assert head == "distance_mm,x_mm,y_mm,fringe_order"
    prof = np.loadtxt(an / "profile.csv", delimiter=",", skiprows=1)
    px_mm = float(geo[-1])
    np.testing.assert_allclose(prof[:, 2], (40 - 30) * px_mm, rtol=1e-5)  # y up from row 40
    np.testing.assert_allclose(prof[[0, -1], 1], [-50 * px_mm, 45 * px_mm], rtol=1e-5)
    # compare: the maps in mm about the sensor origin, labelled
    maps = np.load(d / "maps.npz")
    order = maps["fringe_order"]
    comp = compare_maps(
        order,
        order,
        predicted_pixel_size=float(maps["pixel_size_m"]),
        measured_pixel_size=float(maps["pixel_size_m"]),
        centre_predicted=tuple(maps["indenter_rc"][0]),
    )
    fig = comparison_figure(comp, tmp_path / "c.png", pixel_size=float(maps["pixel_size_m"]))
    maps_axes = [
        a for a in fig.axes if a.get_title().startswith(("measured", "predicted", "resid"))
    ]
    assert len(maps_axes) == 3
    assert all((a.get_xlabel(), a.get_ylabel()) == ("x (mm)", "y (mm)") for a in maps_axes)


def test_analyze_phase_anchored_at_a_point_of_known_order(tiny_images, tmp_path, capsys):
    """A region of interest that leaves the image border out: the default anchor (the
    border ring) has no pixel, and the error names the option that helps (it named the
    Python argument anchor_mask); --order-at ROW COL N anchors the map instead."""
    root, out96, d, geo, border = tiny_images
    maps = np.load(d / "maps.npz")
    order = maps["fringe_order"]
    (rc, cc) = maps["indenter_rc"][0]
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    roi = ["--roi-circle", str(rc), str(cc), "40"]
    an = tmp_path / "an"
    assert main(["analyze", *steps, *roi, *geo, "--out", str(an), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--order-at ROW COL N" in err and "anchor_mask" not in err
    assert not an.exists()
    r, c = int(round(rc)), int(round(cc + 37))  # the far field inside the region
    known = ["--order-at", str(r), str(c), f"{order[r, c]:.4f}"]
    assert main(["analyze", *steps, *roi, *geo, *known, "--out", str(an), "--quiet"]) == 0
    got = np.load(an / "maps.npz")
    ok = got["reliable"] & np.isfinite(order)
    assert ok.sum() > 500
    assert np.median(np.abs(got["fringe_order"][ok] - order[ok])) < 0.02
    bad = ["--order-at", "0", "0", "1.0"]  # outside the region of interest
    assert main(["analyze", *steps, *roi, *geo, *bad, "--out", str(tmp_path / "x")]) == 2
    assert "--order-at 0 0 1" in capsys.readouterr().err


def test_analyze_warns_when_most_of_the_map_is_a_guess(tiny_images, tmp_path, capsys):
    """A monochrome photo analysed as RGB (grey fringes hold no colour): less than half
    of the region is reliable, so analyze says so on stderr and in summary.json, and
    --strict exits 1 (it exited 0 with a map)."""
    import imageio.v3 as iio

    root, out96, d, geo, border = tiny_images
    grey = iio.imread(d / "six_step" / "step1.png")
    iio.imwrite(tmp_path / "grey.png", np.stack([grey] * 3, axis=-1))
    args = ["analyze", str(tmp_path / "grey.png"), "--method", "rgb", *geo]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "warning: only" in err and "reliable" in err
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["reliable_fraction_of_roi"] < 0.5 and "warning" in s
    assert main([*args, "--out", str(tmp_path / "b"), "--strict"]) == 1
    # the rendered white-light image passes
    ok = [
        "analyze",
        str(d / "white_light.png"),
        "--method",
        "rgb",
        *geo,
        "--strict",
        "--seed",
        "0",
        "0",
        f"{border:.3f}",
        "--out",
        str(tmp_path / "c"),
    ]
    assert main(ok) == 0


def test_analyze_rectangle_polygon_and_line_masks(tiny_images, tmp_path, capsys):
    """--roi-rect and --roi-polygon set the region, --exclude-polygon takes out polygons
    and (two vertices) a crack 3 px wide; the default profile runs across the region;
    a region with no pixel left, or a two-vertex region, is refused by option name."""
    root, out96, d, geo, border = tiny_images
    steps = [str(d / "six_step" / f"step{k}.png") for k in range(1, 7)]
    an = tmp_path / "an"
    args = [
        "analyze",
        *steps,
        *geo,
        "--roi-rect",
        "3",
        "3",
        "92",
        "92",
        "--exclude-polygon",
        "60,60",
        "60,80",
        "80,70",
        "--exclude-polygon",
        "10,10",
        "10,80",
        "--out",
        str(an),
        "--quiet",
    ]
    assert main(args) == 0
    s = json.loads((an / "summary.json").read_text())
    order = np.load(an / "maps.npz")["fringe_order"]
    assert np.isnan(order[:3]).all() and np.isnan(order[:, 93:]).all()  # outside the rect
    assert np.isnan(order[65, 70]) and np.isnan(order[10, 40])  # polygon and crack
    assert np.isfinite(order[14, 40]) or np.isfinite(order[16, 40])  # beside the crack
    assert s["line_px"][1] >= 3 and s["line_px"][3] <= 92  # across the region
    bad = ["analyze", *steps, "--roi-polygon", "1,1", "5,5", "--out", str(tmp_path / "b")]
    assert main(bad) == 2 and "--roi-polygon has 2 vertices" in capsys.readouterr().err
    empty = [
        "analyze",
        *steps,
        "--roi-rect",
        "5",
        "5",
        "20",
        "20",
        "--exclude-polygon",
        "0,0",
        "0,30",
        "30,30",
        "30,0",
        "--out",
        str(tmp_path / "e"),
    ]
    assert main(empty) == 2 and "holds no pixel" in capsys.readouterr().err
    assert main(["analyze", *steps, "--roi-polygon", "1;1", "--out", str(tmp_path / "x")]) == 2
    assert "--roi-polygon" in capsys.readouterr().err


def test_analyze_mono_reads_predicts_dark_field_image(tiny_images, tmp_path):
    """predict writes dark_field.png (monochrome, dark-field circular); analyze --method
    mono orders it back to the predicted map."""
    root, out96, d, geo, border = tiny_images
    an = tmp_path / "mono"
    args = [
        "analyze",
        str(d / "dark_field.png"),
        *geo,
        "--anchor-order",
        f"{border:.3f}",
        "--out",
        str(an),
        "--quiet",
    ]
    assert main(args) == 0
    got = np.load(an / "maps.npz")
    truth = np.load(d / "maps.npz")["fringe_order"]
    ok = got["reliable"] & np.isfinite(truth)
    assert ok.sum() > 0.8 * np.isfinite(got["fringe_order"]).sum()
    err = np.abs(got["fringe_order"] - truth)[ok]
    assert np.percentile(err, 95) < 0.1, np.percentile(err, 95)
