"""One solved load state -> the optics outputs of ``fringekit predict``.

:func:`render_state` computes a :class:`RenderedState` in memory (maps, the six
phase-stepped images, the dark-field and white-light images); :func:`write_state` writes
it into ``state_XX/``: ``solution.vtu``, ``maps.npz``, the images and the figures.
:func:`fringe_order_map` gives the monochrome fringe-order map alone (calibration runs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
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
    "RenderedState",
    "fringe_order_map",
    "grid_figure",
    "indenter_pixels",
    "monochrome_images",
    "mono_map",
    "no_data_fill",
    "path_quaternions",
    "render_state",
    "white_light",
    "write_maps",
    "write_monochrome",
    "write_state",
    "write_white_light",
]


def _integrate(
    sol,
    cfg: dict,
    optics: OpticsSetup,
    wavelengths,
    *,
    progress: bool = False,
    samples=None,
    frozen=None,
    turn: float = 0.0,
):
    """Sample (once) and integrate the sheet, and the PC first when configured; with
    ``frozen`` or ``turn``, fresh samples are turned and the sheet's take the frozen
    stress (:meth:`~fringekit.optics.RaySamples.frozen`).

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
        if frozen is not None or turn:
            samples = [r.frozen(None, turn) for r in samples[:-1]] + [
                samples[-1].frozen(frozen, turn)
            ]
    laws = [optics.substrate_law, optics.law] if pc else [optics.law]
    q, simple, valid = integrate_layers(samples, laws, wavelengths)
    return q, simple, valid, samples


def path_quaternions(
    sol, cfg: dict, optics: OpticsSetup, wavelengths, *, frozen=None, turn: float = 0.0
) -> tuple:
    """(q (P, W, 4), valid (P,)) of every pixel of ``optics.grid``'s ray through the solved
    sheet (and the PC first, when the config puts it in the light path) at ``wavelengths``
    (m): the quaternions :func:`mono_map` and the white light start from.

    ``turn`` (rad): the stresses' angles taken in axes turned by -turn (a camera turned
    against the sheet); ``frozen`` (P, 2): a residual birefringence frozen evenly through
    the sheet, its slab pair summed through the thickness (Pa m) in those axes, composed
    with the loads' stress slab by slab (:meth:`~fringekit.optics.RaySamples.frozen`).
    """
    q, _, valid, _ = _integrate(sol, cfg, optics, wavelengths, frozen=frozen, turn=turn)
    return q, valid


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
    map_figure(
        path, data, title, label, cmap, extent=extent, axis_labels=("x (mm)", "y (mm)"), **kw
    )


@dataclass(frozen=True)
class RenderedState:
    """The optics of one solved load state, in memory: maps and camera images.

    Attributes
    ----------
    state : int
        The load state, 1-based.
    solution : fringekit.fea.Solution
        The solved state it was rendered from.
    grid : fringekit.optics.PixelGrid
        The pixel grid (rows, cols) of every map and image.
    fringe_order, isoclinic_rad, simple_order : ndarray (rows, cols)
        Total fringe order at the reference wavelength, isoclinic (rad) and the
        rotation-free simple order; NaN where there is no data.
    branch_ambiguous, mask : ndarray of bool (rows, cols)
        Where the order's branch cannot be chosen; where there is data.
    six_step : dict of str to ndarray (rows, cols)
        The six phase-stepped camera images (``step1`` .. ``step6``), no-data filled.
    dark_field : ndarray (rows, cols)
        The monochrome dark-field circular image, no-data filled.
    white_light : ndarray (rows, cols, 3)
        The white-light colour image, no-data filled (uint8, or uint16 at 16 bit).
    wavelength_m : float
        The reference wavelength (m).
    times_s : dict
        Seconds spent per stage.
    """

    state: int
    solution: object
    grid: object
    fringe_order: np.ndarray
    isoclinic_rad: np.ndarray
    simple_order: np.ndarray
    branch_ambiguous: np.ndarray
    mask: np.ndarray
    six_step: dict
    dark_field: np.ndarray
    white_light: np.ndarray
    wavelength_m: float
    times_s: dict = field(default_factory=dict)

    @property
    def max_fringe_order(self) -> float | None:
        """The largest fringe order over the data, or None without data."""
        valid = np.isfinite(self.fringe_order)
        return float(np.nanmax(self.fringe_order)) if valid.any() else None

    def entry(self) -> dict:
        """This state's entry of ``summary.json["rendered"]``."""
        valid = np.isfinite(self.fringe_order)
        return {
            "state": self.state,
            "folder": f"state_{self.state:02d}",
            "max_fringe_order": self.max_fringe_order,
            "max_simple_order": float(np.nanmax(self.simple_order)) if valid.any() else None,
            "valid_pixel_fraction": float(valid.mean()),
            "branch_ambiguous_fraction": float(self.branch_ambiguous.sum() / max(valid.sum(), 1)),
            "times_s": self.times_s,
        }


def write_maps(d: Path, grid, maps: dict, indenter_rc, wavelength_m: float) -> None:
    """``maps.npz`` of one state: ``maps`` (``fringe_order``, ``branch_ambiguous``,
    ``simple_order``, ``isoclinic_rad``, ``mask``, each (rows, cols)) with the pixels' x
    and y (m), the pixel size (m), ``indenter_rc`` (m, 2) each indenter's axis in pixels
    (row, col) and the reference wavelength (m)."""
    rows, cols = grid.shape
    xy = grid.xy().reshape(rows, cols, 2)
    np.savez_compressed(
        d / "maps.npz",
        **maps,
        x_m=xy[..., 0],
        y_m=xy[..., 1],
        pixel_size_m=grid.pixel_size,
        indenter_rc=np.asarray(indenter_rc, float).reshape(-1, 2),
        wavelength_m=wavelength_m,
    )


def _write_maps(d: Path, rs: RenderedState) -> None:
    """``maps.npz`` of one rendered state."""
    maps = {
        "fringe_order": rs.fringe_order,
        "branch_ambiguous": rs.branch_ambiguous,
        "simple_order": rs.simple_order,
        "isoclinic_rad": rs.isoclinic_rad,
        "mask": rs.mask,
    }
    write_maps(d, rs.grid, maps, indenter_pixels(rs.solution, rs.grid), rs.wavelength_m)


def white_light(qw, lam, cfg: dict, optics: OpticsSetup, mask) -> np.ndarray:
    """The white-light image of quaternions qw (rows, cols, W, 4) at wavelengths lam (m)
    through the config's light, camera and dark-field circular polariscope, at the no-data
    level outside ``mask`` (rows, cols)."""
    o = cfg["optics"]
    rgb = white_light_image(
        qw,
        light_source(o["light"], lam),
        optics.camera,
        dark_field_circular(**optics.errors),
        seed=o["seed"],
    )
    return no_data_fill(rgb, mask)


def write_white_light(d: Path, rgb: np.ndarray, optics: OpticsSetup) -> None:
    """Write ``white_light.png`` (``.tif`` at 16 bit)."""
    write_image(d / ("white_light.png" if optics.camera.bit_depth == 8 else "white_light.tif"), rgb)


def monochrome_images(q_img, cfg: dict, optics: OpticsSetup, mask) -> tuple[dict, np.ndarray]:
    """(the six phase-stepped images by name, the dark-field image) of quaternions q_img
    (rows, cols, 4) at the reference wavelength, the no-data level outside ``mask``."""
    seed = cfg["optics"]["seed"]
    steps = {
        a.name: no_data_fill(monochrome_image(q_img, a, optics.camera, seed=seed), mask)
        for a in six_step_arrangements(**optics.errors)
    }
    dark = monochrome_image(q_img, dark_field_circular(**optics.errors), optics.camera, seed=seed)
    return steps, no_data_fill(dark, mask)


def write_monochrome(d: Path, steps: dict, dark: np.ndarray, mask) -> None:
    """Write ``mask.png``, ``six_step/step1..6.png`` and ``dark_field.png``."""
    (d / "six_step").mkdir(parents=True, exist_ok=True)
    write_image(d / "mask.png", np.where(mask, 255, 0).astype(np.uint8))
    for name, img in steps.items():
        write_image(d / "six_step" / f"{name}.png", img)
    write_image(d / "dark_field.png", dark)


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
    documented no-data level (:data:`fringekit.output.figures.NO_DATA_IMAGE_LEVEL` of full scale
    in every channel): the contact zone and pixels off the sheet look the same in every
    image, and differ from a dark fringe."""
    out = img.copy()
    out[~mask] = round(NO_DATA_IMAGE_LEVEL * np.iinfo(img.dtype).max)
    return out


def _figures(d: Path, rs: RenderedState, cfg: dict) -> None:
    o = cfg["optics"]
    grid_figure(
        d / "fringe_order.png",
        rs.fringe_order,
        rs.grid,
        f"fringe order at {o['wavelength_nm']:g} nm",
        "fringe order",
        "turbo",
        hatch=rs.branch_ambiguous,
        hatch_label="branch ambiguous (maps.npz branch_ambiguous)",
    )
    grid_figure(
        d / "isoclinic.png",
        np.degrees(rs.isoclinic_rad),
        rs.grid,
        "isoclinic",
        "angle (deg)",
        "twilight",
    )
    shown = rs.white_light / float(np.iinfo(rs.white_light.dtype).max)
    shown[~rs.mask] = np.nan  # drawn as "no data"
    grid_figure(
        d / "fringe_image.png",
        shown,
        rs.grid,
        f"white light ({o['light']}), dark-field circular",
        "",
        None,
    )
    _profile(d, rs.solution, rs.fringe_order, rs.grid)


def render_state(
    sol, k: int, cfg: dict, optics: OpticsSetup, progress, show_bars: bool = False
) -> RenderedState:
    """The maps and images of load state ``k`` (0-based), computed in memory.

    ``progress`` is called with one line per stage; ``show_bars`` shows the ray bar.
    """
    o = cfg["optics"]
    times = {}
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
    order = omap.fringe_order()
    ambiguous = omap.branch_ambiguous()
    theta = np.where(omap.mask, omap.principal_angle(), np.nan)
    times["maps_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    steps, dark = monochrome_images(omap.q[:, :, 0], cfg, optics, omap.mask)
    times["six_step_s"] = time.perf_counter() - t0
    progress("optics: six phase-stepped and dark-field images")

    t0 = time.perf_counter()
    rows, cols = optics.grid.shape
    lam = optics.law.wavenumber_grid(o["white_light_wavelengths"])
    qw, _, _, _ = _integrate(sol, cfg, optics, lam, samples=samples)
    rgb = white_light(qw.reshape(rows, cols, len(lam), 4), lam, cfg, optics, omap.mask)
    times["white_light_s"] = time.perf_counter() - t0
    progress("optics: white-light image")
    return RenderedState(
        state=k + 1,
        solution=sol,
        grid=optics.grid,
        fringe_order=order,
        isoclinic_rad=theta,
        simple_order=omap.simple_order,
        branch_ambiguous=ambiguous,
        mask=omap.mask,
        six_step=steps,
        dark_field=dark,
        white_light=rgb,
        wavelength_m=optics.law.wavelength_ref,
        times_s=times,
    )


def write_state(out: Path, rs: RenderedState, cfg: dict, optics: OpticsSetup) -> None:
    """Write the VTU, maps, images and figures of one rendered state into
    ``out/state_XX/``."""
    d = out / f"state_{rs.state:02d}"
    d.mkdir(parents=True, exist_ok=True)
    write_solution_vtu(rs.solution, d / "solution.vtu")
    _write_maps(d, rs)
    write_monochrome(d, rs.six_step, rs.dark_field, rs.mask)
    write_white_light(d, rs.white_light, optics)
    _figures(d, rs, cfg)
