"""The Python API: one import name, computing apart from writing, and the same answers as
the ``fringekit`` command (which is a thin layer over it)."""

from __future__ import annotations

import csv
import importlib.metadata
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from library_fixtures import sensor_config

import fringekit
from fringekit.cli import main
from fringekit.config.inputs import optics_setup
from fringekit.errors import (
    ComputeError,
    ConfigError,
    FringekitError,
    InputError,
    Interrupted,
    LibraryError,
    RefusedError,
)
from fringekit.fea import SolveInterrupted, SolverError
from fringekit.inversion import LOAD_COLUMNS
from fringekit.library import LoadedIndenter
from fringekit.library.synth import synthesise
from fringekit.meshes import MeshQualityError
from fringekit.optics import Camera, dark_field_circular, monochrome_image, write_image
from fringekit.prediction.render import no_data_fill

ROOT = Path(__file__).resolve().parents[1]

# The small block of conftest.py, 32 x 32 pixels: the whole pipeline in seconds.
TINY = {
    "case": "tiny",
    "sheet": {"width_mm": 12, "length_mm": 12},
    "substrate": {"thickness_mm": 4},
    "mesh": {
        "h_contact_mm": 0.6,
        "refine_radius_mm": 1.5,
        "h_sheet_mm": 1.5,
        "h_far_mm": 3,
        "growth": 0.5,
    },
    "optics": {
        "field_of_view_mm": 10,
        "pixels": 32,
        "samples_per_ray": 24,
        "white_light_wavelengths": 7,
    },
    "indenter": [{"load_N": [8.0]}],
}


def test_one_version_and_every_exported_name_exists():
    assert fringekit.__version__ == importlib.metadata.version("fringekit")
    missing = [n for n in fringekit.__all__ if not hasattr(fringekit, n)]
    assert not missing, missing
    assert len(set(fringekit.__all__)) == len(fringekit.__all__)


def test_every_error_is_a_fringekit_error_of_one_family():
    assert all(issubclass(e, InputError) for e in (ConfigError, LibraryError))
    assert issubclass(fringekit.InvertError, RefusedError)
    assert not issubclass(fringekit.InvertError, InputError)  # an image is no config mistake
    for e in (SolverError, MeshQualityError, fringekit.PredictError):
        assert issubclass(e, ComputeError)
    assert issubclass(SolveInterrupted, Interrupted)
    for e in (InputError, RefusedError, ComputeError):
        assert issubclass(e, FringekitError)


def test_a_config_is_checked_when_built_and_when_changed(tmp_path):
    ref = fringekit.Config.reference()
    assert ref.case == "reference" and ref["sheet.thickness_mm"] == 3.0
    assert ref["indenter[0].diameter_mm"] == 3.5
    with pytest.raises(KeyError):
        ref["sheet.no_such_key"]
    changed = ref.replace({"sheet.E_MPa": 5.0, "indenter.load_N": [2.0, 4.0]})
    assert changed["sheet.E_MPa"] == 5.0 and ref["sheet.E_MPa"] == 4.0  # frozen
    assert changed["indenter.load_N"] == [2.0, 4.0]
    with pytest.raises(ConfigError, match=r"sheet\.E_MPa = -2"):
        ref.replace({"sheet.E_MPa": -2})
    with pytest.raises(ConfigError, match="no_table"):
        fringekit.Config.from_dict({"no_table": {}})
    # TOML round trip, and a dict gives the same config as the file
    path = tmp_path / "mine.toml"
    path.write_text(changed.to_toml())
    again = fringekit.Config.from_toml(path)
    assert again.data == dict(changed.data, case="reference")
    assert fringekit.Config.from_dict(TINY) == fringekit.Config.from_dict(
        fringekit.Config.from_dict(TINY).data
    )
    assert fringekit.Config.builtin("shear")["contact.friction"] == "stick"


@pytest.fixture(scope="module")
def tiny(cache_dir, tmp_path_factory):
    """The tiny case by the API (written nowhere) and by the command."""
    pred = fringekit.predict(TINY, cache_dir=cache_dir)
    out = tmp_path_factory.mktemp("cli") / "tiny"
    cfg = tmp_path_factory.mktemp("cfg") / "tiny.toml"
    cfg.write_text(fringekit.Config.from_dict(TINY).to_toml())
    assert (
        main(["predict", str(cfg), "--out", str(out), "--cache-dir", str(cache_dir), "--quiet"])
        == 0
    )
    return pred, out


def test_predict_computes_and_write_gives_the_command_s_folder(tiny, tmp_path):
    pred, cli_out = tiny
    assert pred.status == "ok" and len(pred.states) == 1 and len(pred.solutions) == 1
    rs = pred.states[0]
    assert rs.fringe_order.shape == (32, 32) and rs.white_light.shape == (32, 32, 3)
    assert set(rs.six_step) == {f"step{k}" for k in range(1, 7)}
    assert pred.summary["max_fringe_order"] == pytest.approx(rs.max_fringe_order)
    folder = pred.write(tmp_path / "api")
    ours, theirs = sorted(folder.rglob("*")), sorted(cli_out.rglob("*"))
    names = {p.relative_to(cli_out) for p in theirs if not p.name.startswith(".")}
    assert {p.relative_to(folder) for p in ours} == names
    a, b = np.load(folder / "state_01" / "maps.npz"), np.load(cli_out / "state_01" / "maps.npz")
    assert all(np.array_equal(a[k], b[k], equal_nan=True) for k in b.files)
    sa = json.loads((folder / "summary.json").read_text())
    sb = json.loads((cli_out / "summary.json").read_text())
    assert sa["indenters"] == sb["indenters"] and sa["config"] == sb["config"]
    for name in ("dark_field.png", "white_light.png", "six_step/step3.png"):
        assert (folder / "state_01" / name).read_bytes() == (
            cli_out / "state_01" / name
        ).read_bytes()


def test_analyze_reads_back_the_prediction_and_matches_the_command(tiny, tmp_path):
    pred, cli_out = tiny
    steps = [cli_out / "state_01" / "six_step" / f"step{k}.png" for k in range(1, 7)]
    pixel_mm = 10 / 32
    region = fringekit.Region(exclude_circles=[(15.5, 15.5, 6)])  # the contact zone
    an = fringekit.analyze(steps, pixel_mm=pixel_mm, region=region)
    assert an.method == "phase" and an.fringe_order.shape == (32, 32)
    ok = an.reliable & np.isfinite(pred.states[0].fringe_order)
    assert ok.sum() > 0.5 * ok.size
    # 8-bit camera images of a coarse 32-pixel map: the order back where reliable
    err = np.abs(an.fringe_order - pred.states[0].fringe_order)[ok]
    assert np.median(err) < 0.02 and np.percentile(err, 95) < 0.1, np.percentile(err, [50, 95])
    out = tmp_path / "an"
    argv = [
        "analyze",
        *map(str, steps),
        "--pixel-mm",
        str(pixel_mm),
        "--out",
        str(out),
        "--exclude-circle",
        "15.5",
        "15.5",
        "6",
        "--quiet",
    ]
    assert main(argv) == 0
    b = np.load(out / "maps.npz")
    assert np.array_equal(b["fringe_order"], an.fringe_order, equal_nan=True)
    with pytest.raises(InputError, match="MonoOptions"):
        fringekit.analyze(steps, options=fringekit.MonoOptions())


@pytest.mark.slow
def test_invert_gives_the_command_s_loads_as_a_table(test_library, tmp_path):
    cfg = sensor_config()
    opt = optics_setup(cfg)
    ind = LoadedIndenter(x=0.4e-3, y=-0.3e-3, diameter=3.5e-3, fz=3.0, fx=0.5, fy=0.0)
    sm = synthesise(test_library, [ind], opt.grid, opt.law, [opt.law.wavelength_ref])
    img = monochrome_image(sm.q[:, :, 0], dark_field_circular(), Camera(), seed=0)
    path = tmp_path / "image.png"
    write_image(path, no_data_fill(img, sm.mask))
    pixel_mm = cfg["optics"]["field_of_view_mm"] / cfg["optics"]["pixels"]
    inv = fringekit.invert(path, test_library.folder, pixel_mm=pixel_mm)
    t = inv.table()
    assert list(t)[:12] == list(LOAD_COLUMNS)
    assert len(t["Fz_N"]) == 1 and t["reliable"].all()
    assert t["Fz_N"][0] == pytest.approx(3.0, rel=0.03)
    assert (t["x_mm"][0], t["y_mm"][0]) == pytest.approx((0.4, -0.3), abs=0.05)
    out = tmp_path / "inv"
    argv = [
        "invert",
        str(path),
        "--library",
        str(test_library.folder),
        "--pixel-mm",
        str(pixel_mm),
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(argv) == 0
    with open(out / "loads.csv") as f:
        row = next(csv.DictReader(f))
    assert float(row["Fz_N"]) == pytest.approx(t["Fz_N"][0], rel=1e-5)
    with pytest.raises(InputError, match="--pixel-mm"):
        fringekit.invert(path, test_library, pixel_mm=-1.0)


@pytest.mark.slow
def test_the_wheel_installs_one_package(tmp_path):
    """``pip install .`` puts ``fringekit`` into site-packages and nothing else of ours:
    the stages' folders are mapped into it (pyproject's package-dir)."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    for name in ("fringekit", "meshes", "fea", "optics", "analysis"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path / "dist"),
            str(src),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = (tmp_path / "dist").glob("fringekit-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"fringekit", f"fringekit-{fringekit.__version__}.dist-info"}, tops
    for stage in ("meshes", "fea", "optics", "analysis"):
        assert f"fringekit/{stage}/__init__.py" in names
    assert "fringekit/cli/main.py" in names and "fringekit/_threads.py" in names


def test_the_rgb_method_reads_its_colour_table_from_a_file(tiny, tmp_path):
    """``--colour-table`` (``RGBOptions.colour_table``): the rgb method's colour calibration
    table from a CSV, the same for the API and the command; a missing file is named."""
    from fringekit.analysis import CalibrationTable
    from fringekit.optics import PSM4_ASSUMED, colour_chart, light_source

    _, cli_out = tiny
    image = cli_out / "state_01" / "white_light.png"
    lam = PSM4_ASSUMED.wavenumber_grid(31)
    orders, rgb = colour_chart(PSM4_ASSUMED, light_source("LED", lam), Camera(), max_order=4.0)
    table = tmp_path / "table.csv"
    CalibrationTable.from_chart(orders, np.clip(rgb * 0.9, 0, 1)).to_csv(table)
    an = fringekit.analyze(
        image,
        pixel_mm=10 / 32,
        region=fringekit.Region(exclude_circles=[(15.5, 15.5, 6)]),
        options=fringekit.RGBOptions(colour_table=str(table), seeds=[(0.0, 0.0, 0.03)]),
    )
    assert an.method == "rgb" and an.summary["rgb"]["table"] == str(table)
    assert an.summary["rgb"]["rows"] == len(orders)
    out = tmp_path / "cli"
    argv = [
        "analyze",
        str(image),
        "--method",
        "rgb",
        "--colour-table",
        str(table),
        "--seed",
        "0",
        "0",
        "0.03",
        "--exclude-circle",
        "15.5",
        "15.5",
        "6",
        "--pixel-mm",
        str(10 / 32),
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(argv) == 0
    assert np.array_equal(
        np.load(out / "maps.npz")["fringe_order"], an.fringe_order, equal_nan=True
    )
    missing = tmp_path / "no" / "table.csv"
    with pytest.raises(FileNotFoundError, match="table.csv"):
        fringekit.analyze(image, options=fringekit.RGBOptions(colour_table=str(missing)))


def test_numpy_numbers_are_config_values_and_messages_show_no_repr():
    cfg = fringekit.Config.reference().replace(
        {"optics.pixels": np.int64(64), "sheet.E_MPa": np.float64(5.0)}
    )
    assert cfg["optics.pixels"] == 64 and type(cfg["optics.pixels"]) is int
    with pytest.raises(ConfigError) as exc:
        cfg.replace({"sheet.E_MPa": np.float64(-1.0)})
    assert str(exc.value).startswith("sheet.E_MPa = -1.0 is not allowed")
    assert "np." not in str(exc.value) and "float64" not in str(exc.value)


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: fringekit.PhaseOptions(fold="x"), ["--fold x", "count or isoclinic"]),
        (lambda: fringekit.PhaseOptions(min_modulation=1.5), ["--min-modulation 1.5"]),
        (lambda: fringekit.MonoOptions(field="grey"), ["--field grey", "dark or bright"]),
        (lambda: fringekit.MonoOptions(smooth_px=-1), ["--smooth-px -1"]),
        (lambda: fringekit.RGBOptions(window=0), ["--window 0", "> 0"]),
        (lambda: fringekit.analyze("a.png", pixel_mm=-0.1), ["--pixel-mm -0.1"]),
        (
            lambda: fringekit.analyze("a.png", fringe_value_N_per_m=386, thickness_mm=1e-300),
            ["thickness_mm = 1e-300", "[0.01, 100] mm", "sheet.thickness_mm"],
        ),
        (
            lambda: fringekit.analyze("a.png", fringe_value_N_per_m=1e300, thickness_mm=3),
            ["fringe_value_N_per_m = 1e+300", "(0, 1e+08] N/m", "optics.f_sigma_N_per_m"],
        ),
        (lambda: fringekit.Region(exclude_polygons=[[(1, 1)]]), ["--exclude-polygon 1,1"]),
    ],
)
def test_api_options_are_checked_when_given(make, words):
    with pytest.raises(InputError) as exc:
        make()
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_a_two_vertex_exclusion_is_a_line_three_pixels_wide():
    (band,) = fringekit.Region(exclude_polygons=[[(10, 10), (20, 10)]]).exclude_polygons
    assert band == ((10.0, 11.5), (20.0, 11.5), (20.0, 8.5), (10.0, 8.5))


def test_a_failed_prediction_keeps_its_converged_part(cache_dir, tmp_path):
    cfg = fringekit.Config.from_dict(TINY).replace(
        {"solver.max_iterations": 2, "solver.max_cutbacks": 0}
    )
    with pytest.raises(fringekit.PredictError) as exc:
        fringekit.predict(cfg, cache_dir=cache_dir, use_cache=False)
    assert exc.value.prediction.status == "failed" and not exc.value.prediction.solutions
    # the command's back-end writes it and raises the same, with the prediction attached
    from fringekit.prediction.pipeline import run_predict

    with pytest.raises(fringekit.PredictError) as exc:
        run_predict(cfg, tmp_path / "out", cache_dir=cache_dir, use_cache=False, progress=False)
    assert exc.value.prediction is not None and exc.value.__cause__ is not None
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["status"] == "failed"


def test_an_all_nan_tiff_is_one_line_and_writes_nothing(tmp_path, capsys):
    import tifffile

    tifffile.imwrite(tmp_path / "nan.tif", np.full((16, 16), np.nan, np.float32))
    out = tmp_path / "out"
    assert main(["analyze", str(tmp_path / "nan.tif"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "nan.tif: the image holds no finite value" in err
    assert not out.exists()
