"""Resources and hangs (issue 36): requests whose arrays need more memory than a machine
has are refused before any work, naming the option, its value and the estimate; invert
reports its stages, keeps to a time budget and refuses a pixel pitch its fringes
contradict before fitting.

The memory cases ask for petabytes or terabytes (no machine the tests run on has them),
so they do not depend on the machine; the time budget reads an injected clock at its
safe points only, so it does not depend on the machine's speed either.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from cli_checks import refused
from library_fixtures import TINY, sensor_config

import fringekit
from fringekit.cli import main
from fringekit.config.inputs import optics_setup
from fringekit.inversion.model import ImageModel
from fringekit.library.store import LoadedIndenter
from fringekit.optics import Camera, write_image
from fringekit.prediction.render import no_data_fill

#: The tiny library's images: 48 px over 12 mm.
PITCH_MM = 0.25


@pytest.fixture(scope="module")
def image(tiny_library, tmp_path_factory):
    """A grey (dark-field) library image of one sheared indenter at PITCH_MM per pixel."""
    opt = optics_setup(sensor_config(**TINY))
    n = opt.grid.n_pixels
    blank = ImageModel.build(
        tiny_library, opt.grid, "mono", np.zeros((n, 1)), np.ones(n, bool), opt
    )
    lin, outside = blank.linear([LoadedIndenter(-1.0e-3, 0.5e-3, 3.5e-3, 0.5, -0.4, 3.0)])
    img = Camera(sensitivities="mono").encode((0.8 * lin + 0.02).reshape(opt.grid.shape))
    path = tmp_path_factory.mktemp("image") / "one.png"
    write_image(path, no_data_fill(img, outside.reshape(img.shape)))
    return path


MEMORY = [
    # (argv after the command's inputs, words the one line must hold)
    (["library", "build", "small", "--slabs", "1000000000"], ["--slabs 1000000000", "states"]),
    (["mesh", "small", "--h-contact-mm", "0.0001"], ["mesh.h_contact_mm = 0.0001", "tets"]),
    (
        [
            "predict",
            "small",
            *("--set", "mesh.symmetry=full"),
            *("--set", "optics.pixels=4096", "--set", "optics.samples_per_ray=4096"),
            *("--set", "optics.include_substrate=true"),
            *("--set", "optics.substrate_samples_per_ray=4096"),
        ],
        ["optics.pixels = 4096", "optics.samples_per_ray = 4096", "ray samples"],
    ),
]


@pytest.mark.parametrize("argv,words", MEMORY, ids=[m[0][0] for m in MEMORY])
def test_a_request_larger_than_memory_is_refused_before_work(
    argv, words, image, tiny_library, tmp_path, capsys
):
    out = tmp_path / "out"
    argv = [a.format(image=image, library=tiny_library.folder) for a in argv]
    err = refused([*argv, "--out", str(out)], capsys, [*words, "needs about"], out)
    assert re.search(r"needs about [\d.]+ [TPE]iB .*this machine has [\d.]+ \w+ free", err), err


def test_the_api_checks_memory_where_the_options_range_does_not_reach(image, tiny_library):
    """On the command line --smooth-px and --pixel-mm are held to their ranges (at most
    100 px, at least 0.0001 mm); the Python API takes any positive number, and refuses
    the ones whose arrays would not fit (--smooth-px 1e12 failed with MemoryError)."""
    with pytest.raises(
        fringekit.InputError, match=r"--smooth-px 1e\+12 needs about [\d.]+ [TPE]iB"
    ):
        fringekit.analyze(image, method="mono", options=fringekit.MonoOptions(smooth_px=1e12))
    with pytest.raises(fringekit.InputError, match=r"--pixel-mm 1e-12 needs about .*detection"):
        fringekit.invert(image, tiny_library, pixel_mm=1e-12)


@pytest.mark.parametrize(
    "argv, word",
    [
        (["analyze", "{image}", "--method", "mono", "--smooth-px", "1e12"], "--smooth-px"),
        (["invert", "{image}", "--library", "{library}", "--pixel-mm", "1e-12"], "--pixel-mm"),
    ],
)
def test_the_command_line_holds_those_options_to_their_ranges(
    argv, word, image, tiny_library, tmp_path, capsys
):
    out = tmp_path / "out"
    argv = [a.format(image=image, library=tiny_library.folder) for a in argv]
    refused([*argv, "--out", str(out)], capsys, [word, "allowed range"], out)


def test_the_estimates_follow_the_sizes():
    from fringekit._memory import check_memory, gaussian_bytes, size_text

    assert gaussian_bytes(2.0) == 3 * 17 * 8  # 2 * 8 + 1 taps
    assert size_text(17.5 * 2**40) == "17.5 TiB"
    check_memory(2.0**30, "a grid", "--x 1", free=2**31)  # fits: nothing to say
    with pytest.raises(fringekit.InputError, match=r"^--x 1 needs about 1 GiB for a grid"):
        check_memory(2.0**30, "a grid", "--x 1", free=2**20)


def test_a_scale_the_fringes_contradict_is_refused_before_the_fit(
    image, tiny_library, tmp_path, capsys
):
    """An image at 0.25 mm per pixel, inverted at 2 (and at 0.03): refused in one line
    naming --pixel-mm, its value and the pitch the fringes suggest (the fit ran on past
    120 s at 2 before); the right pitch passes the check."""
    out = tmp_path / "out"
    base = ["invert", str(image), "--library", str(tiny_library.folder), "--out", str(out)]
    for wrong in ("2", "0.03"):
        argv = [*base, "--pixel-mm", wrong, "--max-seconds", "60"]
        err = refused(argv, capsys, [f"--pixel-mm {wrong} contradicts the fringes"], out)
        lo, hi = map(float, re.search(r"at about ([\d.]+)-([\d.]+) mm per pixel", err).groups())
        assert lo / 1.5 <= PITCH_MM <= hi * 1.5, err  # a coarse measure: within 1.5 times
    inv = fringekit.invert(image, tiny_library, pixel_mm=PITCH_MM)
    lo, hi = inv.summary["scale_check"]["pixel_mm_range"]
    assert lo / 1.5 <= PITCH_MM <= hi * 1.5 and len(inv.table()["Fz_N"]) == 1


class Ticks:
    """A clock that advances one second each time it is read."""

    def __init__(self):
        self.t = -1.0

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


# (budget in ticks, the stage after which the fit stops): the clock is read once when
# the budget starts and once at the end of each stage
BUDGETS = [(0.0, "detection"), (1.5, "start scan"), (2.5, "far fit"), (3.5, "near fit")]


@pytest.mark.parametrize("max_seconds,stage", BUDGETS)
def test_the_time_budget_stops_after_a_stage_and_flags_the_answer(
    image, tiny_library, max_seconds, stage
):
    lines = []
    inv = fringekit.invert(
        image,
        tiny_library,
        pixel_mm=PITCH_MM,
        max_seconds=max_seconds,
        clock=Ticks(),
        progress=True,
        echo=lines.append,
    )
    s = inv.summary
    assert s["stopped_after"] == stage and s["reliable"] == [False], s
    assert not inv.table()["reliable"].any()
    assert any(
        f"--max-seconds {max_seconds:g} ran out after the {stage}" in w for w in s["warnings"]
    )
    assert any(line.startswith(f"invert: {stage}") for line in lines), lines
    fz = inv.table()["Fz_N"]
    assert len(fz) == 1 and (np.isnan(fz[0]) if stage == "detection" else abs(fz[0] - 3) < 1)


def test_invert_reports_its_stages_and_a_spent_budget_exits_1_with_the_answer(
    image, tiny_library, tmp_path, capsys
):
    out = tmp_path / "out"
    base = ["invert", str(image), "--library", str(tiny_library.folder), "--out", str(out)]
    assert main([*base, "--pixel-mm", str(PITCH_MM)]) == 0
    said = capsys.readouterr()
    for stage in ("scale check", "detection", "start scan", "far fit", "near fit", "basin search"):
        assert f"invert: {stage}" in said.out, said.out
    assert json.loads((out / "summary.json").read_text())["stopped_after"] is None
    assert main([*base, "--pixel-mm", str(PITCH_MM), "--max-seconds", "0", "--quiet"]) == 1
    said = capsys.readouterr()
    assert said.out == "" and "--max-seconds 0 ran out after the detection" in said.err
    s = json.loads((out / "summary.json").read_text())
    assert s["stopped_after"] == "detection" and s["reliable"] == [False]
    assert s["residual_rms"] == [None]  # no fit: strict JSON, no NaN
    assert (out / "loads.csv").read_text().count("\n") == 2  # the header and the candidate
    assert (out / "fit.png").exists()
