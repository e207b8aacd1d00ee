"""Load-to-fringe calibration, inverse estimates and the disc fringe value."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fringekit.analysis import (
    calibrate_from_maps,
    estimate_load,
    fringe_features,
    load_calibration,
    save_calibration,
)
from fringekit.calibrate.disc_map import fringe_value_from_disc
from fringekit.cli.main import main
from fringekit.optics import PSM4_ASSUMED, DiametralDisc, PixelGrid, optical_map


def _cone(n=201, px=0.05e-3, k=1.0, shift=(0.0, 0.0)):
    """N = k * 6 / r_mm (a Boussinesq-like 1/r decay), centre masked, optionally shifted."""
    r, c = np.mgrid[:n, :n]
    c0 = (n - 1) / 2
    x = (c - c0) * px * 1e3 - shift[0]
    y = -(r - c0) * px * 1e3 - shift[1]
    rr = np.hypot(x, y)
    N = np.where(rr > 1.0, k * 6.0 / np.maximum(rr, 1e-9), np.nan)
    return N, px, (c0, c0)


def test_features_of_a_known_radial_field():
    N, px, rc = _cone()
    f = fringe_features(N, px, rc)
    assert f["order_at_2mm"] == pytest.approx(3.0, rel=0.01)
    assert f["order_at_3mm"] == pytest.approx(2.0, rel=0.01)
    # N = 6/r reaches order k at r = 6/k mm
    assert f["radius_mm_fringe_2"] == pytest.approx(3.0, abs=0.06)
    assert f["radius_mm_fringe_3"] == pytest.approx(2.0, abs=0.06)
    assert f["radius_mm_fringe_1"] == pytest.approx(6.0, abs=0.06)  # in the image corners
    # the annulus 2..6 mm does not fit in a 10 mm image: not defined rather than biased
    assert np.isnan(f["integrated_order_fringe_mm2"])
    N2, px2, rc2 = _cone(n=301)  # 15 mm image: the annulus fits
    f2 = fringe_features(N2, px2, rc2)
    assert f2["integrated_order_fringe_mm2"] == pytest.approx(
        2 * np.pi * 6.0 * 4.0, rel=0.01
    )  # int 6/r r dr dphi
    assert abs(f2["centroid_x_mm"]) < 1e-9 and abs(f2["centroid_y_mm"]) < 1e-9
    with pytest.raises(ValueError, match="pixel_size"):
        fringe_features(N, 0.0, rc)


def test_calibration_round_trip_with_shear(tmp_path):
    """A power law in the load and a linear centroid shift in the shear are recovered."""
    loads = np.array([1.0, 2.0, 4.0, 6.0, 8.0, 10.0])
    shears = np.column_stack([0.5 * loads, np.zeros_like(loads)])
    feats = []
    for F, (sx, _) in zip(loads, shears, strict=True):
        N, px, rc = _cone(n=301, k=(F / 8.0) ** (2 / 3), shift=(0.02 * sx, 0.0))
        feats.append(fringe_features(N, px, rc))
    cal = calibrate_from_maps(loads, shears, feats)
    fit = cal["normal_fits"]["order_at_3mm"]
    assert fit["b"] == pytest.approx(1.5, rel=0.02)  # N ~ F^(2/3) <=> F ~ N^1.5
    assert "shear_x_N" in cal["shear_fits"] and "shear_y_N" not in cal["shear_fits"]
    f = save_calibration(cal, tmp_path / "cal.json")
    cal2 = load_calibration(f)
    N, px, rc = _cone(n=301, k=(5.0 / 8.0) ** (2 / 3), shift=(0.02 * 2.5, 0.0))
    est = estimate_load(cal2, fringe_features(N, px, rc))
    assert est["normal_N"] == pytest.approx(5.0, rel=0.02)
    assert est["shear_N"][0] == pytest.approx(2.5, abs=0.15) and est["shear_N"][1] == 0.0
    N, px, rc = _cone(n=301, k=(40.0 / 8.0) ** (2 / 3))
    with pytest.raises(ValueError, match="calibrated range"):
        estimate_load(cal2, fringe_features(N, px, rc))
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(ValueError, match="not a fringekit calibration"):
        load_calibration(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="no feature changes"):
        calibrate_from_maps([8.0] * 3, np.zeros((3, 2)), feats[:3])


def test_fringe_value_from_the_disc(tmp_path, capsys):
    """Frocht's disc in transmission: the fit gives f_sigma back from the order map."""
    D, t, P, n = 0.04, 5e-3, 300.0, 121
    grid = PixelGrid((n, n), D / n)
    m = optical_map(DiametralDisc(P=P, D=D, t=t), grid, PSM4_ASSUMED, n_samples=3, reflection=False)
    order = m.fringe_order()
    res = fringe_value_from_disc(
        order, grid.pixel_size, ((n - 1) / 2, (n - 1) / 2), load_N=P, diameter=D, thickness=t
    )
    assert res["f_sigma_N_per_m"] == pytest.approx(PSM4_ASSUMED.f_sigma, rel=1e-3)
    assert res["f_sigma_centre_N_per_m"] == pytest.approx(PSM4_ASSUMED.f_sigma, rel=1e-3)
    np.savez(tmp_path / "maps.npz", fringe_order=order, pixel_size_m=grid.pixel_size)
    args = [
        "calibrate",
        "--disc",
        str(tmp_path / "maps.npz"),
        "--load-N",
        str(P),
        "--diameter-mm",
        "40",
        "--thickness-mm",
        "5",
        "--out",
        str(tmp_path / "o"),
    ]
    assert main(args) == 0
    got = json.loads((tmp_path / "o" / "fringe_value.json").read_text())
    assert got["f_sigma_N_per_m"] == pytest.approx(PSM4_ASSUMED.f_sigma, rel=1e-3)
    assert f"{PSM4_ASSUMED.f_sigma:.4g}" in capsys.readouterr().out
    assert main(["calibrate", "--disc", str(tmp_path / "maps.npz"), "--load-N", "300"]) == 2
    assert "--diameter-mm" in capsys.readouterr().err


def test_an_estimate_refuses_a_map_the_calibration_does_not_describe():
    """The features of a map off its centre disagree with each other far beyond their
    calibrated scatter: refused, not a confident wrong load (3.54 +- 0.004 N before).
    Slightly off, the load is kept and its uncertainty widened with a warning."""
    loads = np.array([1.0, 2.0, 4.0, 6.0, 8.0, 10.0])
    feats = [fringe_features(*_cone(n=301, k=(F / 8.0) ** (2 / 3))) for F in loads]
    cal = calibrate_from_maps(loads, np.zeros((6, 2)), feats)
    N, px, rc = _cone(n=301, k=(5.0 / 8.0) ** (2 / 3))
    good = estimate_load(cal, fringe_features(N, px, rc))
    assert good["normal_N"] == pytest.approx(5.0, rel=0.01)
    assert good["consistency_chi2"] < 4 and "warning" not in good
    with pytest.raises(ValueError, match="not consistent with the calibration"):
        estimate_load(cal, fringe_features(N, px, (rc[0] + 20, rc[1] + 20)))  # 1.4 mm off
    near = estimate_load(cal, fringe_features(N, px, (rc[0] + 6, rc[1])))  # 0.3 mm off
    assert near["normal_N"] == pytest.approx(5.0, rel=0.01)
    assert "warning" in near and near["normal_sigma_N"] > 2 * good["normal_sigma_N"]


def test_the_disc_fit_refuses_a_map_that_is_not_a_disc(tmp_path, capsys):
    """An indenter-like map fitted as a disc returned f_sigma = 1.6e4 N/m with a 0.84
    fringe residual and no word; now the residual is measured against the order: refused
    above 25 %, flagged above 5 %."""
    N, px, rc = _cone(n=301)
    with pytest.raises(ValueError, match="does not look like a diametral disc"):
        fringe_value_from_disc(N, px, rc, load_N=300, diameter=0.015, thickness=5e-3)
    D, t, P, n = 0.04, 5e-3, 300.0, 121
    grid = PixelGrid((n, n), D / n)
    m = optical_map(DiametralDisc(P=P, D=D, t=t), grid, PSM4_ASSUMED, n_samples=3, reflection=False)
    order = m.fringe_order()
    rng = np.random.default_rng(1)
    noisy = order * (1 + 0.15 * rng.standard_normal(order.shape))  # 15 % speckle
    res = fringe_value_from_disc(
        noisy, grid.pixel_size, ((n - 1) / 2, (n - 1) / 2), load_N=P, diameter=D, thickness=t
    )
    assert 0.05 < res["relative_residual"] < 0.25 and "warning" in res
    np.savez(tmp_path / "m.npz", fringe_order=noisy, pixel_size_m=grid.pixel_size)
    args = [
        "calibrate",
        "--disc",
        str(tmp_path / "m.npz"),
        "--load-N",
        str(P),
        "--diameter-mm",
        "40",
        "--thickness-mm",
        "5",
    ]
    assert main(args) == 0
    assert "warning: Frocht's field leaves" in capsys.readouterr().err


def test_the_disc_centre_comes_from_the_map_outline_or_is_refused(tmp_path, capsys):
    """Without --centre the disc is found from its data region (it was taken at the image
    centre, off the disc in a real photo); a map with data everywhere is refused, and
    analyze's unreliable pixels are left out of the fit."""
    D, t, P, n = 0.04, 5e-3, 300.0, 121
    grid = PixelGrid((n, n), D / n)
    m = optical_map(DiametralDisc(P=P, D=D, t=t), grid, PSM4_ASSUMED, n_samples=3, reflection=False)
    order = m.fringe_order()
    # the disc off the image centre: pad 30 columns on the left and 12 rows below
    shifted = np.pad(order, ((0, 12), (30, 0)), constant_values=np.nan)
    reliable = np.isfinite(shifted)
    garbage = shifted.copy()
    garbage[70:80, 80:90] = 9.0  # wrong values the analysis flagged as unreliable
    reliable[70:80, 80:90] = False
    np.savez(
        tmp_path / "m.npz", fringe_order=garbage, reliable=reliable, pixel_size_m=grid.pixel_size
    )
    args = [
        "calibrate",
        "--disc",
        str(tmp_path / "m.npz"),
        "--load-N",
        str(P),
        "--diameter-mm",
        "40",
        "--thickness-mm",
        "5",
        "--out",
        str(tmp_path / "o"),
    ]
    assert main(args) == 0
    got = json.loads((tmp_path / "o" / "fringe_value.json").read_text())
    assert got["f_sigma_N_per_m"] == pytest.approx(PSM4_ASSUMED.f_sigma, rel=2e-3)
    assert got["centre_rc"] == pytest.approx([(n - 1) / 2, (n - 1) / 2 + 30], abs=0.5)
    assert got["reliable_mask_used"] and "outline" in got["centre_from"]
    full = np.where(np.isfinite(shifted), shifted, 0.1)  # data everywhere, like a photo
    np.savez(tmp_path / "f.npz", fringe_order=full, pixel_size_m=grid.pixel_size)
    args[2] = str(tmp_path / "f.npz")
    assert main([*args[:-2], "--out", str(tmp_path / "f")]) == 2
    assert "give --centre ROW COL" in capsys.readouterr().err
