"""The image model ``fringekit invert`` fits: library synthesis through the polariscope.

For a set of indenters the library gives the path quaternions of every pixel
(:func:`fringekit.synth.synthesise`); the polariscope and light turn them into linear
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

from dataclasses import dataclass

import numpy as np

from optics import (
    PixelGrid,
    dark_field_circular,
    intensity,
    light_source,
    six_step_arrangements,
    white_light_image,
)

from .library import Library, LoadedIndenter
from .synth import synthesise

__all__ = ["METHODS", "ImageModel", "N_PARAMS", "unpack"]

METHODS = ("rgb", "mono", "phase")
#: Parameters per indenter: x, y (mm), Fz, Fx, Fy (N).
N_PARAMS = 5
#: The model's contact circles are widened by this factor (and one pixel) when pixels
#: are left out of the fit: the library's field is least accurate at the contact edge.
CONTACT_MARGIN = 1.15


def unpack(p: np.ndarray, diameters) -> list[LoadedIndenter]:
    """Indenters of a parameter vector (n * N_PARAMS,) with their diameters (m)."""
    q = np.asarray(p, float).reshape(-1, N_PARAMS)
    return [LoadedIndenter(v[0] * 1e-3, v[1] * 1e-3, d, v[3], v[4], v[2])
            for v, d in zip(q, diameters, strict=True)]  # fmt: skip


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

    @classmethod
    def build(cls, lib, grid, method, measured, usable, optics, *, light="LED",
              white_light_wavelengths=31):  # fmt: skip
        """``optics``: a :class:`fringekit.inputs.OpticsSetup` (law, camera, errors);
        ``light``: the white-light source's name."""
        law = optics.law
        if method == "mono":
            setup = {"arrangements": [dark_field_circular(**optics.errors)]}
            groups = [[0]]
        elif method == "phase":
            setup = {"arrangements": list(six_step_arrangements(**optics.errors))}
            groups = [list(range(6))]
        else:
            lam = law.wavenumber_grid(white_light_wavelengths)
            setup = {
                "arrangement": dark_field_circular(**optics.errors),
                "wavelengths": lam,
                "spectrum": light_source(light, lam),
                "camera": optics.camera,
            }
            groups = [[0], [1], [2]]
        return cls(lib, grid, method, measured, usable, law, setup, groups)

    def linear(self, indenters) -> tuple[np.ndarray, np.ndarray]:
        """Model intensities (P, C) before gain and offset, and the pixels outside every
        (widened) contact circle."""
        lam = self.setup.get("wavelengths")
        sm = synthesise(self.lib, indenters, self.grid, self.law, lam)
        q = sm.q.reshape(-1, len(sm.wavelengths), 4)
        if self.method == "rgb":
            s = self.setup
            img = white_light_image(q[:, None], s["spectrum"], s["camera"], s["arrangement"],
                                    linear=True)[:, 0]  # fmt: skip
        else:
            img = np.stack([intensity(q[:, 0], a) for a in self.setup["arrangements"]], axis=1)
        return img, self.outside_contacts(indenters)

    def outside_contacts(self, indenters) -> np.ndarray:
        xy = self.grid.xy()
        keep = np.ones(len(xy), bool)
        for ind in indenters:
            f = self.lib.fields[self.lib.nearest_diameter(ind.diameter * 1e3)]
            a = float(np.interp(max(ind.fz, 0.0), self.lib.load_N, f["contact_radius_m"][:, 0]))
            reach = max(CONTACT_MARGIN * a + self.grid.pixel_size, self.inner)
            keep &= np.hypot(xy[:, 0] - ind.x, xy[:, 1] - ind.y) > reach
        return keep

    def project(self, model: np.ndarray, use: np.ndarray):
        """Gain and offset per channel group by linear least squares on ``use`` pixels:
        (fitted (P, C), gains (C,), offsets (C,))."""
        fitted = np.zeros_like(model)
        gains = np.zeros(model.shape[1])
        offs = np.zeros(model.shape[1])
        for g in self.groups:
            m = model[use][:, g].ravel()
            d = self.measured[use][:, g].ravel()
            A = np.column_stack([m, np.ones_like(m)])
            (gain, off), *_ = np.linalg.lstsq(A, d, rcond=None)
            gains[g], offs[g] = gain, off
            fitted[:, g] = gain * model[:, g] + off
        return fitted, gains, offs

    def residual(self, p: np.ndarray, diameters) -> np.ndarray:
        """Residuals (P * C,) of the parameter vector; zero on pixels left out."""
        model, outside = self.linear(unpack(p, diameters))
        use = self.usable & (outside if self.keep is None else self.keep)
        fitted, _, _ = self.project(model, use)
        res = self.measured - fitted
        res[~use] = 0.0
        return res.ravel()
