"""One solved load state -> the optics outputs of ``fringekit predict``.

:func:`render_state` writes into ``state_XX/``: ``solution.vtu``, ``maps.npz``, the six
phase-stepped images, the white-light image and the figures. :func:`fringe_order_map`
gives the monochrome fringe-order map alone (calibration runs).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fringekit.analysis import line_profile
from fringekit.config.files import ConfigError
from fringekit.config.inputs import OpticsSetup, optics_setup
from fringekit.fea import write_solution_vtu
from fringekit.optics import (
    FEMStressField,
    OpticalMap,
    dark_field_circular,
    integrate_layers,
    light_source,
    monochrome_image,
    sample_rays,
    six_step_arrangements,
    white_light_image,
    write_image,
)
from fringekit.output.figures import NO_DATA_IMAGE_LEVEL, map_figure, profile_figure, sensor_extent

__all__ = [
    "fringe_order_map",
    "grid_figure",
    "indenter_pixels",
    "mono_map",
    "no_data_fill",
    "render_state",
    "write_monochrome",
    "write_white_light",
]


def _integrate(
    sol, cfg: dict, optics: OpticsSetup, wavelengths, *, progress: bool = False, samples=None
):
    """Sample (once) and integrate the sheet, and the PC first when configured.

    Returns (q (P, W, 4), simple (P,), valid (P,), samples) with ``samples`` reusable
    for other wavelengths.
    """
    o = cfg["optics"]
    pc = optics.substrate_law is not None
    if samples is None:
        step = o["lateral_step_mm"] * 1e-3 or None
        kw = {"lateral_step": step, "progress": progress}
        samples = [sample_rays(FEMStressField(sol), optics.grid, o["samples_per_ray"], **kw)]
        if pc:
            field = FEMStressField(sol, region="substrate")
            n_pc = o["substrate_samples_per_ray"]
            samples.insert(0, sample_rays(field, optics.grid, n_pc, **kw))
    laws = [optics.substrate_law, optics.law] if pc else [optics.law]
    q, simple, valid = integrate_layers(samples, laws, wavelengths)
    return q, simple, valid, samples


def mono_map(sol, cfg: dict, optics: OpticsSetup, *, progress: bool = False):
    """(OpticalMap at the reference wavelength, the ray samples for reuse)."""
    law, grid = optics.law, optics.grid
    q, simple, valid, samples = _integrate(
        sol, cfg, optics, [law.wavelength_ref], progress=progress
    )
    rows, cols = grid.shape
    omap = OpticalMap(
        grid=grid,
        wavelengths=np.array([law.wavelength_ref]),
        q=q.reshape(rows, cols, 1, 4),
        simple_order=np.where(valid, simple, np.nan).reshape(rows, cols),
        mask=valid.reshape(rows, cols),
        reflection=True,
        law=law,
    )
    return omap, samples


def indenter_pixels(sol, grid) -> np.ndarray:
    """(m, 2) each indenter's current axis in pixels (row, col)."""
    return np.array([grid.xy_to_pixel(i.centre[0], i.centre[1]) for i in sol.indenters], float)


def fringe_order_map(sol, cfg: dict, optics: OpticsSetup | None = None):
    """Monochrome fringe-order map of one solution on the config's pixel grid.

    Returns
    -------
    order : (rows, cols) total fringe order at ``optics.wavelength_nm``, NaN outside the
        sheet and in contact zones
    grid : optics.PixelGrid
    centres_rc : (m, 2) each indenter's current axis in pixels (row, col)
    """
    optics = optics or optics_setup(cfg)
    omap, _ = mono_map(sol, cfg, optics)
    return omap.fringe_order(), optics.grid, indenter_pixels(sol, optics.grid)


def grid_figure(path, data, grid, title, label, cmap, **kw) -> None:
    """:func:`map_figure` on the sheet's x, y (mm) of ``grid``: the sensor frame about
    the pixel where the sensor origin falls, pixel edges on the axes."""
    origin = tuple(float(v) for v in grid.xy_to_pixel(0.0, 0.0))
    extent = sensor_extent(grid.shape, grid.pixel_size, origin)
    map_figure(path, data, title, label, cmap, extent=extent, axis_labels=("x (mm)", "y (mm)"),
               **kw)  # fmt: skip


def _write_maps(d: Path, sol, omap: OpticalMap, law) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``maps.npz`` of one state; returns (fringe order, isoclinic (rad), branch ambiguity)."""
    grid = omap.grid
    rows, cols = grid.shape
    order = omap.fringe_order()
    ambiguous = omap.branch_ambiguous()
    theta = np.where(omap.mask, omap.principal_angle(), np.nan)
    xy = grid.xy().reshape(rows, cols, 2)
    np.savez_compressed(
        d / "maps.npz",
        fringe_order=order,
        branch_ambiguous=ambiguous,
        simple_order=omap.simple_order,
        isoclinic_rad=theta,
        mask=omap.mask,
        x_m=xy[..., 0],
        y_m=xy[..., 1],
        pixel_size_m=grid.pixel_size,
        indenter_rc=indenter_pixels(sol, grid),
        wavelength_m=law.wavelength_ref,
    )
    return order, theta, ambiguous


def _white_light(d: Path, sol, cfg: dict, optics: OpticsSetup, samples, mask) -> np.ndarray:
    """Render and write the white-light image (dark-field circular); return it."""
    rows, cols = optics.grid.shape
    lam = optics.law.wavenumber_grid(cfg["optics"]["white_light_wavelengths"])
    qw, _, _, _ = _integrate(sol, cfg, optics, lam, samples=samples)
    return write_white_light(d, qw.reshape(rows, cols, len(lam), 4), lam, cfg, optics, mask)


def write_white_light(d: Path, qw, lam, cfg: dict, optics: OpticsSetup, mask) -> np.ndarray:
    """Write ``white_light.png`` (``.tif`` at 16 bit) of quaternions qw (rows, cols, W, 4)
    at wavelengths lam through the config's light, camera and dark-field circular
    polariscope, the no-data level outside ``mask``; return the image."""
    o, camera = cfg["optics"], optics.camera
    rgb = white_light_image(
        qw, light_source(o["light"], lam), camera, dark_field_circular(**optics.errors),
        seed=o["seed"],
    )  # fmt: skip
    rgb = no_data_fill(rgb, mask)
    write_image(d / ("white_light.png" if camera.bit_depth == 8 else "white_light.tif"), rgb)
    return rgb


def write_monochrome(d: Path, q_img, cfg: dict, optics: OpticsSetup, mask) -> None:
    """Write ``mask.png``, ``six_step/step1..6.png`` and ``dark_field.png`` of quaternions
    q_img (rows, cols, 4) at the reference wavelength, the no-data level outside ``mask``."""
    seed = cfg["optics"]["seed"]
    (d / "six_step").mkdir(parents=True, exist_ok=True)
    write_image(d / "mask.png", np.where(mask, 255, 0).astype(np.uint8))
    for a in six_step_arrangements(**optics.errors):
        img = monochrome_image(q_img, a, optics.camera, seed=seed)
        write_image(d / "six_step" / f"{a.name}.png", no_data_fill(img, mask))
    dark = monochrome_image(q_img, dark_field_circular(**optics.errors), optics.camera,
                            seed=seed)  # fmt: skip
    write_image(d / "dark_field.png", no_data_fill(dark, mask))


def _profile(d: Path, sol, order: np.ndarray, grid) -> None:
    """Fringe order along x through the first indenter (the seed paper's a-b line)."""
    rows, cols = grid.shape
    ind = sol.indenters[0]
    r, _ = grid.xy_to_pixel(ind.centre[0], ind.centre[1])
    row = int(np.clip(np.round(r), 0, rows - 1))
    prof = line_profile(order, (row, 0.0), (row, cols - 1.0), n=cols)
    x_prof = grid.pixel_to_xy(np.full(cols, row), np.arange(cols))[0]
    np.savetxt(
        d / "profile.csv",
        np.column_stack([x_prof * 1e3, prof.values]),
        delimiter=",",
        header="x_mm,fringe_order",
        comments="",
    )
    title = f"fringe order along y = {ind.centre[1] * 1e3:.2f} mm (contact zone masked)"
    profile_figure(d / "profile.png", x_prof * 1e3, prof.values, xlabel="x (mm)", title=title)


def no_data_fill(img: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``img`` (rows, cols[, 3], uint8 or uint16) with the pixels outside ``mask`` at the
    documented no-data level (:data:`fringekit.figures.NO_DATA_IMAGE_LEVEL` of full scale
    in every channel): the contact zone and pixels off the sheet look the same in every
    image, and differ from a dark fringe."""
    out = img.copy()
    out[~mask] = round(NO_DATA_IMAGE_LEVEL * np.iinfo(img.dtype).max)
    return out


def _figures(d: Path, sol, cfg: dict, grid, order, theta, rgb, mask, ambiguous) -> None:
    o = cfg["optics"]
    grid_figure(
        d / "fringe_order.png", order, grid, f"fringe order at {o['wavelength_nm']:g} nm",
        "fringe order", "turbo", hatch=ambiguous,
        hatch_label="branch ambiguous (maps.npz branch_ambiguous)",
    )  # fmt: skip
    grid_figure(d / "isoclinic.png", np.degrees(theta), grid, "isoclinic", "angle (deg)",
                 "twilight")  # fmt: skip
    shown = rgb / float(np.iinfo(rgb.dtype).max)
    shown[~mask] = np.nan  # drawn as "no data"
    grid_figure(
        d / "fringe_image.png", shown, grid,
        f"white light ({o['light']}), dark-field circular", "", None,
    )  # fmt: skip
    _profile(d, sol, order, grid)


def render_state(
    sol, k: int, cfg: dict, out: Path, optics: OpticsSetup, progress, show_bars: bool = False
) -> dict:
    """Write the VTU, maps, images and figures of load state ``k`` (0-based) into
    ``out/state_XX``; return its entry of ``summary.json["rendered"]``.

    ``progress`` is called with one line per stage; ``show_bars`` shows the ray bar.
    """
    o = cfg["optics"]
    d = out / f"state_{k + 1:02d}"
    d.mkdir(parents=True, exist_ok=True)
    times = {}
    t0 = time.perf_counter()
    write_solution_vtu(sol, d / "solution.vtu")
    times["vtu_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    omap, samples = mono_map(sol, cfg, optics, progress=show_bars)
    if not omap.mask.any():
        raise ConfigError(
            f"optics: the field of view (centre {o['center_mm']} mm, width "
            f"{o['field_of_view_mm']} mm) has no pixel over the sheet outside the contact zone"
        )
    times["locate_integrate_s"] = time.perf_counter() - t0
    progress("optics: rays located and integrated")

    t0 = time.perf_counter()
    order, theta, ambiguous = _write_maps(d, sol, omap, optics.law)
    times["maps_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    write_monochrome(d, omap.q[:, :, 0], cfg, optics, omap.mask)
    times["six_step_s"] = time.perf_counter() - t0
    progress("optics: six phase-stepped and dark-field images")

    t0 = time.perf_counter()
    rgb = _white_light(d, sol, cfg, optics, samples, omap.mask)
    times["white_light_s"] = time.perf_counter() - t0
    progress("optics: white-light image")

    t0 = time.perf_counter()
    _figures(d, sol, cfg, optics.grid, order, theta, rgb, omap.mask, ambiguous)
    times["figures_s"] = time.perf_counter() - t0
    valid = np.isfinite(order)
    return {
        "state": k + 1,
        "folder": d.name,
        "max_fringe_order": float(np.nanmax(order)) if valid.any() else None,
        "max_simple_order": float(np.nanmax(omap.simple_order)) if valid.any() else None,
        "valid_pixel_fraction": float(valid.mean()),
        "branch_ambiguous_fraction": float(ambiguous.sum() / max(valid.sum(), 1)),
        "times_s": times,
    }
