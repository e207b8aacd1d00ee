"""invert --refine fem: defect correction converges to the answer of the model the image
came from, not the library's; a turned image is rendered through the sheet's axes.

The rounds are checked against a smooth stand-in for the FEM (the library read as a sheet
10 % stiffer with a fringe value 5 % lower: a model the library cannot reproduce by its
loads alone), so the test runs in seconds and its fixed point is known exactly;
``bench/sensor.py`` runs it on full-FEM images."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from library_fixtures import TINY, sensor_config

import fringekit
import fringekit.inversion.refine as refine
from fringekit.inversion.model import unpack
from fringekit.optics import write_image
from fringekit.tracking.synthetic import blank_model

PX, PIXEL_MM = 64, 0.25
TRUTH = np.array([[-3.0, 1.5, 3.0, 0.6, 0.0], [2.5, -2.0, 2.5, 0.0, -0.5]])


def _other_model(model, cfg, params, diameters, friction, optics, sensor=None):
    """The stand-in for the full FEM: another sheet, read through the same library."""
    law = replace(model.law, f_sigma=model.law.f_sigma * 0.95)
    m = replace(model, lib=model.lib.scaled(1.1), law=law, correction=None, exact=2.5e-3)
    img, _ = m.linear(unpack(np.asarray(params, float).ravel(), list(diameters)))
    return img, np.ones(len(img), bool)


@pytest.mark.slow
def test_refinement_converges_to_the_model_the_image_came_from(tiny_library, tmp_path, monkeypatch):
    """The library alone reads the other sheet's image with its loads off by several %;
    the rounds bring every load within 1e-3 of Fz and every position within 1e-3 mm, and
    the corrected model then reproduces the image (residual below 0.005 of the fringe
    amplitude, and half the library's, which reads the loads several % off at 0.011)."""
    monkeypatch.setattr(refine, "fem_image", _other_model)
    model = blank_model(tiny_library, sensor_config(**TINY), (PX, PX), PIXEL_MM, "mono")
    img, _ = _other_model(model, None, TRUTH, [3.5e-3] * 2, "stick", None)
    raw = np.clip(0.8 * img[:, 0] + 0.02, 0, 1).reshape(PX, PX)
    write_image(tmp_path / "image.png", np.round(raw * 65535).astype(np.uint16))

    def errors(inv):
        t = inv.table()
        got = np.column_stack([t[k] for k in ("x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N")])
        got = got[[int(np.argmin(np.hypot(*(got[:, :2] - v[:2]).T))) for v in TRUTH]]
        return np.abs(got - TRUTH).max(0), t["residual_rms"]

    plain = fringekit.invert(tmp_path / "image.png", tiny_library, pixel_mm=PIXEL_MM)
    err, plain_rms = errors(plain)
    assert err[2] > 0.03 * 2.5 and plain.summary["refine"] is None
    fine = fringekit.invert(tmp_path / "image.png", tiny_library, pixel_mm=PIXEL_MM, refine="fem")
    err, rms = errors(fine)
    assert np.all(err[:2] < 1e-3) and np.all(err[2:] < 1e-3 * 2.5), err
    assert np.all(rms < 0.005) and np.all(rms < 0.5 * plain_rms), (rms, plain_rms)
    rep = fine.summary["refine"]
    assert rep["converged"] and 1 <= len(rep["rounds"]) <= refine.MAX_ROUNDS
    assert fine.summary["times_s"]["refine_s"] == rep["time_s"] > 0  # its solves timed


def test_a_turned_image_is_rendered_on_a_grid_in_the_sheets_axes(tiny_library):
    """For an image turned 30 degrees the FEM is rendered on a grid in the sheet's axes
    that covers the image, and each pixel is read where it lies on the sheet."""
    model = blank_model(tiny_library, sensor_config(**TINY), (20, 30), PIXEL_MM, "mono")
    same, where = refine._sheet_grid(model, 0.0)
    assert same is model.grid and where is None
    grid, where = refine._sheet_grid(model, 30.0)
    t = np.radians(30.0)
    x, y = model.xy.T
    sheet = np.column_stack([np.cos(t) * x + np.sin(t) * y, -np.sin(t) * x + np.cos(t) * y])
    back = np.column_stack(grid.pixel_to_xy(where[0], where[1]))
    assert np.allclose(back, sheet, atol=1e-12)
    assert where.min() >= 0 and where[0].max() <= grid.shape[0] - 1
    assert where[1].max() <= grid.shape[1] - 1
    with pytest.raises(ValueError, match="--refine 'exact' is not allowed"):
        fringekit.invert("x.png", tiny_library, pixel_mm=PIXEL_MM, refine="exact")


@pytest.mark.slow
def test_the_fem_image_holds_the_residual_and_reads_stresses_in_the_images_axes(
    tiny_library, monkeypatch
):
    """The full-FEM image of a sheared contact on six phase steps, for a sensor turned 20
    degrees against the camera, with a residual retarder of up to 0.25 fringe in the
    model: it differs from the library's image at the same loads by what it does without
    a residual (the library's own model error, 0.057 of the light on the tiny mesh beyond
    2 mm of the axis), and by twice that (0.12) when the FEM is rendered without the
    residual, or with its stresses left in the sheet's axes (the six steps' analyser
    angles then 20 degrees off: 0.116 without a residual)."""
    import json

    from fringekit.config.inputs import optics_setup
    from fringekit.library.calibrated import CalibratedSensor
    from fringekit.prediction.render import path_quaternions

    solve, solved = refine.solve_config, {}

    def solve_once(c, **kw):  # one FEM solve of the one state, however often rendered
        key = json.dumps(c, sort_keys=True, default=str)
        if key not in solved:
            solved[key] = solve(c, **kw)
        return solved[key]

    monkeypatch.setattr(refine, "solve_config", solve_once)
    cfg, p, diam = sensor_config(**TINY), np.array([[1.0, -0.5, 3.0, 0.5, -0.4]]), [3.5e-3]
    model = blank_model(tiny_library, cfg, (PX, PX), PIXEL_MM, "phase")
    turned = CalibratedSensor(
        cfg, "", "phase", (PX, PX), PIXEL_MM, (31.5, 31.5), 20.0, 1.0, 1.0, 1.0, (0.0,)
    )
    x, y = model.xy.T / 8e-3  # the field's half-width: 1
    k = float(model.law.retardation_per_stress_length(np.array([model.law.wavelength_ref]))[0])
    delta = 0.25 * 2 * np.pi * np.exp(-((x - 0.1) ** 2 + (y - 0.2) ** 2) / 0.3)  # rad
    axis = 0.6 + 0.8 * x
    res = np.column_stack([delta * np.cos(axis), delta * np.sin(axis)]) / (2 * k)  # Pa m
    far = np.hypot(*(model.xy * 1e3 - p[0, :2]).T) > 2.0

    def misfit(lib_res, fem_res):
        m = replace(model, residual_ab=fem_res)
        fem, valid = refine.fem_image(m, cfg, p, diam, "stick", optics_setup(cfg), turned)
        lib_img, _ = replace(model, residual_ab=lib_res, exact=2.5e-3).linear(unpack(p[0], diam))
        return float(np.sqrt(np.mean((fem - lib_img)[valid & far] ** 2)))

    none, both, fem_without = misfit(None, None), misfit(res, res), misfit(res, None)
    assert 0.02 < none < 0.08 and both < 1.1 * none and fem_without > 1.8 * none, (
        none,
        both,
        fem_without,
    )
    monkeypatch.setattr(
        refine,
        "path_quaternions",
        lambda *a, frozen=None, turn=0.0: path_quaternions(*a, frozen=frozen),
    )
    assert misfit(None, None) > 1.8 * none  # the stresses left in the sheet's axes
