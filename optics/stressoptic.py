"""Stress-optic law with dispersion (``docs/theory.md``, "The stress-optic law").

Relative retardation of a slab of thickness dz under a secondary principal stress
difference ds (Pa) at wavelength lam (m):

    delta = 2 pi C(lam) ds dz / lam,      C(lam_ref) = lam_ref / f_sigma,

so a uniform path of length L gives the fringe order N = L ds / f_sigma at lam_ref.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = [
    "StressOpticLaw",
    "PSM4_ASSUMED",
    "POLYCARBONATE_ASSUMED",
    "check_wavelengths",
    "wavenumber_grid",
]

VISIBLE_NM = (360.0, 830.0)


def check_wavelengths(wavelengths) -> np.ndarray:
    """Return wavelengths (m) as a float array; raise ValueError outside 360-830 nm."""
    lam = np.atleast_1d(np.asarray(wavelengths, dtype=np.float64))
    if lam.size == 0 or not np.all(np.isfinite(lam)):
        raise ValueError(f"wavelength = {wavelengths!r} is not allowed; give finite values (m)")
    lo, hi = VISIBLE_NM[0] * 1e-9, VISIBLE_NM[1] * 1e-9
    bad = (lam < lo) | (lam > hi)
    if np.any(bad):
        raise ValueError(
            f"wavelength = {float(lam[bad][0]):g} m is outside the visible range; allowed "
            f"{VISIBLE_NM[0]:.0f}-{VISIBLE_NM[1]:.0f} nm (give metres, e.g. 575e-9)"
        )
    return lam


@dataclass(frozen=True)
class StressOpticLaw:
    """Material stress-optic law: retardation per stress and path, with dispersion.

    delta = 2 pi C(lam) ds dz / lam with C(lam_ref) = lam_ref / f_sigma (module docstring).

    Parameters
    ----------
    f_sigma : float
        Material fringe value at ``wavelength_ref`` (N/m per fringe, i.e. Pa m).
    wavelength_ref : float
        Reference wavelength (m).
    dispersion : {"none", "cauchy", "power"}
        ``"none"``: C constant (f_sigma proportional to lam). ``"cauchy"``:
        C(lam) = C_ref (1 + B/lam^2) / (1 + B/lam_ref^2) with ``coefficient`` = B (m^2).
        ``"power"``: C(lam) = C_ref (lam_ref/lam)^p with ``coefficient`` = p.
    coefficient : float
        Dispersion coefficient (see above).

    Raises
    ------
    ValueError
        ``f_sigma`` not > 0, a reference wavelength outside 360-830 nm, or an unknown
        dispersion model.

    Examples
    --------
    A 3 mm path under 0.1 MPa of principal stress difference:

    >>> from fringekit.optics import StressOpticLaw
    >>> law = StressOpticLaw(f_sigma=386.0)  # N/m per fringe at 575 nm
    >>> round(float(law.fringe_order(1e5, 3e-3)), 3)
    0.777
    >>> [f"{c:.3e}" for c in law.C([575e-9, 460e-9])]  # m^2/N: no dispersion
    ['1.490e-09', '1.490e-09']
    >>> round(StressOpticLaw.from_strain_optic(K=0.004, E=4e6, nu=0.49).f_sigma, 1)
    385.9
    """

    f_sigma: float
    wavelength_ref: float = 575e-9
    dispersion: Literal["none", "cauchy", "power"] = "none"
    coefficient: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.f_sigma) and self.f_sigma > 0):
            raise ValueError(f"f_sigma = {self.f_sigma!r} is not allowed; it must be > 0 (N/m)")
        check_wavelengths(self.wavelength_ref)
        if self.dispersion not in ("none", "cauchy", "power"):
            raise ValueError(
                f"dispersion = {self.dispersion!r} is not allowed; use 'none', 'cauchy' or 'power'"
            )

    @classmethod
    def from_strain_optic(
        cls, K: float, E: float, nu: float, wavelength_ref: float = 575e-9, **kw
    ) -> StressOpticLaw:
        """Law from the strain-optic coefficient: f_sigma = lam E / (K (1 + nu)).

        Eq. 4 of "Tactile whole-field imaging sensor on photoelasticity" (the seed
        paper, ``docs/theory.md``). ``K`` dimensionless,
        ``E`` in Pa, ``wavelength_ref`` in m.
        """
        if not (K > 0 and E > 0 and -1 < nu <= 0.5):
            raise ValueError(
                f"K = {K!r}, E = {E!r}, nu = {nu!r} not allowed; need K > 0, E > 0, -1 < nu <= 0.5"
            )
        return cls(f_sigma=wavelength_ref * E / (K * (1 + nu)), wavelength_ref=wavelength_ref, **kw)

    @property
    def C_ref(self) -> float:
        """Stress-optic coefficient at the reference wavelength (m^2/N)."""
        return self.wavelength_ref / self.f_sigma

    def C(self, wavelengths) -> np.ndarray:
        """Stress-optic coefficient C(lam) (m^2/N) at wavelengths (m)."""
        lam = check_wavelengths(wavelengths)
        if self.dispersion == "cauchy":
            b = self.coefficient
            return self.C_ref * (1 + b / lam**2) / (1 + b / self.wavelength_ref**2)
        if self.dispersion == "power":
            return self.C_ref * (self.wavelength_ref / lam) ** self.coefficient
        return np.full(lam.shape, self.C_ref)

    def retardation_per_stress_length(self, wavelengths) -> np.ndarray:
        """2 pi C(lam) / lam (rad per Pa per m), the factor turning ds dz into delta."""
        lam = check_wavelengths(wavelengths)
        return 2 * np.pi * self.C(lam) / lam

    def relative_retardation(self, wavelengths) -> np.ndarray:
        """k(lam) / k(lam_ref) with k = 2 pi C / lam: retardation at lam per unit of it at
        the reference wavelength, for the same stress and path (dimensionless)."""
        return self.retardation_per_stress_length(wavelengths) / (
            2 * np.pi * self.C_ref / self.wavelength_ref
        )

    def wavenumber_grid(self, n: int, lo: float = 400e-9, hi: float = 700e-9) -> np.ndarray:
        """``n`` wavelengths (m, ascending) in [lo, hi] at which k = 2 pi C / lam is
        equally spaced; see :func:`wavenumber_grid`."""
        return wavenumber_grid(self, n, lo, hi)

    def fringe_order(self, stress_difference, path_length):
        """Fringe order N = L ds / f_sigma at the reference wavelength."""
        return np.asarray(path_length) * np.asarray(stress_difference) / self.f_sigma


def wavenumber_grid(
    law: StressOpticLaw, n: int, lo: float = 400e-9, hi: float = 700e-9
) -> np.ndarray:
    """Wavelengths (m, ascending) in [lo, hi] where the law's k(lam) = 2 pi C(lam) / lam
    is equally spaced.

    The retardation of any ray is k(lam) times a stress integral, so on this grid it
    steps by the same amount from one sample to the next: the colour oscillation of a
    high-order fringe is sampled evenly (an even lam grid samples it 3x more coarsely
    at 700 nm than at 400 nm), and :func:`optics.jones.integrate_path` can replace the
    per-wavelength sine and cosine by a complex recurrence. k(lam) must be monotone on
    [lo, hi] (it is for every positive dispersion coefficient); the grid is found by
    bisection to machine precision. Weight samples with
    :attr:`optics.camera.Spectrum.weights` (cell widths) when integrating over lam.
    """
    if int(n) < 1 or int(n) != n:
        raise ValueError(f"n = {n!r} is not allowed; give a whole number of wavelengths >= 1")
    lo_hi = check_wavelengths([lo, hi])
    if not lo_hi[0] < lo_hi[1]:
        raise ValueError(f"lo = {lo!r} m must be below hi = {hi!r} m")
    n = int(n)
    if n == 1:
        return check_wavelengths(0.5 * (lo + hi))
    if law.dispersion == "none":  # k proportional to 1/lam: closed form
        return 1.0 / np.linspace(1.0 / lo_hi[0], 1.0 / lo_hi[1], n)
    k_lo, k_hi = law.retardation_per_stress_length(lo_hi)
    if not k_lo > k_hi:
        raise ValueError(
            f"k(lam) = 2 pi C / lam of {law!r} does not fall from {lo!r} to {hi!r} m; "
            "a wavenumber grid needs a monotone law"
        )
    target = np.linspace(k_hi, k_lo, n)[::-1]  # k falls as lam rises
    a = np.full(n, lo_hi[0])
    b = np.full(n, lo_hi[1])
    for _ in range(80):  # bisection: [a, b] halves each step, ends below 1 ulp of lam
        m = 0.5 * (a + b)
        above = law.retardation_per_stress_length(m) > target
        a = np.where(above, m, a)
        b = np.where(above, b, m)
    return 0.5 * (a + b)


#: PSM-4-class urethane sheet, ASSUMED: K = 0.004 (Vishay-class strain-optic coefficient,
#: not confirmed from a datasheet), E = 4 MPa (seed paper), nu = 0.49 (assumed), at 575 nm:
#: f_sigma = 575e-9 * 4e6 / (0.004 * 1.49) = 386 N/m per fringe. Calibrate it (disc image
#: or an indentation at known load) before trusting absolute stresses.
PSM4_ASSUMED = StressOpticLaw.from_strain_optic(K=0.004, E=4e6, nu=0.49)

#: Polycarbonate, ASSUMED: f_sigma = 7.0 kN/m per fringe at 575 nm (typical handbook value
#: for PC, not measured for the sensor's plate).
POLYCARBONATE_ASSUMED = StressOpticLaw(f_sigma=7.0e3)
