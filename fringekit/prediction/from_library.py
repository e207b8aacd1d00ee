"""``fringekit predict --library DIR``: a config's fringes from a library, without FEM.

Each indenter's final load state (``load_N[-1]``, ``shear_N[-1]``) is synthesised from
the library (:mod:`fringekit.library.synth`) on the config's pixel grid, and written as
``predict`` writes a rendered state: ``state_01/maps.npz``, ``six_step/step1..6.png``,
``dark_field.png``, ``white_light.png``, ``mask.png``, ``fringe_order.png``, plus
``summary.json`` (``"source": "library"`` and the library's measured accuracy) and
``config.toml``.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from fringekit.config.files import ConfigError, to_toml
from fringekit.config.inputs import check_layout, optics_setup
from fringekit.library.calibrated import as_calibrated
from fringekit.library.store import LoadedIndenter, check_sensor, load_library
from fringekit.library.synth import quaternions_where, superpose, synthesise
from fringekit.optics import (
    OpticalMap,
    PixelGrid,
    dark_field_circular,
    intensity,
    light_source,
    six_step_arrangements,
    white_light_matrix,
    write_image,
)
from fringekit.output.folders import claim_output
from fringekit.prediction.render import (
    grid_figure,
    monochrome_images,
    white_light,
    write_maps,
    write_monochrome,
    write_white_light,
)

__all__ = [
    "ACCURACY_NOTE",
    "camera_frame",
    "camera_linear",
    "config_indenters",
    "file_values",
    "run_library_predict",
]

#: What docs/library.md measured (stated in every summary).
ACCURACY_NOTE = (
    "library synthesis: superposed single-indenter fields; see docs/library.md for the "
    "measured fringe-order error against full FEM solves"
)


def config_indenters(cfg: dict, lib) -> list[LoadedIndenter]:
    """The config's indenters at their final load state; loads the library cannot give
    are a one-line ConfigError, and so are heads off the sheet or overlapping (the checks
    of FEM ``predict``)."""
    check_layout(cfg)
    out = []
    for i, d in enumerate(cfg["indenter"]):
        if d["load_N"] is None:
            raise ConfigError(f"indenter[{i}].depth_mm: a library takes loads (load_N), not depths")
        fz = float(d["load_N"][-1])
        fx, fy = d["shear_N"][-1] if d["shear_N"] else (0.0, 0.0)
        if lib.nearest_diameter(d["diameter_mm"]) is None:
            raise ConfigError(
                f"indenter[{i}].diameter_mm = {d['diameter_mm']} is not in the "
                f"library (it holds {lib.diameters_mm} mm)"
            )
        if not lib.in_range(fz, np.hypot(fx, fy) / max(fz, 1e-12)):
            raise ConfigError(
                f"indenter[{i}]: load {fz:g} N with tangential ({fx:g}, {fy:g}) N is outside "
                f"the library (normal up to {lib.max_load_N:g} N, tangential up to "
                f"{lib.max_ratio:g} of it)"
            )
        out.append(
            LoadedIndenter(
                d["x_mm"] * 1e-3,
                d["y_mm"] * 1e-3,
                d["diameter_mm"] * 1e-3,
                float(fx),
                float(fy),
                fz,
            )
        )
    return out


def _render(cfg, lib, inds, d: Path, cal=None) -> dict:
    o = cfg["optics"]
    opt = optics_setup(cfg) if cal is None else cal.optics(optics_setup(cfg))
    d.mkdir(parents=True)
    # one superposition for the reference wavelength (maps, grey images) and white light
    lam = opt.law.wavenumber_grid(o["white_light_wavelengths"])
    sm = synthesise(lib, inds, opt.grid, opt.law, np.concatenate([[opt.law.wavelength_ref], lam]))
    omap = OpticalMap(
        grid=opt.grid,
        wavelengths=sm.wavelengths[:1],
        q=sm.q[:, :, :1],
        simple_order=np.where(sm.mask, sm.simple_order, np.nan),
        mask=sm.mask,
        reflection=True,
        law=opt.law,
    )
    order = omap.fringe_order()
    maps = {
        "fringe_order": order,
        "branch_ambiguous": omap.branch_ambiguous(),
        "simple_order": omap.simple_order,
        "isoclinic_rad": np.where(omap.mask, omap.principal_angle(), np.nan),
        "mask": omap.mask,
    }
    axes_rc = [opt.grid.xy_to_pixel(i.x, i.y) for i in inds]  # each axis at first touch
    write_maps(d, opt.grid, maps, axes_rc, opt.law.wavelength_ref)
    write_monochrome(d, *monochrome_images(sm.q[:, :, 0], cfg, opt, sm.mask), sm.mask)
    write_white_light(d, white_light(sm.q[:, :, 1:], lam, cfg, opt, sm.mask), opt)
    title = f"fringe order at {o['wavelength_nm']:g} nm (library)"
    grid_figure(d / "fringe_order.png", order, opt.grid, title, "fringe order", "turbo")
    valid = np.isfinite(order)
    return {
        "state": 1,
        "folder": d.name,
        "max_fringe_order": float(np.nanmax(order)) if valid.any() else None,
    }


def camera_linear(cfg: dict, lib, inds, cal) -> np.ndarray:
    """Linear intensities (rows, cols, C) of ``inds`` (the sheet's axes; ``lib`` already
    scaled to the sheet) on the calibrated sensor ``cal``'s pixels: the library's image in
    the image's axes through the method's optics (the white light's camera matrix for
    rgb), before illumination and exposure."""
    opt = cal.optics(optics_setup(cfg))
    grid = PixelGrid.about_origin(cal.shape, cal.pixel_mm * 1e-3, cal.origin_px)
    t = np.radians(cal.rotation_deg)
    c, s = np.cos(t), np.sin(t)
    turned = [
        replace(
            i,
            x=c * i.x - s * i.y,
            y=s * i.x + c * i.y,
            fx=c * i.fx - s * i.fy,
            fy=s * i.fx + c * i.fy,
        )
        for i in inds
    ]
    arr = dark_field_circular(**opt.errors)
    if cal.method == "rgb":
        lam = opt.law.wavenumber_grid(cfg["optics"]["white_light_wavelengths"])
        q = synthesise(lib, turned, grid, opt.law, lam).q
        light = light_source(cfg["optics"]["light"], lam)
        return intensity(q, arr) @ white_light_matrix(light, opt.camera)
    lam = np.array([opt.law.wavelength_ref])
    if cal.method == "phase":  # the six steps, the sheet's residual retarder in series
        return _steps_linear(lib, turned, grid, opt.law, cal, six_step_arrangements(**opt.errors))
    if cal.residual is not None:  # a grey sensor calibrated with six rest steps
        return _steps_linear(lib, turned, grid, opt.law, cal, [arr])
    q = synthesise(lib, turned, grid, opt.law, lam).q
    return intensity(q[:, :, 0], arr)[..., None]


def _steps_linear(lib, inds, grid, law, cal, arrangements) -> np.ndarray:
    """The linear intensities (rows, cols, A) of ``inds`` (the image's axes) through A
    ``arrangements`` (the six steps, or the dark field), the calibrated sensor's residual
    retarder added to every ray's slabs in equal parts (a stress frozen evenly through
    the sheet, as the inverse's model holds it), every ray integrated slab by slab."""
    xy = grid.xy()
    ab, _ = superpose(lib, inds, xy)
    res = cal.residual_ab(cal.shape)
    if res is not None:
        ab = ab + (res / ab.shape[1]).astype(np.float32)[:, None, :]
    q = quaternions_where(ab, np.ones(len(xy), bool), law, np.array([law.wavelength_ref]))
    return np.stack([intensity(q[:, 0], a) for a in arrangements], -1).reshape(*cal.shape, -1)


def file_values(raw: np.ndarray, bit_depth: int) -> np.ndarray:
    """Stored values (rows, cols, C) in [0, 1] as an image file's integers: uint8 or
    uint16 at ``bit_depth`` 8 or 16, (rows, cols) for one channel.

    Examples
    --------
    >>> file_values(np.full((1, 2, 1), 0.5), 8).tolist()
    [[128, 128]]
    """
    top, kind = {8: (255, np.uint8), 16: (65535, np.uint16)}[bit_depth]
    img = np.round(raw * top).astype(kind)
    return img[..., 0] if img.shape[-1] == 1 else img


def camera_frame(cfg: dict, lib, inds, cal) -> np.ndarray:
    """The frame (rows, cols[, 3]) the calibrated sensor ``cal``'s camera records of
    ``inds`` (the sheet's axes; ``lib`` already scaled to the sheet), 8 or 16 bit as the
    config's camera: :func:`camera_linear` times the calibration's exposure gain, then
    :meth:`CalibratedSensor.encode`."""
    lin = camera_linear(cfg, lib, inds, cal)
    gain = np.asarray(cal.report.get("exposure_gain", [0.8] * lin.shape[-1]), float)
    return file_values(cal.encode(lin * gain), optics_setup(cfg).camera.bit_depth)


def run_library_predict(
    cfg: dict, library, out, *, sensor=None, echo=print, progress=True, inputs=()
) -> dict:
    """Synthesise the config's final state from ``library`` into ``out``; the summary.
    ``sensor``: a calibrated sensor file (``fringekit sensor calibrate``): the library is
    read as its sheet, and ``state_01/camera.png`` is the frame its camera records (a
    phase sensor's six steps: ``camera_step1.png`` to ``camera_step6.png``)."""
    t0 = time.perf_counter()
    cal = as_calibrated(sensor)
    if sensor is not None and cal is None:
        raise ConfigError(
            f"--sensor {sensor}: give a sensor file (.json of fringekit sensor calibrate)"
        )
    with claim_output(out, command="predict", inputs=[library, sensor, *inputs]) as work:
        lib = load_library(library)
        check_sensor(lib, cfg, "the config")
        if cal is not None:
            cal.check(lib)
            lib = cal.library(lib)
        inds = config_indenters(cfg, lib)
        (work / "config.toml").write_text(to_toml(cfg))
        rendered = _render(cfg, lib, inds, work / "state_01", cal)
        if cal is not None:
            frame = camera_frame(cfg, lib, inds, cal)
            if cal.method == "phase":  # six files, in fringekit.analysis.SIX_STEP_ORDER
                for k in range(frame.shape[-1]):
                    write_image(work / "state_01" / f"camera_step{k + 1}.png", frame[..., k])
            else:
                write_image(work / "state_01" / "camera.png", frame)
        summary = {
            "case": cfg["case"],
            "status": "ok",
            "source": "library",
            "library": str(lib.folder),
            "accuracy": ACCURACY_NOTE,
            "max_fringe_order": rendered["max_fringe_order"],
            "indenters": [
                {
                    "force_N": [i.fx, i.fy, -i.fz],
                    "centre_mm": [i.x * 1e3, i.y * 1e3],
                    "diameter_mm": i.diameter * 1e3,
                }
                for i in inds
            ],
            "rendered": [rendered],
            "calibrated_sensor": None if cal is None else cal.summary(str(sensor)),
            "times_s": {"total_s": time.perf_counter() - t0},
        }
        (work / "summary.json").write_text(json.dumps(summary, indent=2))
    if progress:
        echo(
            f"predict: {len(inds)} indenter(s) from the library in "
            f"{time.perf_counter() - t0:.1f} s -> {out}"
        )
    return summary
