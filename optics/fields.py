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
    def stress(self, points: np.ndarray) -> np.ndarray:
        """Cauchy stress (..., 3, 3) in Pa at points (..., 3) in m."""

    def z_range(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bottom z, top z (m) of the photoelastic layer under xy (P, 2), and a validity mask."""


def _sym(sxx, syy, szz, sxy, sxz, syz) -> np.ndarray:
    s = np.stack([sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz], axis=-1)
    return s.reshape(np.shape(sxx) + (3, 3))


@dataclass(frozen=True)
class UniformStress:
    """Homogeneous stress (3, 3) (Pa) in a slab z0 <= z <= z1 (m) of lateral half-size."""

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

    The layer spans z in [z_top - thickness, z_top]; ``core`` (m) masks the singular
    region r < core around the load axis.
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
