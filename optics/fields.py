"""Stress fields that optics can integrate along vertical rays.

A field provides Cauchy stress (Pa) at points (..., 3) (m) as (..., 3, 3), and the
z-extent of the photoelastic layer under each (x, y): ``z_range(xy) -> (z0, z1)``.
The FEM ``Solution`` is one provider (fea stage); the analytic fields below validate
the optics without it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .jones import secondary_principal

__all__ = ["StressField", "UniformStress", "TwistedStress", "DiametralDisc", "Boussinesq"]


class StressField(Protocol):
    """What the optics integrates: a stress field and the photoelastic layer's extent.

    Any object with these two methods is a field (a protocol, not a base class):
    :class:`UniformStress`, :class:`TwistedStress`, :class:`DiametralDisc`,
    :class:`Boussinesq` and :class:`FEMStressField`.

    Methods
    -------
    stress(points)
        Cauchy stress (..., 3, 3) in Pa at points (..., 3) in m.
    z_range(xy)
        Bottom z, top z (m) of the photoelastic layer under xy (P, 2), and a validity
        mask (P,).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import StressField, UniformStress
    >>> def layer_thickness(field: StressField, xy):
    ...     z0, z1, valid = field.z_range(np.asarray(xy, float))
    ...     return np.where(valid, z1 - z0, 0.0)
    >>> layer_thickness(UniformStress(np.zeros((3, 3)), z1=2e-3), [[0.0, 0.0]]).tolist()  # m
    [0.002]
    """

    def stress(self, points: np.ndarray) -> np.ndarray:
        """Cauchy stress (..., 3, 3) in Pa at points (..., 3) in m."""

    def z_range(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bottom z, top z (m) of the photoelastic layer under xy (P, 2), and a validity mask."""


def _sym(sxx, syy, szz, sxy, sxz, syz) -> np.ndarray:
    s = np.stack([sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz], axis=-1)
    return s.reshape(np.shape(sxx) + (3, 3))


@dataclass(frozen=True)
class UniformStress:
    """Homogeneous stress in a slab z0 <= z <= z1 (a closed-form test field).

    Parameters
    ----------
    sigma : (3, 3) float array
        Cauchy stress (Pa).
    z0, z1 : float
        Bottom and top of the layer (m).
    half_size : float
        Lateral half-size of the slab (m); rays outside |x|, |y| <= half_size are not
        valid.

    Examples
    --------
    Transmission through 3 mm at 0.1 MPa: N = t ds / f_sigma.

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress, optical_map
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)
    >>> omap = optical_map(field, PixelGrid((2, 2), 1e-3), PSM4_ASSUMED, reflection=False)
    >>> round(float(omap.fringe_order()[0, 0]), 4), round(3e-3 * 1e5 / PSM4_ASSUMED.f_sigma, 4)
    (0.7774, 0.7774)
    """

    sigma: np.ndarray
    z0: float = 0.0
    z1: float = 3e-3
    half_size: float = np.inf

    def stress(self, points):
        pts = np.asarray(points)
        return np.broadcast_to(np.asarray(self.sigma, float), pts.shape[:-1] + (3, 3)).copy()

    def z_range(self, xy):
        n = len(xy)
        inside = np.all(np.abs(xy) <= self.half_size, axis=1)
        return np.full(n, self.z0), np.full(n, self.z1), inside


@dataclass(frozen=True)
class TwistedStress:
    """Uniform stress difference whose principal axis turns linearly with z.

    theta(z) = theta0 + rate (z - z0); sigma_xx - sigma_yy = ds cos 2 theta,
    2 sigma_xy = ds sin 2 theta (the closed-form twisted retarder test case).

    Parameters
    ----------
    ds : float
        Secondary principal stress difference (Pa).
    theta0 : float
        Principal angle at z0 (rad).
    rate : float
        Turn of the angle per unit height (rad/m).
    z0, z1 : float
        Bottom and top of the layer (m).

    Examples
    --------
    Axes turning by 90 degrees through the sheet: the light sees a retarder and a
    rotator (Aben's characteristic parameters), not the simple order:

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, TwistedStress, optical_map
    >>> field = TwistedStress(ds=1e5, theta0=0.0, rate=np.pi / 2 / 3e-3, z1=3e-3)
    >>> omap = optical_map(field, PixelGrid((1, 1), 1e-3), PSM4_ASSUMED, reflection=False)
    >>> round(float(omap.simple_order[0, 0]), 3), round(float(omap.rotation[0, 0, 0]), 2)
    (0.777, 1.44)
    """

    ds: float
    theta0: float
    rate: float
    z0: float = 0.0
    z1: float = 3e-3

    def stress(self, points):
        z = np.asarray(points)[..., 2]
        th = self.theta0 + self.rate * (z - self.z0)
        half = 0.5 * self.ds
        zero = np.zeros_like(z)
        return _sym(
            half * np.cos(2 * th), -half * np.cos(2 * th), zero, half * np.sin(2 * th), zero, zero
        )

    def z_range(self, xy):
        n = len(xy)
        return np.full(n, self.z0), np.full(n, self.z1), np.ones(n, bool)


@dataclass(frozen=True)
class DiametralDisc:
    """Disc of diameter D (m), thickness t (m), diametral load P (N) along y.

    Plane-stress closed form (Frocht, Photoelasticity vol. 2, 1948; the field used in
    every digital-photoelasticity benchmark). Centre: sigma_x = 2P/(pi t D),
    sigma_y = -6P/(pi t D). The disc occupies z in [0, t]; rays along z give
    N = t (sigma1 - sigma2) / f_sigma in transmission.

    Parameters
    ----------
    P : float
        Diametral load (N, compressive).
    D : float
        Diameter (m).
    t : float
        Thickness (m).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, DiametralDisc, PixelGrid, optical_map
    >>> disc = DiametralDisc(P=10.0, D=20e-3, t=5e-3)
    >>> ds = disc.stress_difference(np.zeros((1, 2)))[0]  # at the centre: 8P / (pi t D), Pa
    >>> round(float(ds)), round(8 * 10.0 / (np.pi * 5e-3 * 20e-3))
    (254648, 254648)
    >>> omap = optical_map(disc, PixelGrid((21, 21), 1e-3), PSM4_ASSUMED, reflection=False)
    >>> round(float(omap.fringe_order()[10, 10]), 3), int(omap.mask.sum())  # pixels on the disc
    (3.299, 305)
    """

    P: float
    D: float
    t: float

    def stress(self, points):
        p = np.asarray(points, float)
        x, y = p[..., 0], p[..., 1]
        R = 0.5 * self.D
        k = -2 * self.P / (np.pi * self.t)
        r1 = x**2 + (R - y) ** 2
        r2 = x**2 + (R + y) ** 2
        with np.errstate(invalid="ignore", divide="ignore"):  # NaN only at the load points
            return self._components(x, y, R, k, r1, r2)

    def _components(self, x, y, R, k, r1, r2):
        sxx = k * ((R - y) * x**2 / r1**2 + (R + y) * x**2 / r2**2 - 1 / self.D)
        syy = k * ((R - y) ** 3 / r1**2 + (R + y) ** 3 / r2**2 - 1 / self.D)
        sxy = -k * ((R - y) ** 2 * x / r1**2 - (R + y) ** 2 * x / r2**2)
        zero = np.zeros_like(x)
        return _sym(sxx, syy, zero, sxy, zero, zero)

    def stress_difference(self, xy):
        """Closed-form secondary principal stress difference (Pa) at xy (..., 2)."""
        s = self.stress(np.concatenate([xy, np.zeros(xy.shape[:-1] + (1,))], axis=-1))
        return secondary_principal(s)[0]

    def z_range(self, xy):
        n = len(xy)
        inside = np.hypot(xy[:, 0], xy[:, 1]) < 0.5 * self.D
        return np.zeros(n), np.full(n, self.t), inside


@dataclass(frozen=True)
class Boussinesq:
    """Point force F (N, compressive) on the surface z = z_top of an elastic half-space.

    Cylindrical components (Johnson, Contact Mechanics, 1985, eq. 3.21 with depth
    zeta = z_top - z >= 0, rho^2 = r^2 + zeta^2; compressive stresses negative):

    - sigma_r = F/(2 pi) [(1 - 2 nu)(1/r^2 - zeta/(rho r^2)) - 3 zeta r^2 / rho^5]
    - sigma_t = -F/(2 pi) (1 - 2 nu) [1/r^2 - zeta/(rho r^2) - zeta/rho^3]
    - sigma_z = -3 F zeta^3 / (2 pi rho^5),  tau_rz = -3 F r zeta^2 / (2 pi rho^5)

    Parameters
    ----------
    F : float
        Normal force (N, pressing).
    nu : float
        Poisson's ratio.
    z_top : float
        Height of the loaded surface (m).
    thickness : float
        The layer spans z in [z_top - thickness, z_top] (m).
    core : float
        Rays within this radius of the load axis (m) are not valid (the singularity).

    Examples
    --------
    On the axis, 1 mm below a 1 N load: sigma_z = -3 F / (2 pi zeta^2):

    >>> import numpy as np
    >>> from fringekit.optics import Boussinesq
    >>> field = Boussinesq(F=1.0, z_top=3e-3)
    >>> s = field.stress(np.array([0.0, 0.0, 2e-3]))
    >>> round(float(s[2, 2])), round(-3 / (2 * np.pi * 1e-3**2))  # Pa
    (-477465, -477465)
    >>> field.z_range(np.array([[0.0, 0.0], [2e-3, 0.0]]))[2].tolist()  # the core is masked
    [False, True]
    """

    F: float
    nu: float = 0.49
    z_top: float = 3e-3
    thickness: float = 3e-3
    core: float = 1e-3

    def stress(self, points):
        p = np.asarray(points, float)
        x, y = p[..., 0], p[..., 1]
        zeta = np.maximum(self.z_top - p[..., 2], 1e-12)
        r2 = np.maximum(x**2 + y**2, 1e-24)
        r = np.sqrt(r2)
        rho = np.sqrt(r2 + zeta**2)
        c = self.F / (2 * np.pi)
        # 1/r^2 - zeta/(rho r^2) = 1 / (rho (rho + zeta)), stable on the axis
        g = 1.0 / (rho * (rho + zeta))
        sr = c * ((1 - 2 * self.nu) * g - 3 * zeta * r2 / rho**5)
        st = -c * (1 - 2 * self.nu) * (g - zeta / rho**3)
        sz = -3 * c * zeta**3 / rho**5
        trz = -3 * c * r * zeta**2 / rho**5
        cs, sn = x / r, y / r
        sxx = sr * cs**2 + st * sn**2
        syy = sr * sn**2 + st * cs**2
        sxy = (sr - st) * cs * sn
        return _sym(sxx, syy, sz, sxy, trz * cs, trz * sn)

    def z_range(self, xy):
        n = len(xy)
        valid = np.hypot(xy[:, 0], xy[:, 1]) >= self.core
        return np.full(n, self.z_top - self.thickness), np.full(n, self.z_top), valid
