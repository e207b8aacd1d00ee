"""Messages a user can act on (issue: hostile inputs at the edges): each names the option
or file and the value, says what is allowed, fits on one line, shows no Python repr, and
comes before anything is written."""

from __future__ import annotations

import re

import imageio.v3 as iio
import numpy as np
import pytest

from fringekit.cli import main

REPR = re.compile(r"np\.\w+\(|PosixPath\(|WindowsPath\(|load_six_step|compare_maps")


@pytest.fixture
def image(tmp_path):
    """A 64 x 64 grey image with fringes."""
    r, c = np.mgrid[:64, :64]
    img = (127.5 + 120 * np.sin(np.hypot(r - 31.5, c - 31.5) / 3)).astype(np.uint8)
    path = tmp_path / "fringes.png"
    iio.imwrite(path, img)
    return path


def _refused(argv, capsys, words, out):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    assert all(w in err for w in words), err
    assert not REPR.search(err), err
    assert not out.exists()


def test_a_circle_outside_the_image_is_named_not_a_profile_line(image, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["analyze", str(image), "--exclude-circle", "500", "500", "10", "--out", str(out)]
    _refused(argv, capsys, ["--exclude-circle 500 500 10", "64 x 64", "rows 0..63"], out)
    argv = ["analyze", str(image), "--roi-circle", "-50", "20", "10", "--out", str(out)]
    _refused(argv, capsys, ["--roi-circle -50 20 10", "outside"], out)
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
    _refused(["analyze", str(tmp_path), "--out", str(out)], capsys, ["is a folder"], out)


def test_a_stack_where_one_image_is_expected_names_the_method(tmp_path, capsys):
    import tifffile

    stack = np.random.default_rng(0).random((3, 16, 16))
    tifffile.imwrite(tmp_path / "stack.tif", stack, photometric="minisblack")
    out = tmp_path / "out"
    argv = ["analyze", str(tmp_path / "stack.tif"), "--method", "mono", "--out", str(out)]
    _refused(argv, capsys, ["stack.tif: holds 3 pages", "phase method"], out)


def test_disc_options_without_disc_are_refused_before_the_reference_calibration(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["calibrate", "--diameter-mm", "40", "--thickness-mm", "6", "--out", str(out)]
    _refused(argv, capsys, ["--diameter-mm", "calibrate --disc"], out)


def test_a_config_saved_with_a_byte_order_mark_is_read(tmp_path, capsys):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf[sheet]\nE_MPa = 5.0\n")
    assert main(["config", "show", str(path)]) == 0
    assert "E_MPa = 5.0" in capsys.readouterr().out


def test_the_same_image_six_times_is_named_not_sent_to_order_at(image, tmp_path, capsys):
    """Six copies of one image used to be told to give --order-at, which failed too."""
    out = tmp_path / "out"
    argv = ["analyze", *[str(image)] * 6, "--out", str(out)]
    _refused(argv, capsys, ["images 1 and 2", "identical", "six polariscope arrangements"], out)


def test_a_dark_frame_brighter_than_the_image_is_blamed_not_the_image(image, tmp_path, capsys):
    """A dark frame brighter than the image used to leave 'the image is empty'."""
    dark = tmp_path / "not_dark.png"
    iio.imwrite(dark, np.full((64, 64), 250, np.uint8))
    out = tmp_path / "out"
    argv = ["analyze", str(image), "--method", "mono", "--dark", str(dark), "--out", str(out)]
    _refused(argv, capsys, ["dark frame", "not_dark.png", "brighter than the image"], out)
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
