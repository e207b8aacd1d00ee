"""Messages a user can act on (issue: hostile inputs at the edges): each names the option
or file and the value, says what is allowed, fits on one line, shows no Python repr, and
comes before anything is written."""

from __future__ import annotations

import itertools
import re

import imageio.v3 as iio
import numpy as np
import pytest

from fringekit.cli import main
from fringekit.config.files import load_config
from fringekit.errors import ConfigError
from fringekit.sweep.run import case_id, expand_cases

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


def test_a_sweep_name_that_leaves_the_output_folder_is_refused(tmp_path, capsys, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    sweep = work / "escape.toml"
    sweep.write_text('name = "../../escaped"\n[grid]\n"sheet.E_MPa" = [3.0, 4.0]\n')
    words = ["escape.toml", 'name = "../../escaped"', "plain folder name"]
    _refused(["sweep", str(sweep), "--quiet"], capsys, words, tmp_path / "escaped")
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
