"""The image model ``fringekit invert`` fits: library synthesis through the polariscope.

For a set of indenters the library gives the path quaternions of every pixel
(:func:`fringekit.library.synth.synthesise`); the polariscope and light turn them into linear
intensities: the dark-field circular image (``mono``), the six phase-stepped images
(``phase``) or the white-light colour image (``rgb``, linear RGB of the camera). The
unknown exposure, gain and offset enter linearly: measured = gain * model + offset per
channel group (one group for mono and for the six steps, which share an exposure; one per
colour channel), and are solved exactly at every evaluation (variable projection: G. H.
Golub and V. Pereyra, "The differentiation of pseudo-inverses and nonlinear least
squares problems whose variables separate", SIAM J. Numer. Anal. 10, 1973), so the
nonlinear fit sees only the indenters' parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from fringekit._threads import task_pool, usable_cores
from fringekit.library.store import Library, LoadedIndenter
from fringekit.library.synth import exact_rays, quaternions_where, superpose
from fringekit.optics import (
    PixelGrid,
    dark_field_circular,
    intensity,
    light_source,
    six_step_arrangements,
    white_light_matrix,
)

__all__ = ["METHODS", "ImageModel", "N_PARAMS", "line_fit", "range_penalty", "unpack"]

METHODS = ("rgb", "mono", "phase")
#: Parameters per indenter: x, y (mm), Fz, Fx, Fy (N).
N_PARAMS = 5
#: The model's contact circles are widened by this factor (and one pixel) when pixels
#: are left out of the fit: the library's field is least accurate at the contact edge.
CONTACT_MARGIN = 1.15


#: Residual per newton of tangential load beyond the library's ratio, in units of the
#: robust loss's scale: the library's field is held at its largest ratio beyond it, so
#: without this the fit could drift there on a flat cost (it did: ratios of 0.9-2.6 with
#: the library's 0.8) instead of being held at the edge, where it is refused.
RANGE_WEIGHT = 1e3


def range_penalty(p: np.ndarray, max_ratio: float, scale: float):
    """Residuals (n,) and their Jacobian (n, n * N_PARAMS) of the tangential load beyond
    ``max_ratio`` times the normal load of each indenter: ``RANGE_WEIGHT * scale *
    max(0, |(Fx, Fy)| - max_ratio Fz)``."""
    q = np.asarray(p, float).reshape(-1, N_PARAMS)
    n = len(q)
    ft = np.hypot(q[:, 3], q[:, 4])
    excess = ft - max_ratio * q[:, 2]
    on = excess > 0
    w = RANGE_WEIGHT * scale
    J = np.zeros((n, n, N_PARAMS))
    i = np.flatnonzero(on)
    J[i, i, 2] = -w * max_ratio
    J[i, i, 3] = w * q[i, 3] / ft[i]
    J[i, i, 4] = w * q[i, 4] / ft[i]
    return w * np.where(on, excess, 0.0), J.reshape(n, n * N_PARAMS)


def line_fit(m: np.ndarray, d: np.ndarray, positive: bool = False):
    """Straight-line fits d ~ gain * m + offset in closed form (the normal equations of
    [m, 1]): one fit of ``m`` shaped like ``d``, or one per leading index of ``m``
    (..., *d.shape), each over all of ``d``.

    A model without contrast (all one value) has gain 0, the offset the mean of ``d``;
    ``positive``: a negative best gain counts as 0 too. Returns gain, offset and the
    residual sum of squares, each a float or shaped like the leading axes.
    """
    axes = tuple(range(m.ndim - d.ndim, m.ndim)) if m.ndim > d.ndim else None
    lead = m.shape[: m.ndim - d.ndim] + (1,) * d.ndim
    n = max(d.size, 1)
    mm = np.sum(m, axis=axes) / n
    dm = d.sum() / n
    mc = m - np.reshape(mm, lead)
    dc = d - dm
    var = np.sum(mc**2, axis=axes)
    cov = np.sum(mc * dc, axis=axes)
    ok = var > 1e-30 * n
    if positive:
        ok &= cov > 0
    gain = np.where(ok, cov / np.where(ok, var, 1.0), 0.0)
    return gain, dm - gain * mm, float(np.sum(dc * dc)) - gain * cov


def unpack(p: np.ndarray, diameters) -> list[LoadedIndenter]:
    """Indenters of a parameter vector (n * N_PARAMS,) with their diameters (m)."""
    q = np.asarray(p, float).reshape(-1, N_PARAMS)
    return [
        LoadedIndenter(v[0] * 1e-3, v[1] * 1e-3, d, v[3], v[4], v[2])
        for v, d in zip(q, diameters, strict=True)
    ]


@dataclass(frozen=True)
class ImageModel:
    """A measured image and everything needed to synthesise it.

    Attributes
    ----------
    lib : Library
    grid : PixelGrid — the pixels fitted (possibly every k-th pixel of the image)
    method : one of METHODS
    measured : (P, C) linear intensities
    usable : (P,) bool — pixels with data (not the no-data fill, not saturated)
    law : optics.StressOpticLaw
    setup : dict — arrangements, wavelengths, spectrum, camera for the method
    groups : list of channel index lists sharing one gain and offset
    inner : float — pixels within this distance (m) of an indenter axis are left out
        (the far-field stage of the fit)
    keep : (P,) bool or None — when set, the pixels fitted, held fixed (a mask that moved
        with the parameters would let the fit lower its cost by leaving pixels out)
    exact : bool or float — Jones integration of every ray, of the rays within this
        distance (m) of an indenter axis, or (False) of none: one equivalent retarder per
        ray (:func:`fringekit.library.synth.synthesise`)
    nodata : (P,) bool or None — pixels at the image's no-data fill level (a contact zone
        ``predict`` marked); None: every unusable pixel counts (saturated ones included)
    points : (P, 2) float array or None — the pixels' positions (m) when they are a
        subset of ``grid`` (:meth:`restrict`); None: every pixel of ``grid``
    correction : (P, C) float array or None — added to the library's intensities before
        gain and offset: a full-FEM image less the library's at one answer (``invert
        --refine fem``, :mod:`fringekit.inversion.refine`); None: the library alone
    residual_ab : (P, 2) float array or None — a residual birefringence of the sheet as the
        summed slab pair it would have (Pa m; ((sigma_xx - sigma_yy) dz, 2 sigma_xy dz)
        summed through the thickness), taken as a stress frozen evenly through the sheet:
        added to every ray's slabs in equal parts before the Jones integration, so that it
        composes with the loads' retardation as a retarder in the sheet does
        (:meth:`background`; six rest steps: a phase ``--reference``, or
        ``--residual-steps``); None: no residual
    censored : (P, C) bool array or None — colour channels the camera stored at its
        black (:func:`~fringekit.inversion.read.clipped_black`): there the light is at
        most the measured level, and the model, which goes on below the camera's gamut, is
        compared as the camera clips it (:meth:`misfit`); None: every channel measured
    """

    lib: Library
    grid: PixelGrid
    method: str
    measured: np.ndarray
    usable: np.ndarray
    law: object
    setup: dict
    groups: list
    inner: float = 0.0
    keep: np.ndarray | None = None
    exact: bool | float = True
    nodata: np.ndarray | None = None
    points: np.ndarray | None = None
    correction: np.ndarray | None = None
    residual_ab: np.ndarray | None = None
    censored: np.ndarray | None = None

    @classmethod
    def build(
        cls,
        lib,
        grid,
        method,
        measured,
        usable,
        optics,
        *,
        light="LED",
        white_light_wavelengths=31,
        nodata=None,
    ):
        """``optics``: a :class:`fringekit.config.inputs.OpticsSetup` (law, camera, errors);
        ``light``: the white-light source's name; ``nodata`` as the attribute."""
        law = optics.law
        if method == "mono":
            setup = {"arrangements": [dark_field_circular(**optics.errors)]}
            groups = [[0]]
        elif method == "phase":
            setup = {"arrangements": list(six_step_arrangements(**optics.errors))}
            groups = [list(range(6))]
        else:
            lam = law.wavenumber_grid(white_light_wavelengths)
            # per-wavelength intensity -> linear RGB is one (W, 3) matrix, made once
            setup = {
                "arrangements": [dark_field_circular(**optics.errors)],
                "wavelengths": lam,
                "to_rgb": white_light_matrix(light_source(light, lam), optics.camera),
            }
            groups = [[0], [1], [2]]
        return cls(lib, grid, method, measured, usable, law, setup, groups, nodata=nodata)

    @cached_property
    def xy(self) -> np.ndarray:
        """(P, 2) pixel positions (m), computed once per model (``grid.xy()``)."""
        return self.grid.xy() if self.points is None else self.points

    def restrict(self, pixels: np.ndarray) -> ImageModel:
        """The model on a subset of its pixels (a bool mask or indices into P)."""

        def pick(a):
            return None if a is None else a[pixels]

        return replace(
            self,
            measured=self.measured[pixels],
            usable=self.usable[pixels],
            keep=pick(self.keep),
            nodata=pick(self.nodata),
            points=self.xy[pixels],
            correction=pick(self.correction),
            residual_ab=pick(self.residual_ab),
            censored=pick(self.censored),
        )

    @cached_property
    def background(self) -> np.ndarray | None:
        """The residual's slab pairs (P, S, 2) float32, its sum in S equal parts (None
        without a residual): what every ray holds before an indenter's field is added;
        made once per model (every evaluation of the fit adds it)."""
        if self.residual_ab is None:
            return None
        S = self.lib.lattice.n_slabs
        part = (np.asarray(self.residual_ab, float) / S).astype(np.float32)
        return np.repeat(part[:, None, :], S, axis=1)

    def with_background(self, ab: np.ndarray) -> np.ndarray:
        """Summed slab pairs (P, S, 2) with the residual's added (as they are without)."""
        bg = self.background
        return ab if bg is None else ab + bg

    def linear(self, indenters) -> tuple[np.ndarray, np.ndarray]:
        """Model intensities (P, C) before gain and offset, and the pixels outside every
        (widened) contact circle."""
        ab, _ = superpose(self.lib, indenters, self.xy)
        lin = self.intensities(self.with_background(ab), indenters)
        if self.correction is not None:
            lin = lin + self.correction
        return lin, self.outside_contacts(indenters)

    def fitted(self, indenters):
        """The model image of ``indenters`` with its best gain and offset on the usable
        pixels outside the contact circles: (fitted (P, C), gains (C,), offsets (C,),
        outside (P,) the pixels outside every widened contact circle)."""
        model, outside = self.linear(indenters)
        fitted, gains, offs = self.project(model, self.usable & outside)
        return fitted, gains, offs, outside

    def intensities(self, ab: np.ndarray, indenters, close=None) -> np.ndarray:
        """Model intensities (N, C) of summed slab pairs ab (N, S, 2); ``close`` (N,) bool:
        the rays integrated slab by slab (default, for the model's own P pixels: as
        ``exact`` and ``indenters`` say)."""
        if close is None:
            close = exact_rays(self.xy, indenters, self.exact)
        return self.polariscope(quaternions_where(ab, close, self.law, self.wavelengths))

    @property
    def wavelengths(self) -> np.ndarray:
        """(W,) the wavelengths (m) the model integrates: the white light's, or the
        reference wavelength."""
        lam = self.setup.get("wavelengths")
        return np.array([self.law.wavelength_ref]) if lam is None else lam

    def polariscope(self, q: np.ndarray) -> np.ndarray:
        """Model intensities (N, C) of path quaternions q (N, W, 4) at :attr:`wavelengths`
        through the method's polariscope (and, for rgb, light and camera)."""
        if self.method == "rgb":
            return intensity(q, self.setup["arrangements"][0]) @ self.setup["to_rgb"]
        return np.stack([intensity(q[:, 0], a) for a in self.setup["arrangements"]], axis=1)

    def jacobian(
        self, p: np.ndarray, diameters, step: float = 1e-3, which=None, own=None
    ) -> np.ndarray:
        """Forward-difference Jacobian (P * C, n) of :meth:`residual` (``keep`` must be
        set), ``step`` times max(1, |p|) as scipy's 2-point rule; ``which``: the indices of
        the indenters whose columns are made (default all), the array then (P * C,
        5 len(which)), their columns in that order; ``own``: every indenter's slab pairs
        at ``p`` on the model's pixels (``lib.slabs``), when the caller has them already.

        A column moves one indenter: only its field is sampled again, the others' sum is
        reused. An indenter's five columns and their base are synthesised as one batch
        of rays, integrated slab by slab only within ``exact`` of that indenter's axis
        (one equivalent retarder elsewhere): what moves it changes most near it, and
        the Jones integration of every other indenter's near rays would cost the
        Jacobian n times more for a derivative the fit only steers by.
        """
        inds = unpack(p, diameters)
        xy = self.xy
        P = len(xy)
        if own is None:
            own = [self.lib.slabs(ind, xy)[0] for ind in inds]
        total = np.sum(own, axis=0) if own else np.zeros((P, 1, 2), np.float32)
        total = self.with_background(total)
        use = self.usable & self.keep
        which = range(len(inds)) if which is None else [int(i) for i in which]
        J = np.empty((int(use.size * self.measured.shape[1]), N_PARAMS * len(which)))

        def columns(col_i) -> None:  # one indenter's five columns, one batch of rays
            col, i = col_i
            sl = slice(i * N_PARAMS, (i + 1) * N_PARAMS)
            h = step * np.maximum(1.0, np.abs(p[sl]))
            batch = [total]
            for j, hj in enumerate(h):
                pj = p.copy()
                pj[sl.start + j] += hj
                batch.append(total - own[i] + self.lib.slabs(unpack(pj, diameters)[i], xy)[0])
            close = exact_rays(xy, inds[i : i + 1], self.exact)
            lin = self.intensities(np.concatenate(batch), inds, np.tile(close, len(batch)))
            res = [self._residual_from(m, use) for m in lin.reshape(len(batch), P, -1)]
            J[:, col * N_PARAMS : (col + 1) * N_PARAMS] = (
                np.stack(res[1:], axis=1) - res[0][:, None]
            ) / h

        jobs = list(enumerate(which))
        if len(jobs) > 1 and usable_cores() > 1:  # indenters on the cores; each bitwise alone
            list(task_pool().map(columns, jobs))
        else:
            for job in jobs:
                columns(job)
        return J

    def _residual_of(self, ab: np.ndarray, indenters, use: np.ndarray) -> np.ndarray:
        """Residuals (P * C,) of summed slab pairs, zero outside ``use``."""
        return self._residual_from(self.intensities(ab, indenters), use)

    def _residual_from(self, model: np.ndarray, use: np.ndarray) -> np.ndarray:
        """Residuals (P * C,) of model intensities (P, C) (the correction added, when set)
        with their best gain and offset on ``use``, zero outside it."""
        if self.correction is not None:
            model = model + self.correction
        fitted, _, _ = self.project(model, use)
        res = self.misfit(fitted)
        res[~use] = 0.0
        return res.ravel()

    def misfit(self, fitted: np.ndarray) -> np.ndarray:
        """Measured less ``fitted`` (..., P, C), the model as the camera records it: on a
        :attr:`censored` channel the camera stored its black, so a model at or below
        the measured level there fits it exactly (a censored observation: J. Tobin,
        "Estimation of relationships for limited dependent variables", Econometrica 26,
        1958), and one above it misfits by the difference.

        Examples
        --------
        A channel stored at black (measured 0) misfits a model above it only:

        >>> import numpy as np
        >>> m = ImageModel(None, None, "rgb", np.zeros((2, 1)), np.ones(2, bool), None,
        ...                {}, [[0]], censored=np.array([[True], [False]]))
        >>> m.misfit(np.array([[-0.1], [-0.1]])).ravel().tolist()
        [0.0, 0.1]
        >>> m.misfit(np.array([[0.2], [0.2]])).ravel().tolist()
        [-0.2, -0.2]
        """
        res = self.measured - fitted
        if self.censored is None:
            return res
        return np.where(self.censored, np.minimum(res, 0.0), res)

    def outside_contacts(self, indenters) -> np.ndarray:
        xy = self.xy
        keep = np.ones(len(xy), bool)
        for ind in indenters:
            f = self.lib.fields[self.lib.nearest_diameter(ind.diameter * 1e3)]
            a = float(np.interp(max(ind.fz, 0.0), self.lib.load_N, f["contact_radius_m"][:, 0]))
            reach = max(CONTACT_MARGIN * a + self.grid.pixel_size, self.inner)
            keep &= np.hypot(xy[:, 0] - ind.x, xy[:, 1] - ind.y) > reach
        return keep

    def project(self, model: np.ndarray, use: np.ndarray):
        """Gain and offset per channel group by linear least squares on ``use`` pixels:
        (fitted (P, C), gains (C,), offsets (C,)).

        The straight-line fit in closed form (:func:`line_fit`); a model without contrast
        on ``use`` (all one value) has no gain: the offset is the measured mean, the
        gain 0. Pixels with a :attr:`censored` channel are left out of it: their light is
        bounded, not measured.
        """
        fitted = np.empty_like(model)
        gains = np.zeros(model.shape[1])
        offs = np.zeros(model.shape[1])
        if self.censored is not None:  # a channel at black bounds the light, no more
            use = use & ~self.censored.any(axis=1)
        mu, du = model[use], self.measured[use]
        for g in self.groups:  # one, or three colour channels
            gain, off, _ = line_fit(mu[:, g], du[:, g])
            gains[g], offs[g] = gain, off
            fitted[:, g] = gain * model[:, g] + off
        return fitted, gains, offs

    def residual(self, p: np.ndarray, diameters) -> np.ndarray:
        """Residuals (P * C,) of the parameter vector; zero on pixels left out (outside
        ``usable``, and inside the contact circles or outside ``keep`` when it is set)."""
        inds = unpack(p, diameters)
        ab, _ = superpose(self.lib, inds, self.xy)
        keep = self.outside_contacts(inds) if self.keep is None else self.keep
        return self._residual_of(self.with_background(ab), inds, self.usable & keep)
