"""Through-thickness integration of a stress field into an :class:`OpticalMap`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .grid import PixelGrid, RaySamples, sample_rays
from .jones import characteristic, integrate_path, qmul, qtranspose, to_matrix
from .stressoptic import StressOpticLaw, check_wavelengths

__all__ = [
    "OpticalMap",
    "optical_map",
    "integrate_samples",
    "BRANCH_DISTINCT",
    "BRANCH_RATIO",
    "BRANCH_JUMP",
]

#: Two order values closer than this (fringe) are one value for the branch test.
BRANCH_DISTINCT = 0.05
#: A pixel's branch is ambiguous when another value lies within this many times the
#: distance between the chosen value and the simple order (see OpticalMap.branch_ambiguous).
BRANCH_RATIO = 3.0
#: ... or when the order steps to a neighbour by this much more than the simple order does
#: (fringe): a switch of branch, not a gradient.
BRANCH_JUMP = 0.25


def _switches(chosen: np.ndarray, guide: np.ndarray) -> np.ndarray:
    """Both pixels of every step between 4-neighbours that exceeds the guide's step there
    by more than :data:`BRANCH_JUMP`: a switch of branch, not a gradient."""
    out = np.zeros(chosen.shape, bool)
    with np.errstate(invalid="ignore"):
        down = np.abs(np.diff(chosen, axis=0) - np.diff(guide, axis=0)) > BRANCH_JUMP
        right = np.abs(np.diff(chosen, axis=1) - np.diff(guide, axis=1)) > BRANCH_JUMP
    out[:-1] |= down
    out[1:] |= down
    out[:, :-1] |= right
    out[:, 1:] |= right
    return out


@dataclass(frozen=True)
class OpticalMap:
    """What the sheet does to light, per pixel and wavelength (made by :func:`optical_map`).

    Parameters
    ----------
    grid : PixelGrid
    wavelengths : (W,) float array
        Wavelengths (m).
    q : (rows, cols, W, 4) float array
        Path quaternions (reflection double pass when ``reflection``); ``jones`` gives
        the (rows, cols, W, 2, 2) complex matrices.
    simple_order : (rows, cols) float array
        N = (passes) * integral(ds dz) / f_sigma at the law's reference wavelength, the
        rotation-free estimate; NaN outside ``mask``.
    mask : (rows, cols) bool array
        True where the ray crosses the photoelastic layer.
    reflection : bool
    law : StressOpticLaw
    timings : dict
        Seconds spent sampling and integrating.

    Examples
    --------
    Viewed in reflection, the light crosses the 3 mm sheet twice:

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import optical_map
    >>> omap = optical_map(field, PixelGrid((2, 2), 1e-3), PSM4_ASSUMED, n_samples=4)
    >>> omap.q.shape, omap.jones.shape, bool(omap.mask.all())
    ((2, 2, 1, 4), (2, 2, 1, 2, 2), True)
    >>> round(float(omap.fringe_order()[0, 0]), 4), round(float(omap.simple_order[0, 0]), 4)
    (1.5548, 1.5548)
    >>> round(float(omap.principal_angle()[0, 0]), 6), bool(omap.branch_ambiguous().any())
    (0.0, False)
    """

    grid: PixelGrid
    wavelengths: np.ndarray
    q: np.ndarray
    simple_order: np.ndarray
    mask: np.ndarray
    reflection: bool
    law: StressOpticLaw
    timings: dict = field(default_factory=dict, compare=False)

    @property
    def jones(self) -> np.ndarray:
        """(rows, cols, W, 2, 2) complex Jones matrices."""
        return to_matrix(self.q)

    @cached_property
    def _char(self):
        return characteristic(self.q)

    @property
    def retardation(self) -> np.ndarray:
        """(rows, cols, W) characteristic retardation Delta* wrapped to [0, pi] (rad)."""
        return self._char[0]

    @property
    def isoclinic(self) -> np.ndarray:
        """(rows, cols, W) characteristic angle theta* (rad)."""
        return self._char[1]

    @property
    def rotation(self) -> np.ndarray:
        """(rows, cols, W) characteristic rotation gamma* (rad)."""
        return self._char[2]

    def _branch(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        d = self.retardation[..., k] / (2 * np.pi)
        guide = self.simple_order * self.law.relative_retardation(self.wavelengths[k])[0]
        cands = np.stack([d + np.round(guide - d), -d + np.round(guide + d)])
        pick = np.argmin(np.abs(cands - guide), axis=0)
        order = np.take_along_axis(cands, pick[None], 0)[0]
        angle = self.isoclinic[..., k] + 0.5 * np.pi * pick
        angle = (angle + np.pi / 2) % np.pi - np.pi / 2
        return np.where(self.mask, order, np.nan), np.where(self.mask, angle, np.nan)

    def fringe_order(self, k: int = 0) -> np.ndarray:
        """(rows, cols) total characteristic fringe order at wavelength index k.

        Delta* is known modulo 2 pi and up to sign (a sign change swaps the axes by
        pi/2); the branch +-Delta*/(2 pi) + n nearest to the simple order (scaled to
        that wavelength) is returned, so it equals the exact order wherever the axes
        do not rotate along the ray. NaN outside ``mask``.
        """
        return self._branch(k)[0]

    def branch_ambiguous(self, k: int = 0) -> np.ndarray:
        """(rows, cols) bool: pixels where the simple order cannot choose the branch.

        The order is one of the values +-Delta*/(2 pi) + n. :meth:`fringe_order` takes
        the one nearest the rotation-free simple order g (distance e1); where the axes
        turn through the sheet, g is off by an unknown amount and the choice can jump
        between values from pixel to pixel (terraces). A pixel is flagged when another
        value, distinct by more than :data:`BRANCH_DISTINCT` fringe, lies within
        :data:`BRANCH_RATIO` times e1 of g: the guide misses the chosen value by more
        than a third of the way to the next candidate; or when the order steps to a 4-neighbour
        by more than :data:`BRANCH_JUMP` beyond the simple order's step there (a switch of
        branch: both pixels). Exact guides never flag. False outside ``mask``.
        """
        d = self.retardation[..., k] / (2 * np.pi)  # [0, 0.5]
        guide = self.simple_order * self.law.relative_retardation(self.wavelengths[k])[0]
        base = np.round(guide)
        n = np.arange(-1, 2)[:, None, None]
        cands = np.concatenate([d + base + n, -d + base + n])  # (6, rows, cols)
        chosen = self.fringe_order(k)
        dist = np.abs(cands - guide)
        e1 = np.abs(chosen - guide)
        other = np.abs(cands - chosen) > BRANCH_DISTINCT
        e2 = np.min(np.where(other, dist, np.inf), axis=0)
        with np.errstate(invalid="ignore"):
            flagged = self.mask & (e2 < BRANCH_RATIO * e1)
            flagged |= _switches(chosen, guide)
        return flagged & self.mask

    def principal_angle(self, k: int = 0) -> np.ndarray:
        """(rows, cols) characteristic axis angle (rad) consistent with :meth:`fringe_order`.

        The isoclinic of the branch chosen there: theta* where +Delta* was taken,
        theta* + pi/2 where -Delta* was, wrapped to [-pi/2, pi/2).
        """
        return self._branch(k)[1]


def integrate_samples(
    samples: RaySamples,
    law: StressOpticLaw,
    wavelengths,
    *,
    reflection: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Path quaternions and simple fringe order from ray samples (one layer).

    One layer of :func:`integrate_layers`.

    Parameters
    ----------
    samples : RaySamples
    law : StressOpticLaw
    wavelengths : (W,) float array
        Wavelengths (m).
    reflection : bool
        Double pass U^T U.

    Returns
    -------
    q : (P, W, 4) float array
        Path quaternions per pixel.
    simple : (P,) float array
        Rotation-free fringe order at the law's reference wavelength.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import integrate_samples, sample_rays
    >>> rays = sample_rays(field, PixelGrid((2, 2), 1e-3), n_samples=4)
    >>> q, simple = integrate_samples(rays, PSM4_ASSUMED, [575e-9], reflection=False)
    >>> q.shape, simple.round(4).tolist()
    ((4, 1, 4), [0.7774, 0.7774, 0.7774, 0.7774])
    """
    q, simple, _ = integrate_layers([samples], [law], wavelengths, reflection=reflection)
    return q, simple


def integrate_layers(
    samples: list[RaySamples],
    laws: list[StressOpticLaw],
    wavelengths,
    *,
    reflection: bool = True,
    reference: int = -1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path quaternions through stacked layers of different materials.

    Parameters
    ----------
    samples : list of RaySamples
        On the same grid, in the order the light meets them (for the sensor viewed from
        the PC side: the polycarbonate, then the sheet; the coated contact face reflects
        it back, ``docs/theory.md``).
    laws : list of StressOpticLaw
        One per layer.
    wavelengths : (W,) float array
        Wavelengths (m).
    reflection : bool
        Double pass U^T U.
    reference : int
        The layer whose law defines the fringe order (default: the last, the
        photoelastic sheet).

    Returns
    -------
    q : (P, W, 4) float array
        Path quaternions per pixel.
    simple : (P,) float array
        Rotation-free order summed over the layers, in fringes of the reference law at
        its reference wavelength.
    valid : (P,) bool array
        Rays valid in every layer.

    Raises
    ------
    ValueError
        Not one law per layer, or wavelengths outside 360-830 nm.

    Examples
    --------
    The same stress in a polycarbonate layer adds 386 / 7000 of the sheet's order:

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import POLYCARBONATE_ASSUMED, integrate_layers, sample_rays
    >>> rays = sample_rays(field, PixelGrid((1, 2), 1e-3), n_samples=4)
    >>> laws = [POLYCARBONATE_ASSUMED, PSM4_ASSUMED]
    >>> q, simple, valid = integrate_layers([rays, rays], laws, [575e-9], reflection=False)
    >>> q.shape, simple.round(4).tolist(), valid.tolist()
    ((2, 1, 4), [0.8202, 0.8202], [True, True])
    """
    if len(samples) != len(laws) or not samples:
        raise ValueError("give one StressOpticLaw per layer of samples (and at least one)")
    lam = check_wavelengths(wavelengths)
    first = samples[0]
    if any(
        not (np.array_equal(s.index, first.index) and np.array_equal(s.mirror, first.mirror))
        for s in samples[1:]
    ):  # layers that fold the pixels differently meet pixel by pixel
        samples = [s.per_pixel() for s in samples]
        first = samples[0]
    ds = np.concatenate([s.ds for s in samples], axis=1)
    th = np.concatenate([s.theta for s in samples], axis=1)
    dz = np.concatenate([s.dz for s in samples], axis=1)
    valid = np.logical_and.reduce([s.valid for s in samples])
    # a row is integrated when any pixel that uses it is valid in every layer
    row_valid = np.zeros(len(ds), bool)
    row_valid[first.index[valid]] = True
    k = np.concatenate(
        [
            np.repeat(law.retardation_per_stress_length(lam)[None, :], s.ds.shape[1], axis=0)
            for s, law in zip(samples, laws, strict=True)
        ]
    )
    r = np.flatnonzero(row_valid)
    q_rows = integrate_path(ds[r], th[r], dz[r], k)
    if reflection:
        q_rows = qmul(qtranspose(q_rows), q_rows)  # U_refl = U^T U (docs/theory.md, unfolded frame)
    ref = laws[reference]
    passes = 2.0 if reflection else 1.0
    simple_rows = np.zeros(len(r))
    for s, law in zip(samples, laws, strict=True):
        k_ref = law.retardation_per_stress_length(np.array([ref.wavelength_ref]))[0]
        simple_rows += passes * np.sum(s.ds[r] * s.dz[r], axis=1) * k_ref / (2 * np.pi)
    # back to pixels: a mirrored pixel's path is its row's conjugated by the mirror,
    # which flips the x and y quaternion parts (theta -> -theta in every slab)
    slot = np.full(len(ds), len(r))  # rows not integrated -> the identity appended below
    slot[r] = np.arange(len(r))
    pick = np.where(valid, slot[first.index], len(r))
    identity = np.zeros((1, len(lam), 4))
    identity[..., 0] = 1.0  # invalid pixels: no retardation
    q = np.concatenate([q_rows, identity]).take(pick, axis=0)
    flip = np.flatnonzero(valid & first.mirror)
    q[flip, :, 1:3] *= -1.0
    simple = np.append(simple_rows, 0.0)[pick]
    return q, simple, valid


def optical_map(
    field,
    grid: PixelGrid,
    law: StressOpticLaw,
    wavelengths=None,
    *,
    n_samples: int = 64,
    reflection: bool = True,
) -> OpticalMap:
    """Integrate ``field`` along vertical rays through the photoelastic layer.

    Parameters
    ----------
    field : StressField
        Provides ``stress(points)`` (Pa) and ``z_range(xy)`` (m); see optics.fields.
    grid : PixelGrid
    law : StressOpticLaw
    wavelengths : (W,) float array, optional
        Wavelengths (m). Default: the law's reference wavelength.
    n_samples : int
        Slabs per ray (midpoint rule).
    reflection : bool
        Double pass through the layer (the sensor is viewed in reflection).

    Returns
    -------
    OpticalMap

    Raises
    ------
    ValueError
        Wavelengths outside 360-830 nm or ``n_samples < 1``.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import optical_map
    >>> omap = optical_map(field, PixelGrid((2, 2), 1e-3), PSM4_ASSUMED, [500e-9, 600e-9])
    >>> omap.q.shape, omap.fringe_order(1).round(3).tolist()  # orders at 600 nm
    ((2, 2, 2, 4), [[1.49, 1.49], [1.49, 1.49]])
    """
    lam = check_wavelengths(law.wavelength_ref if wavelengths is None else wavelengths)
    t0 = time.perf_counter()
    samples = sample_rays(field, grid, n_samples)
    t1 = time.perf_counter()
    q, simple = integrate_samples(samples, law, lam, reflection=reflection)
    t2 = time.perf_counter()
    rows, cols = grid.shape
    return OpticalMap(
        grid=grid,
        wavelengths=lam,
        q=q.reshape(rows, cols, len(lam), 4),
        simple_order=np.where(samples.valid, simple, np.nan).reshape(rows, cols),
        mask=samples.valid.reshape(rows, cols),
        reflection=reflection,
        law=law,
        timings={"sample_s": t1 - t0, "integrate_s": t2 - t1},
    )
