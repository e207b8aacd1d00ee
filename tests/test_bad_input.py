"""Bad input at the command line: one line naming the option or file, the value and what
is allowed; exit 2; no traceback; nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fringekit.cli.main import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A valid order map, a few broken files and a broken calibration."""
    d = tmp_path_factory.mktemp("bad")
    order = np.fromfunction(lambda r, c: np.hypot(r - 31.5, c - 31.5) / 10, (64, 64))
    np.savez(d / "maps.npz", fringe_order=order, pixel_size_m=np.array(1e-4))
    np.savez(d / "noorder.npz", something=np.zeros(3))
    np.save(d / "pickled.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    (d / "pickled.npy").rename(d / "pickled.npz")
    (d / "garbage.npz").write_bytes(b"\x00\x01 not a zip at all")
    (d / "empty.png").write_bytes(b"")
    (d / "text.png").write_text("this is not an image\n")
    cal = {"version": 2, "normal_fits": {"order_at_2mm": {"a": "x", "b": 1.0, "sigma_logF": 0.1}}}
    (d / "cal.json").write_text(json.dumps(cal))
    (d / "nofits.json").write_text(json.dumps({"version": 2, "normal_fits": {}}))
    good = {"a": 1.0, "b": 1.5, "sigma_logF": 0.1, "n": 5, "range": [0.1, 5.0]}
    (d / "good.json").write_text(json.dumps({"version": 2, "normal_fits": {"order_at_2mm": good}}))
    return d


CASES = [
    (["analyze", "{d}/empty.png", "--out", "{o}"], "empty.png: not a readable"),
    (["analyze", "{d}/text.png", "--out", "{o}"], "text.png: not a readable"),
    (["analyze", "{d}/text.png", "--pixel-mm", "0", "--out", "{o}"], "argument --pixel-mm: 0"),
    (["analyze", "{d}/text.png", "--pixel-mm", "-1", "--out", "{o}"], "argument --pixel-mm: -1"),
    (["analyze", "{d}/text.png", "--pixel-mm", "nan", "--out", "{o}"], "argument --pixel-mm: nan"),
    (["analyze", "{d}/text.png", "--max-order", "-1", "--out", "{o}"], "argument --max-order"),
    (["analyze", "{d}/text.png", "--min-modulation", "2", "--out", "{o}"], "--min-modulation"),
    (
        ["compare", "{d}/maps.npz", "{d}/maps.npz", "--predicted-pixel-mm", "0", "--out", "{o}"],
        "argument --predicted-pixel-mm: 0",
    ),
    (["compare", "{d}/noorder.npz", "{d}/maps.npz", "--out", "{o}"], "holds no fringe_order"),
    (["compare", "{d}/garbage.npz", "{d}/maps.npz", "--out", "{o}"], "garbage.npz: not a maps"),
    (["compare", "{d}/pickled.npz", "{d}/maps.npz", "--out", "{o}"], "pickled.npz: not a maps"),
    (
        ["estimate", "{d}/noorder.npz", "--calibration", "{d}/good.json", "--out", "{o}"],
        "holds no fringe_order",
    ),
    (
        [
            "estimate",
            "{d}/maps.npz",
            "--calibration",
            "{d}/cal.json",
            "--centre",
            "31.5",
            "31.5",
            "--out",
            "{o}",
        ],
        "normal_fits.order_at_2mm.a = 'x'",
    ),
    (
        [
            "estimate",
            "{d}/maps.npz",
            "--calibration",
            "{d}/nofits.json",
            "--centre",
            "31.5",
            "31.5",
            "--out",
            "{o}",
        ],
        "the calibration has no fit",
    ),
    (
        [
            "estimate",
            "{d}/maps.npz",
            "--calibration",
            "{d}/good.json",
            "--centre",
            "-5",
            "-5",
            "--out",
            "{o}",
        ],
        "--centre -5 -5 is outside the map",
    ),
    (
        [
            "calibrate",
            "--disc",
            "{d}/garbage.npz",
            "--load-N",
            "300",
            "--diameter-mm",
            "40",
            "--thickness-mm",
            "5",
            "--out",
            "{o}",
        ],
        "garbage.npz: not a maps",
    ),
    (
        [
            "calibrate",
            "--disc",
            "{d}/maps.npz",
            "--load-N",
            "0",
            "--diameter-mm",
            "40",
            "--thickness-mm",
            "5",
            "--out",
            "{o}",
        ],
        "argument --load-N: 0",
    ),
    (["sweep", "{d}/none.toml", "--workers", "0"], "argument --workers: 0"),
]


@pytest.mark.parametrize(("args", "message"), CASES, ids=[" ".join(c[0][:2]) for c in CASES])
def test_bad_input_is_one_line_and_writes_nothing(files, tmp_path, capsys, args, message):
    out = tmp_path / "out"
    argv = [a.format(d=files, o=out) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_a_profile_line_outside_the_image_writes_nothing(tmp_path, capsys):
    import imageio.v3 as iio

    img = (np.random.default_rng(0).random((32, 32, 3)) * 255).astype(np.uint8)
    iio.imwrite(tmp_path / "w.png", img)
    out = tmp_path / "out"
    argv = ["analyze", str(tmp_path / "w.png"), "--line", "0", "0", "40", "40", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "--line end (40, 40) is outside the image" in err and "np.float64" not in err
    assert len(err.splitlines()) == 1 and not out.exists()
