"""``invert --reference``: the sensor at rest taken into account in one image's inverse.

Dark field (rgb, mono): the rest light (glare, stray light) is taken off the image. Phase:
the six rest steps give the sheet's residual retarder, put into the model in series with
the loads' retardation."""

from __future__ import annotations

import csv
import json
from dataclasses import replace

import numpy as np
import pytest
from library_fixtures import frozen_stress

from fringekit.analysis import read_pixels
from fringekit.cli.main import main
from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.inversion import invert
from fringekit.inversion.read import read_measurement
from fringekit.inversion.rest import RestFrames, take_rest
from fringekit.library.calibrated import CalibratedSensor
from fringekit.optics import write_image
from fringekit.tracking import library_frames
from fringekit.tracking.synthetic import blank_model

PX, PIXEL_MM = 64, 0.25  # 16 x 16 mm images of the tiny library's sensor
#: Two contacts (x, y mm, Fz, Fx, Fy N), one sheared along x, one along y.
TRUTH = [(-4.0, 3.5, 2.5, 0.3, 0.0), (3.0, -4.0, 3.0, 0.0, 0.3)]


def _errors(table) -> np.ndarray:
    """(2, 5) |read - true| of each true contact's nearest read one (x, y mm, Fz, Fx, Fy N)."""
    got = np.stack([table[k] for k in ("x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N")], 1)
    out = []
    for t in np.asarray(TRUTH):
        near = got[int(np.argmin(np.hypot(*(got[:, :2] - t[:2]).T)))]
        out.append(np.abs(near - t))
    return np.array(out)


def _glare(shape) -> np.ndarray:
    """A smooth rest light (linear 0-1): an even glare and a bright patch, up to 0.17."""
    r, c = np.mgrid[: shape[0], : shape[1]] / shape[0]
    return 0.05 + 0.12 * np.exp(-((r - 0.4) ** 2 + (c - 0.65) ** 2) / (2 * 0.2**2))


@pytest.fixture(scope="module")
def glare_image(tiny_library, tmp_path_factory):
    """(image, rest frame) paths: a 16-bit dark-field image of TRUTH with the glare added,
    and a frame of the glare alone."""
    d = tmp_path_factory.mktemp("glare")
    library_frames(tiny_library, [TRUTH], d, pixels=PX, pixel_mm=PIXEL_MM, bit_depth=16)
    glare = _glare((PX, PX))
    img = read_pixels(d / "frame_0000.png") / 65535.0
    assert img.max() + glare.max() < 1.0  # nothing saturates
    write_image(d / "lit.png", np.round((img + glare) * 65535).astype(np.uint16))
    write_image(d / "rest.png", np.round(glare * 65535).astype(np.uint16))
    return d / "lit.png", d / "rest.png"


@pytest.mark.slow
def test_invert_takes_a_rest_frame_s_light_off_the_image(tiny_library, glare_image, tmp_path):
    """A dark-field image with a rest light up to 0.17 of full scale: with the rest frame
    as ``--reference`` both contacts come back within 2 um and 2e-3 of their Fz, reliable,
    and ``summary.json`` reports the light taken off. (Without it the glare is read as
    load: ``track``'s rest test measures 0.13 N; a second inverse here would double the
    test's time.)"""
    lit, rest = glare_image
    out = tmp_path / "out"
    args = ["invert", str(lit), "--library", str(tiny_library.folder)]
    args += ["--pixel-mm", str(PIXEL_MM), "--reference", str(rest), "--out", str(out)]
    assert main([*args, "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reference"]["frames"] == [str(rest)]
    assert summary["reference"]["light_max"][0] == pytest.approx(_glare((PX, PX)).max(), abs=2e-3)
    assert summary["reference"]["unknown_px"] == 0
    rows = list(csv.DictReader((out / "loads.csv").open()))
    table = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    err = _errors(table)
    assert len(rows) == 2 and summary["reliable"] == [True, True], rows
    assert np.all(err[:, :2] <= 2e-3) and np.all(err[:, 2:] <= 2e-3 * 3.0), err


@pytest.fixture(scope="module")
def phase_steps(tiny_library, tmp_path_factory):
    """(six steps of TRUTH, six rest steps) paths, 16-bit, in a sheet with a residual of up
    to 0.3 fringe."""
    cfg = load_config(tiny_library.folder / "config.toml")
    blank = blank_model(tiny_library, cfg, (PX, PX), PIXEL_MM, "phase", None, optics_setup(cfg))
    ab = frozen_stress(blank)[2]
    d = tmp_path_factory.mktemp("phase")
    kw = {"pixels": PX, "pixel_mm": PIXEL_MM, "method": "phase", "bit_depth": 16}
    library_frames(tiny_library, [TRUTH], d / "loaded", residual_ab=ab, **kw)
    library_frames(tiny_library, [[]], d / "rest", residual_ab=ab, **kw)
    steps = [d / "loaded" / f"frame_0000_step{k}.png" for k in range(1, 7)]
    rest = [d / "rest" / f"frame_0000_step{k}.png" for k in range(1, 7)]
    return steps, rest


def test_invert_reads_the_six_rest_steps_as_the_sheet_s_residual(tiny_library, phase_steps):
    """Six steps of two contacts in a sheet with a residual of up to 0.3 fringe: with the
    six rest steps as ``reference`` the residual is put into the model and both contacts
    come back within 5 um and 2e-3 of their Fz, reliable; the summary gives the residual's
    largest retardation (0.3 fringe)."""
    steps, rest = phase_steps
    inv = invert(steps, tiny_library, pixel_mm=PIXEL_MM, reference=rest)
    assert inv.summary["method"] == "phase"
    assert inv.summary["reference"]["residual_max_fringe"] == pytest.approx(0.3, abs=0.01)
    assert inv.summary["reference"]["unknown_px"] == 0
    table = inv.table()
    err = _errors(table)
    assert len(table["Fz_N"]) == 2 and table["reliable"].all(), table
    assert np.all(err[:, :2] <= 5e-3) and np.all(err[:, 2:] <= 2e-3 * 3.0), err


@pytest.mark.slow
def test_a_grey_image_reads_the_sheet_s_residual_from_six_rest_steps(
    tiny_library, phase_steps, tmp_path
):
    """A dark-field (mono) image of two contacts in a sheet with a residual of up to 0.3
    fringe, six times what a rest frame's subtraction serves: with the six rest steps as
    ``residual_steps`` the residual is modelled and both contacts come back within 5 um
    and 2e-3 of their Fz, reliable (0.8 um and 0.04 % here, 8 s). Without them the image
    was refused as one the library cannot explain, after 21 s (measured, not tested)."""
    _, rest = phase_steps
    cfg = load_config(tiny_library.folder / "config.toml")
    blank = blank_model(tiny_library, cfg, (PX, PX), PIXEL_MM, "mono", None, optics_setup(cfg))
    kw = {"pixels": PX, "pixel_mm": PIXEL_MM, "bit_depth": 16}
    library_frames(tiny_library, [TRUTH], tmp_path, residual_ab=frozen_stress(blank)[2], **kw)
    inv = invert(tmp_path / "frame_0000.png", tiny_library, pixel_mm=PIXEL_MM, residual_steps=rest)
    assert inv.summary["method"] == "mono"
    assert inv.summary["reference"]["residual_max_fringe"] == pytest.approx(0.3, abs=0.01)
    table = inv.table()
    err = _errors(table)
    assert len(table["Fz_N"]) == 2 and table["reliable"].all(), table
    assert np.all(err[:, :2] <= 5e-3) and np.all(err[:, 2:] <= 2e-3 * 3.0), err


def test_a_bad_reference_is_one_line_and_writes_nothing(
    tiny_library, glare_image, phase_steps, tmp_path, capsys
):
    """Rest frames of another size, five phase rest steps, and ``--residual-steps`` with
    phase, with rgb, three of them, with ``--reference`` or with a calibrated sensor's rest
    map: each refused in one line naming the option; no output folder is made."""
    lit, _ = glare_image
    steps, rest = phase_steps
    small = tmp_path / "small.png"
    write_image(small, np.zeros((PX, PX - 2), np.uint8))
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", str(PIXEL_MM)]
    cfg = load_config(tiny_library.folder / "config.toml")
    sha, middle = tiny_library.manifest["manifest_sha256"], ((PX - 1) / 2,) * 2
    cal = CalibratedSensor(cfg, sha, "mono", (PX, PX), PIXEL_MM, middle, 0.0, 1.0, 1.0, 1.0, (0.0,))
    sensor = replace(cal, rest=np.zeros((8, 8, 1))).save(tmp_path / "sensor.json")
    grey = read_pixels(lit).astype(float)
    colour = tmp_path / "colour.tif"
    write_image(colour, np.stack([grey, 0.9 * grey, 0.8 * grey], -1).astype(np.uint16))
    for images, extra, words in (
        ([lit], ["--reference", str(small)], ["--reference", "small.png", f"{PX} x {PX - 2}"]),
        (steps, ["--reference", *map(str, rest[:5])], ["--reference", "six phase steps", "got 5"]),
        ([colour], ["--residual-steps", *map(str, rest)], ["--residual-steps", "rgb"]),
        (steps, ["--residual-steps", *map(str, rest)], ["--residual-steps", "--method phase"]),
        ([lit], ["--residual-steps", *map(str, rest[:3])], ["--residual-steps", "got 3"]),
        (
            [lit],
            ["--reference", str(lit), "--residual-steps", *map(str, rest)],
            ["--residual-steps with --reference"],
        ),
        (
            [lit],
            ["--sensor", str(sensor), "--residual-steps", *map(str, rest)],
            ["--residual-steps with a calibrated --sensor"],
        ),
    ):
        out = tmp_path / "out"
        code = main(["invert", *map(str, images), *lib, *extra, "--out", str(out), "--quiet"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1, err
        assert all(w in err[0] for w in words), err
        assert not out.exists()


def test_six_steps_given_as_a_dark_field_rest_are_warned_of(tiny_library):
    """Phase steps of the rest average about half of full scale, which a dark field at
    rest never does: given as a mono ``--reference`` they are warned of, naming
    ``--residual-steps``; a dark rest is not."""
    cfg = load_config(tiny_library.folder / "config.toml")
    optics, measured, usable = optics_setup(cfg), np.full((16, 1), 0.3), np.ones(16, bool)
    for level, warned in ((0.5, True), (0.05, False)):
        rest = RestFrames((np.full((4, 4), level),), ("rest.png",))
        *_, warnings = take_rest(rest, "mono", measured, usable, (4, 4), optics)
        assert (len(warnings) == 1 and "--residual-steps" in warnings[0]) == warned, warnings


def test_a_green_light_photograph_s_rest_is_read_in_its_channel(tmp_path):
    """A colour photograph of green light read by mono is read in its green channel
    (``Measurement.channel``), and so is its colour rest frame, whose red glare (0.5 of full
    scale) would otherwise be taken off: the light taken off is the rest's green, 0.1."""
    r, c = np.mgrid[:16, :16] / 15.0
    photo = np.zeros((16, 16, 3))
    photo[..., 1] = 0.2 + 0.6 * r * c  # the fringes, in green
    photo[..., 0] = 0.02
    rest = np.stack([np.full((16, 16), v) for v in (0.5, 0.1, 0.05)], -1)
    for name, im in (("photo.tif", photo), ("rest.tif", rest)):
        write_image(tmp_path / name, np.round(im * 65535).astype(np.uint16))
    meas = read_measurement([tmp_path / "photo.tif"], "mono", "none")
    assert meas.channel == 1
    optics = optics_setup(load_config("small"))
    rest = RestFrames.read([tmp_path / "rest.tif"])
    args = (meas.linear, meas.usable, meas.shape, optics, None, meas.channel)
    got, usable, ab, summary, _ = take_rest(rest, "mono", *args)
    assert ab is None and summary["light_max"][0] == pytest.approx(0.1, abs=1e-4)
    assert np.allclose(got[:, 0], photo[..., 1].ravel() - 0.1, atol=1e-4) and usable.all()
