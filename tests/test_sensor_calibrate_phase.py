"""fringekit sensor calibrate --method phase: six-step frames rendered by a sensor that
departs from its library as test_sensor_calibrate's does (modulus +15 %, fringe value
-8 %, gamma 2.2, a black level, 30 % vignetting, the image turned 2 degrees, 1 % off in
pitch and 0.6 mm off in origin) and whose sheet holds a residual retarder of up to
0.2 fringe (turning axis) are calibrated back, the residual retarder with them; invert,
track and predict --library use it; the bad inputs are one line each."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from test_sensor_calibrate import (
    KNOWN,
    PIXEL_MM,
    PX,
    TEST,
    check_fitted,
    contact_errors,
    predict_with_sensor,
    sensor_truth,
    write_known_and_test,
)

import fringekit
from fringekit.analysis import read_pixels
from fringekit.cli.main import main
from fringekit.config.inputs import optics_setup
from fringekit.inversion.rest import residual_fringes
from fringekit.library.calibrated import CalibratedSensor, coarse_map, load_sensor
from fringekit.library.store import load_library
from fringekit.optics import write_image
from fringekit.sensor import sensor_frame

#: The residual retarder's peak (fringes, the double pass).
RESIDUAL = 0.2
#: The exposure: the six steps' brightest (1 + cos d) / 2 of full light stays below full
#: scale after the vignetting and the response.
GAIN = 0.45


def _truth(lib) -> CalibratedSensor:
    """test_sensor_calibrate's sensor (scales, response, light, geometry) read by the six
    steps, its sheet holding a residual retarder of RESIDUAL fringe at its peak (an
    off-centre bump, its axis turning across the field) instead of a rest light."""
    dark = sensor_truth(lib)
    rr, cc = np.mgrid[0:PX, 0:PX]
    u, v = (cc - 31.5) / 32, (rr - 31.5) / 32
    law = dark.optics(optics_setup(dark.config)).law
    k = float(law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0])
    d = RESIDUAL * 2 * np.pi * np.exp(-((u - 0.3) ** 2 + (v + 0.2) ** 2) / 0.15)
    axis = 0.6 + 0.5 * u  # twice the residual's principal direction (rad)
    ab = np.stack([d * np.cos(axis), d * np.sin(axis)], -1) / (2 * k)
    return replace(dark, method="phase", rest=None, residual=coarse_map(ab))


def _six(folder, name: str, lib, truth, contacts) -> list:
    """The six steps of ``contacts`` as 16-bit files; their paths."""
    steps = sensor_frame(lib, truth, contacts, gain=GAIN, bit_depth=16)
    paths = [folder / f"{name}_{k + 1}.png" for k in range(6)]
    for k, p in enumerate(paths):
        write_image(p, steps[..., k])
    return paths


@pytest.fixture(scope="module")
def lib(tiny_library):
    """The tiny library as it is on disk (its manifest's checksum is the sensor's)."""
    return load_library(tiny_library.folder)


@pytest.fixture(scope="module")
def calibrated(lib, tmp_path_factory):
    """The frames, and the sensor file ``sensor calibrate --method phase`` wrote."""
    d = tmp_path_factory.mktemp("phase-sensor")
    truth = _truth(lib)
    rest = _six(d, "rest", lib, truth, [])
    rows = ["image,x_mm,y_mm,Fx_N,Fy_N,Fz_N"]
    for i, c in enumerate(KNOWN):
        names = ";".join(p.name for p in _six(d, f"known{i}", lib, truth, [c]))
        rows.append(f"{names}," + ",".join(f"{x:g}" for x in c))
    (d / "known.csv").write_text("\n".join(rows) + "\n")
    _six(d, "test", lib, truth, TEST)
    argv = ["sensor", "calibrate", "--library", str(lib.folder), "--quiet", "--method", "phase"]
    argv += ["--reference", *map(str, rest), "--known", str(d / "known.csv")]
    assert main([*argv, "--out", str(d / "sensor.json"), "--pixel-mm", str(PIXEL_MM)]) == 0
    return d, truth, load_sensor(d / "sensor.json")


@pytest.mark.slow
def test_phase_calibration_returns_the_sensor_and_its_residual_retarder(calibrated):
    """Scales to 1e-3, the response, pitch, origin, rotation and black level, each error
    within 3 of its stated 1-sigma (``check_fitted``); the illumination within 1 %; the
    residual retarder within 0.002 fringe everywhere (16-bit frames of the library's own
    model)."""
    d, truth, got = calibrated
    assert (d / "sensor.png").is_file() and got.method == "phase" and got.rest is None
    check_fitted(got, truth)
    assert np.abs(got.illumination - truth.illumination).max() < 0.01
    law = got.optics(optics_setup(got.config)).law
    peak = residual_fringes(truth.residual.reshape(-1, 2), law).max()
    off = residual_fringes((got.residual - truth.residual).reshape(-1, 2), law).max()
    assert peak > 0.9 * RESIDUAL and off < 0.002, (peak, off)
    assert got.report["warnings"] == [] and got.report["residual_max_fringe"] > 0.9 * RESIDUAL


@pytest.mark.slow
def test_invert_and_track_read_phase_frames_through_the_sensor_file(calibrated, lib):
    """Two contacts in the residual, turned and scaled by the sensor: within 0.02 mm and
    1 % of Fz through the sensor file (its residual retarder in the model), by invert and
    by track; read with the nominal pitch and no residual they are refused or off."""
    d, _, _ = calibrated
    sensor, want = d / "sensor.json", np.array(TEST)
    steps = [d / f"test_{k + 1}.png" for k in range(6)]
    inv = fringekit.invert(steps, lib, sensor=sensor, method="phase")
    pos, load = contact_errors(inv.table(), want)
    assert np.all(pos < 0.02) and np.all(load < 0.01 * want[:, 4]), (pos, load)
    assert inv.summary["reference"]["residual_from"] == "the sensor file"
    try:
        plain = fringekit.invert(steps, lib, pixel_mm=PIXEL_MM, method="phase").table()
        pos, load = contact_errors(plain, want)
        assert np.any(pos > 0.05) or np.any(load > 0.03 * want[:, 4]), (pos, load)
    except fringekit.InvertError:
        pass  # refused: as good a "no" as a wrong answer flagged
    frames = d / "frames"
    frames.mkdir()
    for i in range(2):  # two load states, six steps each
        for k, p in enumerate(steps):
            (frames / f"s{i}_{k + 1}.png").write_bytes(p.read_bytes())
    t = fringekit.track(frames, lib, sensor=sensor, method="phase")
    table = t.table()
    pos, load = contact_errors({k: v[table["frame"] == 1] for k, v in table.items()}, want)
    assert np.all(pos < 0.02) and np.all(load < 0.01 * want[:, 4]), (pos, load)
    assert t.summary["reference"]["residual_from"] == "the sensor file"


@pytest.mark.slow
def test_a_grey_sensor_calibrated_with_six_rest_steps_models_its_residual(lib, tmp_path):
    """The same sensor read in the dark field, its 0.2-fringe residual given as six rest
    steps (``--residual-steps``) instead of a rest frame: the scales and geometry come
    back as in ``check_fitted``, the residual within 0.002 fringe, and invert reads two
    contacts through the file within 0.02 mm and 1 % of Fz."""
    phase = _truth(lib)
    grey = replace(phase, method="mono")
    rest = _six(tmp_path, "rest", lib, phase, [])
    write_known_and_test(tmp_path, lib, grey)
    argv = ["sensor", "calibrate", "--library", str(lib.folder), "--quiet"]
    argv += ["--residual-steps", *map(str, rest), "--known", str(tmp_path / "known.csv")]
    argv += ["--out", str(tmp_path / "sensor.json"), "--pixel-mm", str(PIXEL_MM)]
    assert main(argv) == 0
    got = load_sensor(tmp_path / "sensor.json")
    assert got.method == "mono" and got.rest is None
    check_fitted(got, grey)
    law = got.optics(optics_setup(got.config)).law
    off = residual_fringes((got.residual - grey.residual).reshape(-1, 2), law).max()
    assert off < 0.002, off
    inv = fringekit.invert(tmp_path / "test.png", lib, sensor=tmp_path / "sensor.json")
    pos, load = contact_errors(inv.table(), np.array(TEST))
    assert np.all(pos < 0.02) and np.all(load < 0.01 * np.array(TEST)[:, 4]), (pos, load)
    assert inv.summary["reference"]["residual_from"] == "the sensor file"


def test_bad_phase_calibration_inputs_are_one_line_each_and_write_nothing(lib, tmp_path, capsys):
    """Rest frames that are not whole six-step sets, a known frame of one file, a missing
    step, rest steps with a rest frame, and rest steps for a colour sensor: exit 2, one
    line naming the input, nothing written."""
    truth = _truth(lib)
    rest = _six(tmp_path, "rest", lib, truth, [])
    known = _six(tmp_path, "k", lib, truth, [KNOWN[0]])
    row = ",".join(f"{x:g}" for x in KNOWN[0])
    base = ["sensor", "calibrate", "--library", str(lib.folder), "--pixel-mm", "0.25"]
    base += ["--method", "phase", "--known", str(tmp_path / "known.csv")]
    base += ["--out", str(tmp_path / "s.json")]
    cases = [
        (rest[:4], ";".join(p.name for p in known), "--reference: give the six phase steps"),
        (rest, known[0].name, "give six files joined by ';' (the phase steps)"),
        (rest, ";".join(["gone.png"] + [p.name for p in known[1:]]), "'gone.png' not found"),
    ]
    for refs, cell, words in cases:
        (tmp_path / "known.csv").write_text(f"image,x_mm,y_mm,Fx_N,Fy_N,Fz_N\n{cell},{row}\n")
        assert main([*base, "--reference", *map(str, refs)]) == 2, words
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err, err
        assert not (tmp_path / "s.json").exists() and not (tmp_path / "s.png").exists()
    both = ["--reference", str(rest[0]), "--residual-steps", *map(str, rest)]
    for method, words in (
        ("mono", "--residual-steps with --reference is not allowed"),
        ("rgb", "--residual-steps is for --method mono"),
    ):
        argv = [a if a != "phase" else method for a in base]
        argv += both if method == "mono" else both[2:]
        assert main(argv) == 2, method
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err, err
        assert not (tmp_path / "s.json").exists()


def test_predict_library_with_a_phase_sensor_writes_its_six_steps(lib, tmp_path):
    """``predict --library --sensor`` with a phase sensor writes the six steps its camera
    records, residual retarder included: the calibration's forward model (sensor_frame)
    to one count of 8 bits."""
    truth = replace(_truth(lib), report={"exposure_gain": [GAIN]})
    out = predict_with_sensor(lib, truth, tmp_path)
    want = sensor_frame(lib, truth, TEST, gain=GAIN, bit_depth=8).astype(int)
    for k in range(6):
        got = read_pixels(out / "state_01" / f"camera_step{k + 1}.png").astype(int)
        assert got.shape == (PX, PX) and np.abs(got - want[..., k]).max() <= 1, k
    assert not (out / "state_01" / "camera.png").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["calibrated_sensor"]["fringe_scale"] == 0.92
