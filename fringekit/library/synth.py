"""Fast forward synthesis from a response library: no FEM.

Several indenters are combined by superposing their stresses on every ray, slab by slab
at the same fraction of the sheet's thickness, and integrating the superposed ray with
the Jones calculus (double pass, as :mod:`optics.opticalmap` does for an FEM solution).
Superposition is exact for linear elasticity on a fixed geometry; here the sheet is
nearly incompressible, large-deformation and the contacts interact through it, so it
holds while each indenter's near field (a few contact radii) is clear of the others'
contacts. ``docs/library.md`` states the measured error against full FEM solves of two
indenters at 10, 6 and 4 mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fringekit.library.store import Library, LoadedIndenter
from fringekit.optics import PixelGrid, integrate_path
from fringekit.optics.jones import qmul, qtranspose, retarder_spectrum

__all__ = [
    "SynthMap",
    "exact_rays",
    "quaternions_where",
    "ray_quaternions",
    "slab_sum",
    "superpose",
    "synthesise",
]


@dataclass(frozen=True)
class SynthMap:
    """Quaternions and maps of a synthesised image.

    Attributes
    ----------
    grid : PixelGrid
    wavelengths : (W,) m
    q : (rows, cols, W, 4) double-pass path quaternions (identity where no stress)
    simple_order : (rows, cols) rotation-free order, the double pass of the summed slab
        magnitudes (fringe, at the law's reference wavelength; as
        :attr:`optics.OpticalMap.simple_order`)
    mask : (rows, cols) bool — outside every contact circle
    """

    grid: PixelGrid
    wavelengths: np.ndarray
    q: np.ndarray
    simple_order: np.ndarray
    mask: np.ndarray


def superpose(lib: Library, indenters, xy: np.ndarray):
    """Summed Cartesian slab pairs (P, S, 2) float32 (Pa m) and the contact mask (P,)."""
    ab = np.zeros((len(xy), lib.lattice.n_slabs, 2), np.float32)
    contact = np.zeros(len(xy), bool)
    for ind in indenters:  # a handful of indenters; each is vectorised over pixels
        one, c = lib.slabs(ind, xy)
        ab += one
        contact |= c
    return ab, contact


def _quaternions(ab: np.ndarray, law, wavelengths: np.ndarray, exact: bool) -> np.ndarray:
    """Double-pass quaternions (P, W, 4) of rays with slab pairs ab (P, S, 2).

    ``exact``: the Jones integration slab by slab. Otherwise the ray is one linear
    retarder with the summed slab vector (its magnitude the retardation, half its angle
    the axis): exact where the secondary principal axes do not turn along the ray, and
    within 0.0004 fringe RMS of the Jones integration beyond twice the contact radius of
    the reference case (0.016 RMS, 0.13 at most, between one and two contact radii).
    The double pass of a linear retarder doubles its retardation (U^T = U)."""
    k = law.retardation_per_stress_length(wavelengths)
    if not exact:
        tot = 2.0 * slab_sum(ab)  # the double pass
        return retarder_spectrum(tot[:, 0], tot[:, 1], k)
    a = ab[..., 0].astype(float)
    b = ab[..., 1].astype(float)
    ds = np.hypot(a, b)  # (Pa m): the slab thickness is already in
    theta = 0.5 * np.arctan2(b, a)
    q = integrate_path(ds, theta, np.ones_like(ds), k)
    return qmul(qtranspose(q), q)


def slab_sum(ab: np.ndarray) -> np.ndarray:
    """Slab pairs ab (P, S, 2) summed along each ray: (P, 2) float64.

    Added slab by slab in float64, the order numpy's own reduction takes, but without
    its strided pass over a float64 copy of ab (3-4 times slower on 10^5 rays).

    Examples
    --------
    >>> ab = np.arange(12, dtype=np.float32).reshape(2, 3, 2)
    >>> slab_sum(ab)
    array([[ 6.,  9.],
           [24., 27.]])
    """
    tot = ab[:, 0].astype(float)
    for s in range(1, ab.shape[1]):  # a few slabs; each pass is vectorised over rays
        tot += ab[:, s]
    return tot


def exact_rays(xy: np.ndarray, indenters, exact: bool | float) -> np.ndarray:
    """(P,) bool: the rays :func:`ray_quaternions` integrates slab by slab (``exact``
    True: all; False: none; a distance (m): those within it of an indenter axis)."""
    if isinstance(exact, bool):
        return np.full(len(xy), exact)
    close = np.zeros(len(xy), bool)
    for ind in indenters:  # a handful of indenters
        close |= np.hypot(xy[:, 0] - ind.x, xy[:, 1] - ind.y) < exact
    return close


def quaternions_where(ab: np.ndarray, close: np.ndarray, law, lam) -> np.ndarray:
    """Double-pass quaternions (P, W, 4) of rays with slab pairs ``ab`` (P, S, 2): the
    Jones integration where ``close`` (P,) holds, one equivalent retarder elsewhere."""
    if close.all() or not close.any():
        return _quaternions(ab, law, lam, bool(close.all()))
    q = np.empty((len(ab), len(lam), 4))
    q[close] = _quaternions(ab[close], law, lam, True)
    q[~close] = _quaternions(ab[~close], law, lam, False)
    return q


def ray_quaternions(ab, xy, indenters, law, lam, exact: bool | float = True) -> np.ndarray:
    """Double-pass quaternions (P, W, 4) of rays at ``xy`` (P, 2) (m) with summed slab
    pairs ``ab`` (P, S, 2): all by Jones integration (``exact=True``), none (``False``:
    one equivalent retarder per ray) or those within ``exact`` (m) of an indenter axis."""
    if isinstance(exact, bool):
        return _quaternions(ab, law, lam, exact)
    return quaternions_where(ab, exact_rays(xy, indenters, exact), law, lam)


def synthesise(
    lib: Library,
    indenters: list[LoadedIndenter],
    grid: PixelGrid,
    law,
    wavelengths=None,
    *,
    exact: bool | float = True,
) -> SynthMap:
    """Quaternions of the sheet under ``indenters`` on ``grid``.

    Only rays within the lattice radius of some indenter are integrated; the rest carry
    no stress (identity). ``wavelengths`` (m) default to the law's reference one;
    ``exact`` as :func:`ray_quaternions` (``False`` and a distance serve the early and
    late stages of ``invert``).
    """
    lam = np.atleast_1d(
        np.asarray(law.wavelength_ref if wavelengths is None else wavelengths, float)
    )
    xy = grid.xy()
    P = len(xy)
    near = np.zeros(P, bool)
    for ind in indenters:
        near |= np.hypot(xy[:, 0] - ind.x, xy[:, 1] - ind.y) < lib.lattice.r_max
    idx = np.flatnonzero(near)
    q = np.zeros((P, len(lam), 4))
    q[..., 0] = 1.0
    simple = np.zeros(P)
    mask = np.ones(P, bool)
    if idx.size:
        ab, contact = superpose(lib, indenters, xy[idx])
        q[idx] = ray_quaternions(ab, xy[idx], indenters, law, lam, exact)
        k_ref = law.retardation_per_stress_length(np.array([law.wavelength_ref]))[0]
        mag = np.hypot(ab[..., 0].astype(float), ab[..., 1]).sum(axis=1)
        simple[idx] = 2.0 * mag * k_ref / (2 * np.pi)
        mask[idx] = ~contact
    rows, cols = grid.shape
    return SynthMap(
        grid=grid,
        wavelengths=lam,
        q=q.reshape(rows, cols, len(lam), 4),
        simple_order=simple.reshape(rows, cols),
        mask=mask.reshape(rows, cols),
    )
