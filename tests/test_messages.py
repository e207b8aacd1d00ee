"""Messages a user can act on (issue: hostile inputs at the edges): each names the option
or file and the value, says what is allowed, fits on one line, shows no Python repr, and
comes before anything is written."""

from __future__ import annotations

import itertools

import imageio.v3 as iio
import numpy as np
import pytest
from cli_checks import refused

from fringekit.analysis import calibrate_from_maps, fringe_features, save_calibration
from fringekit.cli import main
from fringekit.config.files import load_config
from fringekit.errors import ConfigError
from fringekit.sweep.run import case_id, expand_cases


@pytest.fixture
def image(tmp_path):
    """A 64 x 64 grey image with fringes."""
    r, c = np.mgrid[:64, :64]
    img = (127.5 + 120 * np.sin(np.hypot(r - 31.5, c - 31.5) / 3)).astype(np.uint8)
    path = tmp_path / "fringes.png"
    iio.imwrite(path, img)
    return path


def test_a_circle_outside_the_image_is_named_not_a_profile_line(image, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["analyze", str(image), "--exclude-circle", "500", "500", "10", "--out", str(out)]
    refused(argv, capsys, ["--exclude-circle 500 500 10", "64 x 64", "rows 0..63"], out)
    argv = ["analyze", str(image), "--roi-circle", "-50", "20", "10", "--out", str(out)]
    refused(argv, capsys, ["--roi-circle -50 20 10", "outside"], out)
    # a circle that reaches into the image is a region like any other
    assert main(
        [
            "analyze",
            str(image),
            "--exclude-circle",
            "-5",
            "31.5",
            "12",
            "--out",
            str(out),
            "--quiet",
        ]
    ) in (0, 1)


def test_a_folder_given_as_an_image_is_called_a_folder(tmp_path, capsys):
    out = tmp_path / "out"
    refused(["analyze", str(tmp_path), "--out", str(out)], capsys, ["is a folder"], out)


def test_a_stack_where_one_image_is_expected_names_the_method(tmp_path, capsys):
    import tifffile

    stack = np.random.default_rng(0).random((3, 16, 16))
    tifffile.imwrite(tmp_path / "stack.tif", stack, photometric="minisblack")
    out = tmp_path / "out"
    argv = ["analyze", str(tmp_path / "stack.tif"), "--method", "mono", "--out", str(out)]
    refused(argv, capsys, ["stack.tif: holds 3 pages", "phase method"], out)


def test_disc_options_without_disc_are_refused_before_the_reference_calibration(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["calibrate", "--diameter-mm", "40", "--thickness-mm", "6", "--out", str(out)]
    refused(argv, capsys, ["--diameter-mm", "calibrate --disc"], out)


def test_a_config_saved_with_a_byte_order_mark_is_read(tmp_path, capsys):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf[sheet]\nE_MPa = 5.0\n")
    assert main(["config", "show", str(path)]) == 0
    assert "E_MPa = 5.0" in capsys.readouterr().out


def test_the_same_image_six_times_is_named_not_sent_to_order_at(image, tmp_path, capsys):
    """Six copies of one image used to be told to give --order-at, which failed too."""
    out = tmp_path / "out"
    argv = ["analyze", *[str(image)] * 6, "--out", str(out)]
    refused(argv, capsys, ["images 1 and 2", "identical", "six polariscope arrangements"], out)


def test_a_dark_frame_brighter_than_the_image_is_blamed_not_the_image(image, tmp_path, capsys):
    """A dark frame brighter than the image used to leave 'the image is empty'."""
    dark = tmp_path / "not_dark.png"
    iio.imwrite(dark, np.full((64, 64), 250, np.uint8))
    out = tmp_path / "out"
    argv = ["analyze", str(image), "--method", "mono", "--dark", str(dark), "--out", str(out)]
    refused(argv, capsys, ["dark frame", "not_dark.png", "brighter than the image"], out)
    # a real dark frame (black level 3 of 255, with noise) is subtracted as before
    noise = np.random.default_rng(0).integers(0, 7, (64, 64)).astype(np.uint8)
    iio.imwrite(dark, noise)
    assert main([*argv[:-1], str(tmp_path / "ok"), "--quiet"]) in (0, 1)


def test_a_quiet_sweep_with_failed_cases_says_so_on_stderr(tmp_path, capsys, monkeypatch):
    """sweep --quiet used to exit 1 with nothing on stderr."""
    import fringekit.cli.sweep as cli_sweep

    (tmp_path / "sweep.toml").write_text('base = "small"\n[grid]\n"indenter.load_N" = [[2.0]]\n')
    table = str(tmp_path / "out" / "results.csv")
    result = {"cases": 3, "run": 3, "skipped": 0, "failed": 2, "time_s": 1.0, "table": table}
    monkeypatch.setattr(cli_sweep, "run_sweep", lambda *a, **k: result)
    assert main(["sweep", str(tmp_path / "sweep.toml"), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert "2 of 3 cases failed" in err and "results.csv" in err and "\n" not in err


def test_an_os_error_names_the_users_path_not_the_hidden_working_folder(
    image, tmp_path, capsys, monkeypatch
):
    """A disk or permission error used to print the raw errno text with the run's hidden
    .part folder; now the path the user asked for, and the reason."""
    from fringekit.measurement.order import Analysis

    def fail(self, folder, **kw):
        raise PermissionError(13, "Permission denied", str(folder / "maps.npz"))

    monkeypatch.setattr(Analysis, "write", fail)
    out = tmp_path / "an"
    assert main(["analyze", str(image), "--method", "mono", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"{out / 'maps.npz'}: Permission denied"), err
    assert ".part" not in err and "Errno" not in err and "\n" not in err
    assert not out.exists()


def test_a_sweep_name_that_leaves_the_output_folder_isrefused(tmp_path, capsys, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    sweep = work / "escape.toml"
    sweep.write_text('name = "../../escaped"\n[grid]\n"sheet.E_MPa" = [3.0, 4.0]\n')
    words = ["escape.toml", 'name = "../../escaped"', "plain folder name"]
    refused(["sweep", str(sweep), "--quiet"], capsys, words, tmp_path / "escaped")
    assert sorted(p.name for p in work.iterdir()) == ["escape.toml"]


#: A long load path first: every case's overrides share their first 60 characters, the
#: part of the id that is not a hash.
LONG_PATH = [0.5 * k for k in range(1, 13)]


def _grid_case(e, g, f):
    return {
        "indenter.load_N": LONG_PATH,
        "sheet.E_MPa": e,
        "mesh.growth": g,
        "optics.f_sigma_N_per_m": f,
    }


def test_two_cases_whose_ids_collided_are_two_cases():
    """A pair of a 10^6-case grid (100 values of each of three keys) that 32 bits of hash
    gave one id, reported as a case repeating an earlier one; a real repeat still is."""
    a, b = _grid_case(1.04, 1.9, 1.06), _grid_case(1.06, 1.14, 1.64)
    cases = expand_cases(load_config("small"), [a, b])
    assert len({c["id"] for c in cases}) == 2
    with pytest.raises(ConfigError, match="case 2 .* repeats an earlier case"):
        expand_cases(load_config("small"), [a, b, dict(a)])


@pytest.mark.slow
def test_the_case_ids_of_a_million_case_grid_are_distinct():
    """Every id of that 10^6-case grid, without solving (about 50 s on a loaded CI core;
    32 bits of hash gave about a hundred pairs of cases one id)."""
    values = [round(1 + 0.01 * k, 2) for k in range(100)]
    grid = itertools.product(values, values, values)
    assert len({case_id(_grid_case(*v)) for v in grid}) == 10**6


#: Out-of-range numbers given as options -> words of the refusal: the option, the value
#: and the range, which is the config key's where the option sets one (the schema's).
OUT_OF_RANGE = [
    (
        ["analyze", "{img}", "--f-sigma-N-per-m", "1e300", "--thickness-mm", "3"],
        ["--f-sigma-N-per-m: 1e300", "(0, 1e+08] N/m", "config key optics.f_sigma_N_per_m"],
    ),
    (
        ["analyze", "{img}", "--f-sigma-N-per-m", "386", "--thickness-mm", "1e-300"],
        ["--thickness-mm: 1e-300", "[0.01, 100] mm", "config key sheet.thickness_mm"],
    ),
    (
        ["analyze", "{img}", "--method", "rgb", "--exposure", "1e9"],
        ["--exposure: 1e9", "(0, 1000]", "config key optics.exposure"],
    ),
    (
        ["analyze", "{img}", "--pixel-mm", "1e-300"],
        ["--pixel-mm: 1e-300", "[0.0001, 10] mm"],
    ),
    (
        ["calibrate", "--disc", "{img}", "--load-N", "100", "--diameter-mm", "40"]
        + ["--thickness-mm", "6", "--wavelength-nm", "1e9"],
        ["--wavelength-nm: 1e9", "[360, 830] nm", "config key optics.wavelength_nm"],
    ),
    (
        ["calibrate", "--disc", "{img}", "--load-N", "1e9", "--diameter-mm", "40"],
        ["--load-N: 1e9", "(0, 10000] N", "config key indenter.load_N"],
    ),
    (
        ["calibrate", "--disc", "{img}", "--load-N", "100", "--diameter-mm", "1e-300"],
        ["--diameter-mm: 1e-300", "[1, 500] mm"],
    ),
    (
        ["library", "build", "small", "--load-N", "0", "4"],
        ["--load-N: 0", "(0, 10000] N", "config key indenter.load_N"],
    ),
    (
        ["library", "build", "small", "--shear-ratio", "0", "1.5"],
        ["--shear-ratio: 1.5", "allowed range [0, 1]"],
    ),
    (
        ["library", "build", "small", "--diameter-mm", "1e5"],
        ["--diameter-mm: 1e5", "(0, 100] mm", "config key indenter.diameter_mm"],
    ),
    (
        ["mesh", "--h-contact-mm", "1e9"],
        ["--h-contact-mm: 1e9", "(0, 50] mm", "config key mesh.h_contact_mm"],
    ),
    (
        ["compare", "{img}", "{img}", "--rotation-deg", "1e9"],
        ["--rotation-deg: 1e9", "[-360, 360] deg"],
    ),
    (
        ["invert", "{img}", "--library", "{img}", "--pixel-mm", "20"],
        ["--pixel-mm: 20", "[0.0001, 10] mm"],
    ),
]


@pytest.mark.parametrize(("argv", "words"), OUT_OF_RANGE, ids=lambda v: " ".join(v)[:40])
def test_an_out_of_range_option_is_refused_with_its_range(argv, words, image, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [a.replace("{img}", str(image)) for a in argv] + ["--out", str(out)]
    refused(argv, capsys, words, out)


def _calibration(path, **fit):
    """A calibration file of the synthetic Hertz-like maps, one fit's coefficients set."""
    r_mm = np.hypot(*np.mgrid[-60:61, -60:61]) * 0.1

    def order_map(load):
        return (load / 8) ** (2 / 3) * 3.0 * np.exp(-((r_mm / 2.5) ** 2))

    loads = [2.0, 4.0, 8.0, 12.0]
    cal = calibrate_from_maps(
        loads, np.zeros((4, 2)), [fringe_features(order_map(f), 1e-4, (60, 60)) for f in loads]
    )
    cal["normal_fits"]["order_at_2mm"].update(fit)
    save_calibration(cal, path)
    np.savez(path.with_name("maps.npz"), fringe_order=order_map(6.0), pixel_size_m=np.array(1e-4))
    return path


#: A fitted relation's coefficients -> words of the refusal (file and key, value, range).
DEGENERATE_FITS = [
    ({"b": 1e-300}, ["normal_fits.order_at_2mm.b = 1e-300", "[0.2, 10]"]),
    ({"b": -1.5}, ["normal_fits.order_at_2mm.b = -1.5", "[0.2, 10]"]),
    ({"a": 0.0}, ["normal_fits.order_at_2mm.a = 0", "(0, inf)"]),
]


@pytest.mark.parametrize(("fit", "words"), DEGENERATE_FITS, ids=str)
def test_a_calibration_with_a_degenerate_fit_isrefused(fit, words, tmp_path, capsys):
    cal = _calibration(tmp_path / "calibration.json", **fit)
    out = tmp_path / "out"
    argv = ["estimate", str(tmp_path / "maps.npz"), "--calibration", str(cal)]
    refused(argv + ["--centre", "60", "60", "--out", str(out)], capsys, [str(cal), *words], out)
