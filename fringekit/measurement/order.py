"""Analyse fringe images as an API: :func:`analyze` turns image files into a fringe-order
map (:class:`Analysis`), with typed options per method; :meth:`Analysis.write` gives the
folder of ``fringekit analyze``.

Pixel coordinates (row, col) are those of the image; lengths the user gives are in mm.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tifffile

from fringekit.analysis import load_image, principal_stress_difference
from fringekit.config.files import check_number
from fringekit.config.schema import schema_key
from fringekit.errors import ConfigError, InputError
from fringekit.measurement.methods import analyse_phase, analyse_rgb
from fringekit.measurement.mono import analyse_mono
from fringekit.measurement.options import MonoOptions, PhaseOptions, Region, RGBOptions
from fringekit.measurement.regions import disc_region
from fringekit.measurement.write import write_analysis

__all__ = ["Analysis", "analyze", "choose_method", "counts"]

METHODS = ("phase", "rgb", "mono")


#: Share of the region of interest that must be reliable before analyze stops warning
#: (and, with ``--strict``, exits 1).
MIN_RELIABLE_SHARE = 0.5


def counts(order, reliable, mask, part: dict) -> dict:
    """Pixel counts, the order range and the reliability warning of an analysis."""
    finite = np.isfinite(order)
    roi = int(mask.sum())
    share = float(np.sum(reliable & mask)) / roi if roi else 0.0
    out = {
        "shape": list(order.shape),
        "valid_pixels": int(finite.sum()),
        "reliable_pixels": int(np.sum(reliable)),
        "masked_pixels": int((~mask).sum()),
        "fringe_order_range": [float(np.nanmin(order)), float(np.nanmax(order))]
        if finite.any()
        else None,
        "reliable_fraction_of_roi": share,
    }
    warnings = []
    if share < MIN_RELIABLE_SHARE:
        why = part.get("unreliable_reason", "the order map is mostly a guess")
        warnings.append(
            f"only {100 * share:.0f} % of the region of interest is reliable (fewer than "
            f"{100 * MIN_RELIABLE_SHARE:.0f} %): {why}"
        )
    if "extra_warning" in part:
        warnings.append(part["extra_warning"])
    if warnings:
        out["warning"] = "; ".join(warnings)
    return out


_OPTIONS = {"phase": PhaseOptions, "rgb": RGBOptions, "mono": MonoOptions}


@dataclass(frozen=True)
class Analysis:
    """A fringe-order map read off images, with the method's other maps.

    Attributes
    ----------
    method : str
        ``"phase"``, ``"rgb"`` or ``"mono"``.
    fringe_order : ndarray (rows, cols)
        Total fringe order, NaN where unknown.
    reliable : ndarray of bool (rows, cols)
        Pixels whose order the method stands behind.
    region : Region
        The region of interest as given.
    roi_mask : ndarray of bool (rows, cols)
        The region of interest analysed (the region less saturated pixels).
    maps : dict of str to ndarray
        Every map of ``maps.npz``: the two above and the method's own (``isoclinic_rad``,
        ``modulation``, ``order_sd``, ``colour_error``, ``stress_difference_Pa``...).
    pixel_mm : float
        The pixel pitch on the sheet (mm), 0 when not known.
    origin_px : (row, col)
        The pixel of the sensor origin.
    summary : dict
        Counts of valid and reliable pixels, the order range, warnings, the method's info.

    Examples
    --------
    See :func:`analyze`; the maps by name:

    >>> import tempfile, fringekit
    >>> folder = fringekit.predict("small").write(tempfile.mkdtemp())
    >>> an = fringekit.analyze(folder / "state_01" / "dark_field.png", pixel_mm=12 / 64,
    ...                        region=fringekit.Region(exclude_circles=[(31.5, 31.5, 9)]))
    >>> an.method, sorted(an.maps)[:4]
    ('mono', ['fringe_centres', 'fringe_order', 'normalised_intensity', 'order_sd'])
    """

    method: str
    maps: dict = field(repr=False)
    region: Region
    roi_mask: np.ndarray = field(repr=False)
    pixel_mm: float
    origin_px: tuple[float, float]
    summary: dict = field(repr=False)

    @property
    def fringe_order(self) -> np.ndarray:
        return self.maps["fringe_order"]

    @property
    def reliable(self) -> np.ndarray:
        return self.maps["reliable"]

    def write(self, folder, *, line=None, points=None) -> Path:
        """Write ``maps.npz``, the figures, ``profile.csv``/``.png`` along ``line`` (r0,
        c0, r1, c1 px; default across the region), ``points.csv`` for a CSV of points, and
        ``summary.json`` into ``folder``; return it."""
        return write_analysis(self, Path(folder), line=line, points=points)


def _tiff_pages(path: str) -> int:
    """The pages of a TIFF file (0 when it cannot be read: load_image then says why)."""
    try:
        with tifffile.TiffFile(path) as tif:
            return len(tif.pages)
    except (OSError, tifffile.TiffFileError):
        return 0


def choose_method(method: str | None, paths: list[str]) -> str:
    """The method asked for, or the default for the images given (checked): ``phase`` for
    several images or one multi-page TIFF (a six-step stack), else ``rgb`` for a colour
    image and ``mono`` for a grey one."""
    if method is None:
        stack = len(paths) > 1 or (
            paths[0].lower().endswith((".tif", ".tiff")) and _tiff_pages(paths[0]) > 1
        )
        method = "phase" if stack else ("rgb" if load_image(paths[0]).data.ndim == 3 else "mono")
    if method not in METHODS:
        raise InputError(f"--method {method} is not allowed; use phase, rgb or mono")
    return method


def analyze(
    images: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    method: str | None = None,
    pixel_mm: float = 0.0,
    origin_px: tuple[float, float] | None = None,
    region: Region | None = None,
    dark: str | os.PathLike | None = None,
    anchor_order: float = 0.0,
    order_at: Sequence[tuple[float, float, float]] = (),
    fringe_value_N_per_m: float | None = None,
    thickness_mm: float | None = None,
    options: PhaseOptions | RGBOptions | MonoOptions | None = None,
) -> Analysis:
    """Fringe order from six phase-stepped images, one white-light colour image, or one
    monochrome photograph.

    Parameters
    ----------
    images : path or sequence of paths
        ``phase``: six files in :data:`fringekit.analysis.SIX_STEP_ORDER` or one 6-page
        TIFF; ``rgb``: one colour image; ``mono``: one image.
    method : {"phase", "rgb", "mono"}, optional
        Default ``rgb`` for one colour image, ``mono`` for one grey image, ``phase``
        otherwise.
    pixel_mm : float
        The pixel pitch on the sheet (mm) for the sensor frame; 0 keeps pixels.
    origin_px : (row, col), optional
        The pixel of the sensor origin; default the image centre.
    region : Region, optional
        The region of interest; default the whole image.
    dark : path, optional
        A dark frame subtracted from every image.
    anchor_order : float
        The order of the image border (the far field); ``order_at`` gives (row, col,
        order) of pixels of known order instead, each the lowest about it.
    fringe_value_N_per_m, thickness_mm : float, optional
        Both give the principal stress difference map (``stress_difference_Pa``).
    options : PhaseOptions, RGBOptions or MonoOptions, optional
        The method's options (default: its defaults).

    Returns
    -------
    Analysis
        The maps and the summary; nothing is written.

    Examples
    --------
    The six phase-stepped images of the small built-in case, read back against the
    prediction's own order, with the contact zone left out:

    >>> import tempfile
    >>> import numpy as np
    >>> import fringekit
    >>> pred = fringekit.predict("small")
    >>> folder = pred.write(tempfile.mkdtemp())
    >>> steps = sorted((folder / "state_01" / "six_step").glob("step*.png"))
    >>> an = fringekit.analyze(steps, pixel_mm=12 / 64,
    ...                        region=fringekit.Region(exclude_circles=[(31.5, 31.5, 9)]))
    >>> ok = an.reliable & np.isfinite(pred.states[0].fringe_order)
    >>> error = np.abs(an.fringe_order - pred.states[0].fringe_order)[ok]
    >>> an.method, bool(np.median(error) < 0.02)
    ('phase', True)
    """
    paths = (
        [os.fspath(images)]
        if isinstance(images, (str, os.PathLike))
        else [os.fspath(p) for p in images]
    )
    if not paths:
        raise InputError("analyze needs at least one image")
    if not (np.isfinite(pixel_mm) and pixel_mm >= 0):
        raise InputError(
            f"--pixel-mm {pixel_mm} is not allowed; give the pixel pitch on the sheet (mm, > 0), "
            "or 0 for pixels"
        )
    _check_stress_inputs(fringe_value_N_per_m, thickness_mm)
    method = choose_method(method, paths)
    opts = options if options is not None else _OPTIONS[method]()
    if not isinstance(opts, _OPTIONS[method]):
        raise InputError(
            f"options {type(opts).__name__} are not for --method {method}; give "
            f"{_OPTIONS[method].__name__}"
        )
    region = Region() if region is None else region
    circle, pixel_size = region.circle, pixel_mm * 1e-3
    disc = None
    if region.disc_diameter_mm is not None:
        disc = disc_region(paths[0], region.disc_diameter_mm * 1e-3, dark)
        circle, pixel_size = disc["roi_circle"], pixel_size or disc["pixel_size"]
        origin_px = origin_px if origin_px is not None else disc["origin_px"]
    mask_args = (
        circle,
        list(region.exclude_circles),
        region.polygon,
        [list(p) for p in region.exclude_polygons],
        None if region.mask is None else os.fspath(region.mask),
    )
    order_at = [tuple(p) for p in order_at]
    if method == "phase":
        kw = dataclasses.asdict(opts)
        res = analyse_phase(paths, dark, mask_args, anchor_order, order_at, **kw)
    elif method == "mono":
        res = analyse_mono(paths, dark, mask_args, anchor_order, order_at, dataclasses.asdict(opts))
    else:
        kw = opts.as_kwargs()
        res = analyse_rgb(
            paths, dark, mask_args, order_at=order_at, anchor_order=anchor_order, **kw
        )
    order, reliable, maps, part, mask = res
    summary: dict = {"method": method, "images": paths}
    if disc is not None:
        summary["disc_found"] = disc["info"]
    summary.update((k, v) for k, v in part.items() if k != "extra_warning")
    rows, cols = order.shape
    origin = tuple(origin_px) if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
    maps.update(fringe_order=order, reliable=reliable, pixel_size_m=np.array(pixel_size))
    if fringe_value_N_per_m is not None:
        maps["stress_difference_Pa"] = principal_stress_difference(
            order, fringe_value_N_per_m, thickness_mm * 1e-3
        )
    summary.update(counts(order, reliable, mask, part))
    summary.update(pixel_size_mm=pixel_size * 1e3, origin_px=[float(v) for v in origin])
    return Analysis(method, maps, region, mask, pixel_size * 1e3, origin, summary)


def _check_stress_inputs(fringe_value_N_per_m, thickness_mm) -> None:
    """Both or neither, each in its config key's range (a 1e-300 mm sheet gave a stress
    map of inf)."""
    if (fringe_value_N_per_m is None) != (thickness_mm is None):
        raise InputError("give both the fringe value and the thickness for stress, or neither")
    if fringe_value_N_per_m is None:
        return
    for name, value, key in (
        ("fringe_value_N_per_m", fringe_value_N_per_m, "optics.f_sigma_N_per_m"),
        ("thickness_mm", thickness_mm, "sheet.thickness_mm"),
    ):
        try:
            check_number(name, value, schema_key(key))
        except ConfigError as exc:
            raise InputError(f"{exc} (the range of config key {key})") from None
