"""``fringekit calibrate --disc IMAGE... --load-N P...``: the fringe value from photographs.

Reads the photographs (and the zero-load ``--reference``), finds the disc (given by
``--centre`` and ``--radius-px``; else :func:`analysis.find_disc`: its outline, else the
symmetry of its fringes), fits Frocht's field through
the polariscope to the intensities (:func:`fringekit.calibrate.disc_photo.fit_disc_photos`) and
writes to ``--out``:

- ``disc_calibration.json`` - exactly ``f_sigma_N_per_m``, ``f_sigma_sd_N_per_m``,
  ``offset_order`` and ``images``: per photograph ``file``, ``load_N``, ``centre_order``
  (the load's part, without the offset) and ``residual_rms`` (fraction of the fringe
  amplitude);
- ``summary.json`` - how: the disc found (centre, radius, pixel size, method), the field,
  the wavelength, the uncertainty's method, warnings, time;
- ``disc_fit.png`` - the fitted fringe centres over each photograph.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fringekit.analysis import find_disc, grey_channel, load_image
from fringekit.calibrate.disc_photo import (
    FIT_RADIUS,
    REFUSE_RESIDUAL,
    WARN_RESIDUAL,
    DiscGeometry,
    DiscImage,
    disc_coordinates,
    fit_disc_photos,
)
from fringekit.calibrate.disc_series import MIN_SERIES, fit_disc_series
from fringekit.errors import InputError, RefusedError
from fringekit.optics import DiametralDisc
from fringekit.output.figures import disc_fit_figure
from fringekit.output.folders import atomic_write, claim_output

__all__ = [
    "DiscCalibration",
    "calibrate_disc",
    "check_disc_in_image",
    "is_photo",
    "run_disc_photos",
]


def is_photo(path) -> bool:
    """Whether ``path`` is an image file (else a maps.npz or an analyze folder)."""
    return Path(path).suffix.lower() in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")


#: Least fraction of the fitted disc (FIT_RADIUS of its radius) that must lie in the image,
#: and its least radius (px): a disc mostly off the image, or a few pixels wide, is no
#: calibration however well its few pixels fit.
MIN_INSIDE = 0.5
MIN_RADIUS_PX = 8.0


def check_disc_in_image(shape, geometry: DiscGeometry, named: str) -> None:
    """Refuse (:class:`InputError`, naming ``named``) a disc that lies mostly outside an
    image of ``shape`` (rows, cols) or is too small to fit.

    The inside fraction is that of the fitted area (radius ``FIT_RADIUS * radius_px``),
    counted on a 64 x 64 lattice over its bounding square.

    Examples
    --------
    >>> check_disc_in_image((240, 240), DiscGeometry(120, 120, 100), "--radius-px 100")
    >>> check_disc_in_image((240, 240), DiscGeometry(120, 120, 5000), "--radius-px 5000")
    Traceback (most recent call last):
    ...
    fringekit.errors.InputError: --radius-px 5000: the disc (centre row 120, col 120, radius
    5000 px) has only ... % of its area in the 240 x 240 image ...
    """
    rows, cols = shape[:2]
    R = FIT_RADIUS * geometry.radius_px
    u = (np.arange(64) + 0.5) / 32 - 1
    dy, dx = np.meshgrid(u * R, u * R, indexing="ij")
    disc = np.hypot(dx, dy) <= R
    r, c = geometry.row + dy[disc], geometry.col + dx[disc]
    inside = float(np.mean((r >= -0.5) & (r <= rows - 0.5) & (c >= -0.5) & (c <= cols - 0.5)))
    if inside < MIN_INSIDE or geometry.radius_px < MIN_RADIUS_PX:
        raise InputError(
            f"{named}: the disc (centre row {geometry.row:.4g}, col {geometry.col:.4g}, radius "
            f"{geometry.radius_px:.4g} px) has only {100 * inside:.2g} % of its area in the "
            f"{rows} x {cols} image (rows 0..{rows - 1}, cols 0..{cols - 1}); allowed: a disc "
            f"at least {100 * MIN_INSIDE:.0f} % inside, radius at least {MIN_RADIUS_PX:g} px"
        )


def _named(centre, radius_px, pixel_mm) -> str:
    """The options that placed the disc, as the user gave them."""
    parts = []
    if centre is not None:
        parts.append(f"--centre {centre[0]:g} {centre[1]:g}")
    if radius_px is not None:
        parts.append(f"--radius-px {radius_px:g}")
    elif pixel_mm:
        parts.append(f"--pixel-mm {pixel_mm:g}")
    return ", ".join(parts) or "--disc (the disc found)"


def _geometry(photo, centre, radius_px, pixel_mm, diameter_mm) -> tuple[DiscGeometry, str]:
    """The disc in the photo: from the options, its outline, or its fringes' symmetry;
    refused when it lies mostly outside the photo."""
    geometry, how = _placed(photo, centre, radius_px, pixel_mm, diameter_mm)
    check_disc_in_image(photo.shape, geometry, _named(centre, radius_px, pixel_mm))
    return geometry, how


def _placed(photo, centre, radius_px, pixel_mm, diameter_mm) -> tuple[DiscGeometry, str]:
    """The disc from the options, its outline, or its fringes' symmetry."""
    if pixel_mm and radius_px is None:
        radius_px = diameter_mm / 2 / pixel_mm
    if centre is not None and radius_px is not None:
        return DiscGeometry(centre[0], centre[1], radius_px), "--centre and --radius-px"
    try:
        c, how = find_disc(photo)
    except ValueError:
        raise InputError(
            "--disc: no disc found in the photograph; give --centre ROW COL and --radius-px R"
        ) from None
    row, col = centre if centre is not None else (c.row, c.col)
    return DiscGeometry(row, col, radius_px or c.radius), how


def _order_map(shape, geometry: DiscGeometry, fit, load_N, diameter, thickness):
    """(rows, cols) fitted total order P g / f_sigma + N_0 inside the disc, NaN outside."""
    r, c = np.mgrid[: shape[0], : shape[1]]
    xy = disc_coordinates(r.ravel(), c.ravel(), geometry, diameter)
    inside = np.hypot(xy[:, 0], xy[:, 1]) < 0.98 * diameter / 2
    N = np.full(len(xy), np.nan)
    disc = DiametralDisc(P=max(load_N, 1e-12), D=diameter, t=thickness)
    N[inside] = thickness * disc.stress_difference(xy[inside]) / fit.f_sigma * (load_N > 0)
    return (N + fit.offset_order).reshape(shape)


@dataclass(frozen=True)
class DiscCalibration:
    """The material fringe value fitted to photographs of a disc in diametral compression.

    Attributes
    ----------
    f_sigma_N_per_m, f_sigma_sd_N_per_m : float
        The material fringe value and its 1-sigma (N/m; jackknife over the photographs,
        or over eight sectors of one).
    offset_order : float
        The residual (frozen-stress) order common to all photographs.
    images : list of dict
        Per photograph: ``file``, ``load_N``, ``centre_order`` (the load's part) and
        ``residual_rms`` (fraction of the fringe amplitude).
    summary : dict
        The disc found, the field, the wavelength, the uncertainty's method, warnings.
    photos, orders : list of ndarray (rows, cols)
        The grey photographs and the fitted fringe-order maps (for the figure).

    Examples
    --------
    See :func:`calibrate_disc`; the fitted value and its 1-sigma as a dict:

    >>> sorted(DiscCalibration(7000.0, 20.0, 0.0, [], {}, [], []).result())
    ['f_sigma_N_per_m', 'f_sigma_sd_N_per_m', 'images', 'offset_order']
    """

    f_sigma_N_per_m: float
    f_sigma_sd_N_per_m: float
    offset_order: float
    images: list
    summary: dict = field(repr=False)
    photos: list = field(repr=False)
    orders: list = field(repr=False)

    def result(self) -> dict:
        """What ``disc_calibration.json`` holds."""
        return {
            "f_sigma_N_per_m": self.f_sigma_N_per_m,
            "f_sigma_sd_N_per_m": self.f_sigma_sd_N_per_m,
            "offset_order": self.offset_order,
            "images": self.images,
        }

    def write(self, folder) -> Path:
        """Write ``disc_calibration.json``, ``summary.json`` and ``disc_fit.png`` into
        ``folder`` (created if missing); return it."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        atomic_write(out / "disc_calibration.json", json.dumps(self.result(), indent=2))
        atomic_write(out / "summary.json", json.dumps(self.summary, indent=2))
        titles = [
            f"{Path(im['file']).name}: {im['load_N']:g} N, centre {im['centre_order']:.3f}"
            for im in self.images
        ]
        disc_fit_figure(out / "disc_fit.png", self.photos, self.orders, titles)
        return out


def _fit(discs, geometry, D, t, field, shared, residual_field):
    """The uniform-residual fit, or (``residual_field``) the series fit; and the worst
    residual left to judge (0 after a series fit, which judges its loads itself)."""
    fit = fit_disc_photos(
        discs, geometry, diameter=D, thickness=t, field=field, shared_light=shared
    )
    worst = max(fit.residuals)
    distinct = len({d.load_N for d in discs})
    if residual_field == "series" or (
        residual_field == "auto" and worst > WARN_RESIDUAL and distinct >= MIN_SERIES
    ):
        fit = fit_disc_series(discs, geometry, diameter=D, thickness=t, field=field)
        _check_loads(fit, [d.name for d in discs])
        return fit, 0.0
    return fit, worst


def _unexplained(worst: float, distinct: int, residual_field: str) -> RefusedError:
    """The refusal of photographs the disc fit does not explain (RMS residual ``worst``,
    a fraction of the fringe amplitude, from ``distinct`` loads)."""
    series = (
        f"; a frozen stress that varies over the disc needs a load series of at least "
        f"{MIN_SERIES} photographs at distinct loads (given {distinct}; a zero-load "
        "--reference counts)"
        if residual_field == "auto" and distinct < MIN_SERIES
        else ""
    )
    return RefusedError(
        f"--disc: Frocht's field leaves an RMS residual of "
        f"{'over 100' if worst > 1 else f'{100 * worst:.0f}'} % of the fringe "
        "amplitude: the photographs are not explained as a disc in diametral compression "
        "(check --load-N, --diameter-mm, --field, the disc found, or give --centre/--radius-px)"
        + series
    )


def calibrate_disc(
    images,
    *,
    load_N,
    diameter_mm,
    thickness_mm,
    wavelength_nm=None,
    reference=None,
    field="dark",
    centre_px=None,
    radius_px=None,
    pixel_mm=None,
    dark=None,
    echo=None,
    residual_field="auto",
) -> DiscCalibration:
    """The material fringe value from photographs of a disc in diametral compression.

    Fits Frocht's field through the polariscope to the photographs' intensities: the
    illumination and background of each photo, a residual order common to all, and the
    disc's centre, radius and load-axis tilt.

    Parameters
    ----------
    images : sequence of paths
        Photographs of the disc (transmission), one per load.
    load_N : sequence of float
        The diametral load of each photograph (N).
    diameter_mm, thickness_mm : float
        The disc's diameter and thickness (mm).
    wavelength_nm : float, optional
        The light's wavelength (nm), recorded with the result.
    reference : path, optional
        A photograph at zero load; pins the residual order.
    field : {"dark", "bright"}
        The polariscope's field.
    centre_px, radius_px : optional
        The disc's centre (row, col) and radius (px); default found in the photograph
        (its outline, else the symmetry of its fringes).
    pixel_mm : float, optional
        The pixel pitch (mm), which gives the radius from the diameter.
    dark : path, optional
        A dark frame subtracted from every photograph.
    echo : callable, optional
        Where the one line on the disc found goes (default: nowhere).
    residual_field : {"auto", "uniform", "series"}
        The frozen stress: ``uniform`` a residual order common to the whole disc;
        ``series`` any smooth frozen field, by load stepping over a series of at least
        four distinct loads (:func:`fringekit.calibrate.disc_series.fit_disc_series`);
        ``auto`` (default) uniform, and the series fit when the uniform one leaves more
        than 4 % of the fringe amplitude and the series is long enough.

    Returns
    -------
    DiscCalibration

    Raises
    ------
    InputError
        Loads and photographs that do not pair up, photographs of different sizes, no
        disc found.
    RefusedError
        Photographs Frocht's field does not explain (an RMS residual above 25 % of the
        fringe amplitude).

    Examples
    --------
    Two photographs of a 40 mm, 6 mm thick disc of the PSM-4-class material at 1 and 2 N,
    rendered through a dark-field circular polariscope, give its fringe value back:

    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import fringekit
    >>> from fringekit.optics import (PSM4_ASSUMED, Camera, DiametralDisc, PixelGrid,
    ...     dark_field_circular, monochrome_image, optical_map, retarder, write_image)
    >>> folder, photos = Path(tempfile.mkdtemp()), []
    >>> for load in (1.0, 2.0):
    ...     disc = DiametralDisc(P=load, D=40e-3, t=6e-3)
    ...     omap = optical_map(disc, PixelGrid((120, 120), 0.4e-3), PSM4_ASSUMED,
    ...                        reflection=False)
    ...     q = np.where(omap.mask[..., None], omap.q[:, :, 0], retarder(0.0, 0.0))
    ...     photos.append(folder / f"disc_{load:g}N.png")
    ...     write_image(photos[-1], monochrome_image(q, dark_field_circular(), Camera()))
    >>> cal = fringekit.calibrate_disc(photos, load_N=[1.0, 2.0], diameter_mm=40,
    ...                                thickness_mm=6)
    >>> round(cal.f_sigma_N_per_m), round(PSM4_ASSUMED.f_sigma)
    (386, 386)
    """
    t0 = time.perf_counter()
    if len(load_N) != len(images):
        raise InputError(
            f"--load-N: {len(load_N)} load(s) for {len(images)} photograph(s); give one per photo"
        )
    photos = [grey_channel(load_image(p, dark=dark).data) for p in images]
    names, all_loads = [str(p) for p in images], [float(v) for v in load_N]
    if reference is not None:
        photos.append(grey_channel(load_image(reference, dark=dark).data))
        names.append(str(reference))
        all_loads.append(0.0)
    shapes = {p.shape for p in photos}
    if len(shapes) > 1:
        raise InputError(
            f"--disc: the photographs differ in size ({sorted(shapes)}); allowed: one size"
        )
    D, t = diameter_mm * 1e-3, thickness_mm * 1e-3
    strongest = photos[int(np.argmax(all_loads))]
    geometry, how = _geometry(strongest, centre_px, radius_px, pixel_mm, diameter_mm)
    (echo or (lambda line: None))(
        f"disc: centre ({geometry.row:.1f}, {geometry.col:.1f}) px, radius "
        f"{geometry.radius_px:.1f} px from the {how}; fitting {len(photos)} photograph(s)"
    )
    discs = [DiscImage(p, P, n) for p, P, n in zip(photos, all_loads, names, strict=True)]
    fit, worst = _fit(discs, geometry, D, t, field, reference is not None, residual_field)
    if worst > REFUSE_RESIDUAL:
        raise _unexplained(worst, len(set(all_loads)), residual_field)
    warnings = []
    if worst > WARN_RESIDUAL:
        warnings.append(
            f"RMS residual {100 * worst:.0f} % of the fringe amplitude (a good fit leaves 1-2 "
            "%): f_sigma is uncertain beyond its stated sd; check the loads, the diameter, "
            "uneven residual stress, or fringes too dense for the pixels"
        )
    g = fit.geometry
    series = getattr(fit, "load_scales", None) is not None
    summary = {
        "disc": {
            "centre_px": [float(g.row), float(g.col)],
            "radius_px": float(g.radius_px),
            "load_axis_tilt_deg": float(np.degrees(g.angle_rad)),
            "found_from": how,
            "pixel_mm": float(diameter_mm / 2 / g.radius_px),
        },
        "diameter_mm": diameter_mm,
        "thickness_mm": thickness_mm,
        "field": field,
        "wavelength_nm": wavelength_nm,
        "reference": None if reference is None else str(reference),
        "sd_method": fit.sd_method,
        "model_evaluations": fit.evaluations,
        "warnings": warnings,
        "residual_field": "series" if series else "uniform",
        "time_s": time.perf_counter() - t0,
    }
    if series:
        summary["series"] = {
            "load_scales": list(fit.load_scales),
            "own_centre_orders": list(fit.own_centre_orders),
            "r_squared": fit.r_squared,
            "offset_order_is": "the frozen order at the centre modulo one fringe",
        }
    images_out = [
        {"file": n, "load_N": P, "centre_order": float(c), "residual_rms": float(r)}
        for n, P, c, r in zip(names, all_loads, fit.centre_orders, fit.residuals, strict=True)
    ]
    orders = [_order_map(p.shape, g, fit, P, D, t) for p, P in zip(photos, all_loads, strict=True)]
    return DiscCalibration(
        float(fit.f_sigma),
        float(fit.f_sigma_sd),
        float(fit.offset_order),
        images_out,
        summary,
        photos,
        orders,
    )


#: Largest departure of a photograph's best-fitting load from its --load-N in a series.
LOAD_TOLERANCE = 0.03


def _check_loads(fit, names) -> None:
    """Refuse a series whose photographs disagree with their loads (one line)."""
    off = [(abs(s - 1), s, n) for s, n in zip(fit.load_scales, names, strict=True) if s == s]
    worst, scale, name = max(off)
    if worst > LOAD_TOLERANCE:
        scales = ", ".join(f"{s:.3f}" for s in fit.load_scales if s == s)
        raise RefusedError(
            f"--load-N: the photographs' fringe orders are not proportional to the loads: "
            f"{Path(name).name} fits a load {100 * (scale - 1):+.0f} % off its --load-N "
            f"(best factor per photo {scales}; allowed within {100 * LOAD_TOLERANCE:.0f} %)"
        )


def run_disc_photos(
    images,
    loads,
    *,
    diameter_mm,
    thickness_mm,
    out,
    wavelength_nm=None,
    reference=None,
    field="dark",
    centre=None,
    radius_px=None,
    pixel_mm=None,
    dark=None,
    echo=print,
    residual_field="auto",
) -> dict:
    """``fringekit calibrate --disc``: :func:`calibrate_disc`, then write ``out``."""
    with claim_output(out, command="calibrate", inputs=[*images, reference, dark]) as work:
        cal = calibrate_disc(
            images,
            load_N=loads,
            diameter_mm=diameter_mm,
            thickness_mm=thickness_mm,
            wavelength_nm=wavelength_nm,
            reference=reference,
            field=field,
            centre_px=centre,
            radius_px=radius_px,
            pixel_mm=pixel_mm,
            dark=dark,
            echo=echo,
            residual_field=residual_field,
        )
        cal.write(work)
    return {**cal.result(), "summary": cal.summary}
