"""Plausible or refused (issue: hostile inputs at the edges): geometry given against the
image, a colour photograph given to a monochrome method, and data a command did not
measure. Each refusal is one line naming the option and its value, with no Python repr,
before anything is written."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest
from cli_checks import refused

from fringekit.cli import main


def _rings(n=96, order_max=4.0, lam=(550.0,), gains=(1.0,)):
    """Dark-field rings (order falling from the centre) in light of the wavelengths
    ``lam`` (nm; the order is given at 550 nm), one channel per wavelength, 8-bit."""
    r, c = np.mgrid[:n, :n]
    order = order_max * np.exp(-((np.hypot(r - n / 2, c - n / 2) / (n / 4)) ** 2))
    ch = [g * np.sin(np.pi * order * 550 / w) ** 2 for w, g in zip(lam, gains, strict=True)]
    img = np.stack(ch, -1) if len(ch) > 1 else ch[0]
    return np.round(20 + 220 * img).astype(np.uint8)


@pytest.fixture
def disc_photo(tmp_path):
    path = tmp_path / "disc.png"
    iio.imwrite(path, _rings(240))
    return path


@pytest.mark.parametrize(
    "options, words",
    [
        (["--radius-px", "5000"], ["--radius-px 5000", "240 x 240"]),
        (["--centre", "500", "-20", "--radius-px", "100"], ["--centre 500 -20", "240 x 240"]),
        (["--pixel-mm", "0.001"], ["--pixel-mm 0.001", "240 x 240"]),
        (["--centre", "120", "120", "--radius-px", "3"], ["--radius-px 3", "at least 8 px"]),
    ],
)
def test_a_disc_outside_the_photo_isrefused(disc_photo, tmp_path, capsys, options, words):
    """A disc mostly off the photo used to give a fringe value 6.6x wrong with a 0.1 %
    residual: the few pixels it kept fit anything."""
    out = tmp_path / "cal"
    argv = ["calibrate", "--disc", str(disc_photo), "--load-N", "100", "--diameter-mm", "40"]
    argv += ["--thickness-mm", "6", *options, "--out", str(out)]
    refused(argv, capsys, words, out)


@pytest.fixture
def tiny_lib_folder(tiny_library):
    return tiny_library.folder


@pytest.mark.parametrize(
    "origin, pixel_mm, words",
    [
        (("5000", "5000"), "0.25", ["--origin-px 5000 5000", "48 x 48"]),
        (("-1e6", "1e6"), "0.25", ["--origin-px -1e+06 1e+06", "outside"]),
        (("48", "10"), "0.25", ["--origin-px 48 10", "rows 0..47"]),
    ],
)
def test_an_origin_off_the_image_isrefused(
    tiny_lib_folder, tmp_path, capsys, origin, pixel_mm, words
):
    """invert --origin-px 5000 5000 used to return an indenter at (-619, 619) mm on a
    20 mm sheet, marked reliable."""
    image = tmp_path / "image.png"
    iio.imwrite(image, _rings(48))
    out = tmp_path / "inv"
    argv = ["invert", str(image), "--library", str(tiny_lib_folder), "--pixel-mm", pixel_mm]
    argv += ["--origin-px", *origin, "--method", "mono", "--out", str(out), "--quiet"]
    refused(argv, capsys, words, out)


WHITE = {"lam": (620.0, 550.0, 460.0), "gains": (1.0, 1.0, 1.0)}
SODIUM = {"lam": (589.0, 589.0, 589.0), "gains": (0.9, 1.0, 0.35)}


def test_a_white_light_colour_photo_is_refused_by_the_mono_methods(tmp_path, capsys, tiny_library):
    """A colour image of white-light fringes given to --method mono used to be averaged
    into grey and read as wrong orders (and loads) marked reliable."""
    image = tmp_path / "white.png"
    iio.imwrite(image, _rings(48, **WHITE))
    out = tmp_path / "an"
    argv = ["analyze", str(image), "--method", "mono", "--out", str(out)]
    refused(argv, capsys, ["--method mono", "white.png", "channels disagree", "--method rgb"], out)
    argv = ["invert", str(image), "--library", str(tiny_library.folder), "--pixel-mm", "0.25"]
    argv += ["--method", "mono", "--out", str(out), "--quiet"]
    refused(argv, capsys, ["--method mono", "white.png", "channels disagree"], out)


def test_a_colour_photo_of_monochromatic_light_is_read_as_its_strongest_channel(tmp_path):
    """Sodium light on a colour camera: the channels are one pattern; analyze reads the
    strongest (green here) and says so; the orders match the grey image's."""
    import json

    colour, grey = tmp_path / "sodium.png", tmp_path / "grey.png"
    iio.imwrite(colour, _rings(64, **SODIUM))
    iio.imwrite(grey, _rings(64, lam=(589.0,)))
    runs = {}
    for name, path in (("colour", colour), ("grey", grey)):
        out = tmp_path / name
        assert main(["analyze", str(path), "--method", "mono", "--out", str(out), "--quiet"]) in (
            0,
            1,
        )
        runs[name] = (np.load(out / "maps.npz"), json.loads((out / "summary.json").read_text()))
    assert "read as its green channel" in runs["colour"][1]["warning"]
    a, b = (runs[k][0]["fringe_order"] for k in ("colour", "grey"))
    both = np.isfinite(a) & np.isfinite(b)
    assert both.mean() > 0.5
    assert np.abs(a - b)[both].max() < 0.05


@pytest.mark.parametrize(
    "sets, words",
    [
        (["indenter[0].x_mm=9"], ["indenter[0] at x_mm = 9", "off the 20 x 20 mm sheet"]),
        (
            ["indenter[0].x_mm=-1", "indenter[1].x_mm=1"],
            ["indenter[0] and indenter[1] overlap", "2 mm apart"],
        ),
    ],
)
def test_predict_from_a_library_checks_the_heads_as_the_fem_does(
    tiny_library, tmp_path, capsys, sets, words
):
    """predict --library used to synthesise heads off the sheet and heads overlapping,
    which FEM predict refuses."""
    from fringekit.config.files import load_config, to_toml

    cfg = load_config(tiny_library.folder / "config.toml")
    cfg["indenter"] = [dict(cfg["indenter"][0], x_mm=0.0, y_mm=0.0, load_N=[3.0])]
    cfg["indenter"].append(dict(cfg["indenter"][0], x_mm=5.0))
    path = tmp_path / "two.toml"
    path.write_text(to_toml(cfg))
    out = tmp_path / "pred"
    argv = ["predict", str(path), "--library", str(tiny_library.folder), "--out", str(out)]
    for s in sets:
        argv += ["--set", s]
    refused(argv, capsys, words, out)
    # the same config without the change is synthesised
    assert main(argv[: argv.index("--set")] + ["--quiet"]) == 0


def _with_no_data_disc(tmp_path, n=64, rad=6):
    """Rings with predict's no-data fill (half scale in every channel) over the contact."""
    img = _rings(n, **SODIUM)
    r, c = np.mgrid[:n, :n]
    disc = np.hypot(r - n / 2, c - n / 2) <= rad
    img[disc] = 128
    path = tmp_path / "with_disc.png"
    iio.imwrite(path, img)
    return path, disc


@pytest.mark.parametrize("method", ["mono", "rgb"])
def test_predicts_no_data_fill_is_not_read_as_data(tmp_path, method):
    """analyze used to read predict's flat grey contact disc as a reliable plateau of
    order 3.5 (65,404 of 65,536 pixels reliable on the reference image)."""
    import json

    path, disc = _with_no_data_disc(tmp_path)
    out = tmp_path / "an"
    assert main(["analyze", str(path), "--method", method, "--out", str(out), "--quiet"]) in (0, 1)
    summary = json.loads((out / "summary.json").read_text())
    maps = np.load(out / "maps.npz")
    assert summary["no_data_px"] == int(disc.sum())
    assert not maps["reliable"][disc].any()
    # mono gives no order where the fringes are denser than the pixels (the rings' flank)
    dense = summary.get("mono", {}).get("unresolved_px", 0)
    assert summary["valid_pixels"] == disc.size - disc.sum() - dense


def test_a_mask_image_limits_the_region(tmp_path, capsys):
    """--mask takes predict's mask.png (data where bright); one of another size is refused."""
    import json

    path, _ = _with_no_data_disc(tmp_path)
    keep = np.zeros((64, 64), np.uint8)
    keep[:, :32] = 255
    iio.imwrite(tmp_path / "mask.png", keep)
    out = tmp_path / "an"
    argv = ["analyze", str(path), "--method", "mono", "--out", str(out), "--quiet"]
    assert main([*argv, "--mask", str(tmp_path / "mask.png")]) in (0, 1)
    assert not np.load(out / "maps.npz")["reliable"][:, 32:].any()
    assert json.loads((out / "summary.json").read_text())["valid_pixels"] <= 64 * 32
    iio.imwrite(tmp_path / "small_mask.png", keep[:32])
    out2 = tmp_path / "an2"
    capsys.readouterr()
    argv = ["analyze", str(path), "--mask", str(tmp_path / "small_mask.png"), "--out", str(out2)]
    refused(argv, capsys, ["--mask", "small_mask.png", "32 x 64 px", "64 x 64 px"], out2)
