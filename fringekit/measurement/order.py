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

from fringekit.analysis import load_image, principal_stress_difference
from fringekit.errors import InputError
from fringekit.measurement.methods import analyse_phase, analyse_rgb
from fringekit.measurement.mono import analyse_mono
from fringekit.measurement.regions import disc_region
from fringekit.measurement.write import write_analysis

__all__ = [
    "LINE_HALF_WIDTH_PX",
    "Analysis",
    "MonoOptions",
    "PhaseOptions",
    "RGBOptions",
    "Region",
    "analyze",
    "choose_method",
    "exclusion_polygon",
]

METHODS = ("phase", "rgb", "mono")


#: Half-width (px) of an excluded line (an exclusion polygon of two vertices: a crack).
LINE_HALF_WIDTH_PX = 1.5


def exclusion_polygon(vertices) -> tuple:
    """An ``--exclude-polygon``: 3 or more vertices as given; two vertices, the line
    between them widened to a 3 px band (a crack)."""
    if len(vertices) >= 3:
        return tuple(tuple(v) for v in vertices)
    if len(vertices) != 2 or tuple(vertices[0]) == tuple(vertices[1]):
        raise InputError(
            f"--exclude-polygon {' '.join(f'{r:g},{c:g}' for r, c in vertices)}: allowed: two "
            "distinct vertices (a line) or three or more (a polygon)"
        )
    (r0, c0), (r1, c1) = vertices
    length = ((r1 - r0) ** 2 + (c1 - c0) ** 2) ** 0.5
    nr, nc = -(c1 - c0) / length * LINE_HALF_WIDTH_PX, (r1 - r0) / length * LINE_HALF_WIDTH_PX
    return ((r0 + nr, c0 + nc), (r1 + nr, c1 + nc), (r1 - nr, c1 - nc), (r0 - nr, c0 - nc))


@dataclass(frozen=True)
class Region:
    """The region of interest of an image, in pixels (row, col).

    Attributes
    ----------
    circle : (row, col, radius), optional
        A circular region; default the whole image.
    polygon : sequence of (row, col), optional
        A polygonal region (3 or more vertices).
    exclude_circles : sequence of (row, col, radius)
        Circles left out (an indenter's contact zone, a load point).
    exclude_polygons : sequence of sequences of (row, col)
        Polygons left out; one of two vertices is the line between them, 3 px wide (a
        crack).
    disc_diameter_mm : float, optional
        Find a circular specimen of this diameter in the first image: it sets the circle,
        the pixel size and the origin.

    Examples
    --------
    >>> from fringekit import Region
    >>> Region(exclude_circles=[(127.5, 127.5, 16)]).exclude_circles
    ((127.5, 127.5, 16),)
    """

    circle: tuple[float, float, float] | None = None
    polygon: tuple | None = None
    exclude_circles: tuple = ()
    exclude_polygons: tuple = ()
    disc_diameter_mm: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "exclude_circles", tuple(tuple(v) for v in self.exclude_circles))
        polygons = tuple(exclusion_polygon(p) for p in self.exclude_polygons)
        object.__setattr__(self, "exclude_polygons", polygons)


@dataclass(frozen=True)
class PhaseOptions:
    """Options of the six-step phase method.

    Attributes
    ----------
    min_modulation : float
        Pixels whose modulation is below this fraction are unreliable.
    fold : {"count", "isoclinic"}
        How the folded phase is resolved (the other resolution checks it).
    reference : sequence of paths, optional
        Six images of the unloaded specimen; their residual retardation is removed.

    Examples
    --------
    >>> from fringekit import PhaseOptions
    >>> PhaseOptions(fold="isoclinic")
    PhaseOptions(min_modulation=0.1, fold='isoclinic', reference=None)
    """

    min_modulation: float = 0.1
    fold: str = "count"
    reference: tuple | None = None

    def __post_init__(self):
        if self.fold not in ("count", "isoclinic"):
            raise InputError(f"--fold {self.fold} is not allowed; use count or isoclinic")
        if not 0 <= self.min_modulation < 1:
            raise InputError(
                f"--min-modulation {self.min_modulation} is not allowed; give a fraction in [0, 1)"
            )


@dataclass(frozen=True)
class RGBOptions:
    """Options of the white-light colour method.

    Attributes
    ----------
    colour_table : path, optional
        The colour calibration table of RGB photoelasticity (CSV ``order,R,G,B``);
        default a synthetic chart of the light and camera below.
    light, camera : str
        The chart's light source and camera sensitivities.
    max_order : float
        The chart's range (fringe orders).
    exposure : float
        The chart's exposure (fraction of full scale).
    seeds : sequence of (row, col, order)
        Pixels of known order that start the refined search.
    window : float
        Half-width of the refined search about the neighbours' order (fringe).

    Examples
    --------
    >>> from fringekit import RGBOptions
    >>> RGBOptions(max_order=3.0, seeds=[(0, 0, 0.03)]).max_order
    3.0
    """

    colour_table: str | None = None
    light: str = "LED"
    camera: str = "CIE1931"
    max_order: float = 4.0
    exposure: float = 0.9
    seeds: tuple = ()
    window: float = 0.25

    def __post_init__(self):
        for name in ("max_order", "exposure", "window"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(
                    f"--{name.replace('_', '-')} {v} is not allowed; give a number > 0"
                )

    def as_kwargs(self) -> dict:
        chart = {
            "light": self.light,
            "camera": self.camera,
            "max_order": self.max_order,
            "exposure": self.exposure,
        }
        seeds = [tuple(s) for s in self.seeds]
        return {
            "colour_table": self.colour_table,
            "chart": chart,
            "seeds": seeds,
            "window": self.window,
        }


@dataclass(frozen=True)
class MonoOptions:
    """Options of the one-photograph monochrome method.

    Attributes
    ----------
    field : {"dark", "bright"}
        The polariscope's field.
    flat : path, optional
        An image of the light alone (no specimen, or no load in a bright field), for the
        envelope instead of the fringes' own.
    smooth_px : float
        Gaussian smoothing of the photograph before counting (px).

    Examples
    --------
    >>> from fringekit import MonoOptions
    >>> MonoOptions(field="bright").field
    'bright'
    """

    field: str = "dark"
    flat: str | None = None
    smooth_px: float = 0.5

    def __post_init__(self):
        if self.field not in ("dark", "bright"):
            raise InputError(f"--field {self.field} is not allowed; use dark or bright")
        if not (np.isfinite(self.smooth_px) and self.smooth_px >= 0):
            raise InputError(f"--smooth-px {self.smooth_px} is not allowed; give a number >= 0")


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


def choose_method(method: str | None, paths: list[str]) -> str:
    """The method asked for, or the default for the images given (checked)."""
    if method is None:
        single = len(paths) == 1 and not paths[0].lower().endswith((".tif", ".tiff"))
        method = ("rgb" if load_image(paths[0]).data.ndim == 3 else "mono") if single else "phase"
    if method not in METHODS:
        raise InputError(f"--method {method} is not allowed; use phase, rgb or mono")
    return method


def analyze(
    images: str | os.PathLike | Sequence[str | os.PathLike],
    *,
    method: str | None = None,
    pixel_mm: float = 0.0,
    origin_px: tuple[float, float] | None = None,
    region: Region = Region(),
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
    region : Region
        The region of interest.
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
    method = choose_method(method, paths)
    opts = options if options is not None else _OPTIONS[method]()
    if not isinstance(opts, _OPTIONS[method]):
        raise InputError(
            f"options {type(opts).__name__} are not for --method {method}; give "
            f"{_OPTIONS[method].__name__}"
        )
    if (fringe_value_N_per_m is None) != (thickness_mm is None):
        raise InputError("give both the fringe value and the thickness for stress, or neither")
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
    )
    order_at = [tuple(p) for p in order_at]
    if method == "phase":
        kw = dataclasses.asdict(opts)
        res = analyse_phase(paths, dark, mask_args, anchor_order, order_at, **kw)
    elif method == "mono":
        res = analyse_mono(paths, dark, mask_args, anchor_order, order_at, dataclasses.asdict(opts))
    else:
        res = analyse_rgb(paths, dark, mask_args, **opts.as_kwargs())
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
