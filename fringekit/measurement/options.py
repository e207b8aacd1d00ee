"""What :func:`fringekit.analyze` takes besides the images: the region of interest
(:class:`Region`, in pixels) and the options of each method, checked when they are made."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fringekit._memory import check_memory, gaussian_bytes
from fringekit.errors import InputError

__all__ = [
    "LINE_HALF_WIDTH_PX",
    "MonoOptions",
    "PhaseOptions",
    "RGBOptions",
    "Region",
    "exclusion_polygon",
]


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
    mask : path, optional
        A mask image of the images' size, data where it is bright (``predict``'s
        ``mask.png``). Regions at the no-data level of fringekit's own images (``predict``'s
        contact zones) are left out with or without it.

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
    mask: str | None = None

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
        Pixels of known order that start the refined search (with ``order_at``; without
        either it starts from the region's border at ``anchor_order``, as phase and mono).
    window : float
        Half-width of the refined search about the neighbours' order (fringe).
    search : {"refined", "plain"}
        ``refined``: fringe-order continuity from the seeds (refined TFP), to about order
        6.5; ``plain``: every pixel against the whole table, to about order 3.
    adapt : {"auto", "seeds", "off"}
        Colour adaptation of the table to the image (refined search): to the seeds and
        the pixels the search solves below order 3 (``auto``), to the seeds only (a
        no-load region), or none.

    Examples
    --------
    >>> from fringekit import RGBOptions
    >>> RGBOptions(max_order=3.0, seeds=[(0, 0, 0.03)]).max_order
    3.0
    """

    colour_table: str | None = None
    light: str = "LED"
    camera: str = "CIE1931"
    max_order: float = 7.0
    exposure: float = 0.9
    seeds: tuple = ()
    window: float = 0.25
    search: str = "refined"
    adapt: str = "auto"

    def __post_init__(self):
        if self.search not in ("refined", "plain"):
            raise InputError(f"--search {self.search} is not allowed; use refined or plain")
        if self.adapt not in ("auto", "seeds", "off"):
            raise InputError(f"--adapt {self.adapt} is not allowed; use auto, seeds or off")
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
            "search_mode": self.search,
            "adapt": self.adapt,
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
        check_memory(
            gaussian_bytes(self.smooth_px),
            f"the smoothing kernel ({2 * int(4 * self.smooth_px + 0.5) + 1:.3g} taps)",
            f"--smooth-px {self.smooth_px:g}",
            hint="give a smoothing of a few pixels",
        )
