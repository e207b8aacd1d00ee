"""Hyperelastic materials with a split isochoric / volumetric strain energy.

The strain energy per unit reference volume is

.. math::

    \\Psi(F) = \\Psi_\\mathrm{iso}(\\bar I_1, \\bar I_2) + U(J), \\qquad
    \\bar I_1 = J^{-2/3} \\operatorname{tr} C, \\quad
    \\bar I_2 = J^{-4/3} \\tfrac12 (I_1^2 - C : C), \\quad U(J) = \\tfrac{K}{2} (J - 1)^2,

with :math:`C = F^T F` (Holzapfel, *Nonlinear Solid Mechanics*, 2000, sections 6.4-6.5).
Neo-Hookean: :math:`\\Psi_\\mathrm{iso} = \\tfrac{\\mu}{2} (\\bar I_1 - 3)`; Mooney-Rivlin:
:math:`C_{10} (\\bar I_1 - 3) + C_{01} (\\bar I_2 - 3)` with :math:`\\mu = 2 (C_{10} + C_{01})`.
The solver evaluates :math:`U` at the element's mean dilatation (:mod:`fea.assembly`), so
these kernels return the isochoric part (energy, first Piola-Kirchhoff stress, tangent)
and the volumetric function separately. All moduli in Pa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "cofactor",
    "cauchy_stress",
    "Material",
    "NeoHookean",
    "MooneyRivlin",
    "SHEET_DEFAULT",
    "POLYCARBONATE_DEFAULT",
    "material_from_dict",
]


def _check_modulus(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} = {value!r} is not allowed; it must be finite and > 0 (Pa)")


def _check_nu(nu: float) -> None:
    if not (math.isfinite(nu) and -1.0 < nu < 0.5):
        raise ValueError(
            f"nu = {nu!r} is not allowed; Poisson's ratio must lie in (-1, 0.5) "
            "(0.5 itself would need an infinite bulk modulus; use 0.499 or 0.4999)"
        )


@dataclass(frozen=True)
class Material:
    """Base class of the hyperelastic solids: shear modulus ``mu`` and bulk modulus ``K``.

    Subclasses (:class:`NeoHookean`, :class:`MooneyRivlin`) give the isochoric energy; the
    volumetric part U(J) = K/2 (J - 1)^2 is shared.

    Parameters
    ----------
    mu : float
        Small-strain shear modulus (Pa), > 0.
    K : float
        Bulk modulus (Pa), > 0.

    Raises
    ------
    ValueError
        A modulus that is not finite and positive.

    Examples
    --------
    >>> from fringekit.fea import Material, NeoHookean
    >>> sheet = NeoHookean.from_E_nu(4e6, 0.49)
    >>> isinstance(sheet, Material), round(sheet.E), round(sheet.nu, 2)
    (True, 4000000, 0.49)
    """

    mu: float
    K: float

    def __post_init__(self) -> None:
        _check_modulus("mu", self.mu)
        _check_modulus("K", self.K)

    @property
    def E(self) -> float:
        """Small-strain Young's modulus (Pa)."""
        return 9 * self.K * self.mu / (3 * self.K + self.mu)

    @property
    def nu(self) -> float:
        """Small-strain Poisson's ratio."""
        return (3 * self.K - 2 * self.mu) / (2 * (3 * self.K + self.mu))

    def volumetric(
        self, J: np.ndarray, dJ: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """U(J) = K/2 (J - 1)^2 and its first two derivatives (Pa).

        ``dJ`` = J - 1 computed without cancellation (:func:`det_minus_one`); J - 1 formed
        from J near 1 loses the digits of a small dilatation, a pressure error of about
        K * 1e-16 that a 1 TPa plate makes larger than the solver's force tolerance.
        """
        d = J - 1.0 if dJ is None else dJ
        return 0.5 * self.K * d * d, self.K * d, np.full_like(J, self.K)

    def isochoric(
        self,
        F: np.ndarray,
        *,
        tangent: bool = True,
        H: np.ndarray | None = None,
        G: np.ndarray | None = None,
        J: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Isochoric energy, first Piola-Kirchhoff stress and tangent.

        Parameters
        ----------
        F : (..., 3, 3) float array
            Deformation gradient.
        H : (..., 3, 3) float array, optional
            The displacement gradient F - I as computed from the displacements; the
            stress is then formed without the cancellation of F - I1/3 F^-T near F = I.
        G, J : (..., 3, 3) and (...) float arrays, optional
            F^-T and det F when the caller has them (both or neither).
        tangent : bool
            Compute A; when False it is None (residual-only evaluations, e.g. line search
            and stress recovery, cost ~1/3).

        Returns
        -------
        W : (...) float array, energy per reference volume (Pa).
        P : (..., 3, 3) float array, dW/dF (Pa).
        A : (..., 3, 3, 3, 3) float array, d^2W/dF dF with index order (i, J, k, L) (Pa).
        """
        raise NotImplementedError

    def to_dict(self) -> dict:
        return {"model": type(self).__name__, **self.__dict__}


def cofactor(F: np.ndarray) -> np.ndarray:
    """Cofactor matrix cof F = det(F) F^-T of 3 x 3 batches, written out in the
    components (rows of cof F are cross products of the other two rows of F; ten times
    faster than ``np.linalg.inv`` on (c, q, 3, 3) batches).

    Parameters
    ----------
    F : (..., 3, 3) float array
    """
    cof = np.empty_like(F)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        for a in range(3):
            b, c = (a + 1) % 3, (a + 2) % 3
            cof[..., i, a] = F[..., j, b] * F[..., k, c] - F[..., j, c] * F[..., k, b]
    return cof


def _invariant_parts(F: np.ndarray, G=None, J=None):
    """(det F, F^-T, tr C), the first two taken from the caller when given."""
    if G is None or J is None:
        cof = cofactor(F)
        J = np.einsum("...j,...j->...", F[..., 0, :], cof[..., 0, :])
        G = cof / J[..., None, None]
    I1 = np.einsum("...ij,...ij->...", F, F)
    return J, G, I1


def det_minus_one(H: np.ndarray) -> np.ndarray:
    """det(I + H) - 1 without cancellation: tr H + (tr(H)^2 - tr(H H)) / 2 + det H,
    written out in the components (faster than ``np.linalg.det`` on 3 x 3 batches).

    Parameters
    ----------
    H : (..., 3, 3) float array, the displacement gradient F - I.
    """
    h00, h01, h02 = H[..., 0, 0], H[..., 0, 1], H[..., 0, 2]
    h10, h11, h12 = H[..., 1, 0], H[..., 1, 1], H[..., 1, 2]
    h20, h21, h22 = H[..., 2, 0], H[..., 2, 1], H[..., 2, 2]
    m0 = h11 * h22 - h12 * h21  # cofactors of the first row
    m1 = h10 * h22 - h12 * h20
    m2 = h10 * h21 - h11 * h20
    second = h00 * h11 + h11 * h22 + h00 * h22 - h01 * h10 - h12 * h21 - h02 * h20
    return (h00 + h11 + h22) + second + (h00 * m0 - h01 * m1 + h02 * m2)


def deviatoric_piola_factor(H: np.ndarray, G: np.ndarray) -> np.ndarray:
    """F - (I1 / 3) F^-T for F = I + H, formed from terms of order |H|.

    With I - F^-T = F^-T H^T and I1 - 3 = 2 tr H + H : H,

        F - I1/3 G = H + G H^T - (2 tr H + H : H) / 3 G,

    so a strain of 1e-10 keeps its digits instead of leaving mu * 1e-16 of round-off
    (seen as a residual floor with a 1 TPa substrate).

    Parameters
    ----------
    H : (..., 3, 3) float array, F - I.
    G : (..., 3, 3) float array, F^-T.
    """
    c = (2.0 * np.einsum("...ii->...", H) + np.einsum("...ij,...ij->...", H, H)) / 3.0
    return H + G @ H.swapaxes(-1, -2) - c[..., None, None] * G


@dataclass(frozen=True)
class NeoHookean(Material):
    """Compressible / nearly incompressible neo-Hookean solid.

    Psi = mu/2 (I1_bar - 3) + K/2 (J - 1)^2 (module docstring).

    Parameters
    ----------
    mu, K : float
        Shear and bulk moduli (Pa). Use :meth:`from_E_nu` for engineering constants.

    Raises
    ------
    ValueError
        A modulus that is not finite and positive.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.fea import NeoHookean
    >>> mat = NeoHookean.from_E_nu(E=4e6, nu=0.49)
    >>> round(mat.mu / 1e6, 4), round(mat.K / 1e6, 2)  # MPa
    (1.3423, 66.67)
    >>> W, P, A = mat.isochoric(np.eye(3)[None])  # undeformed: no energy, no stress
    >>> float(W[0]), float(abs(P).max()), A.shape
    (0.0, 0.0, (1, 3, 3, 3, 3))
    """

    @classmethod
    def from_E_nu(cls, E: float, nu: float) -> NeoHookean:
        """From Young's modulus ``E`` (Pa) and Poisson's ratio ``nu`` (small strain)."""
        _check_modulus("E", E)
        _check_nu(nu)
        return cls(mu=E / (2 * (1 + nu)), K=E / (3 * (1 - 2 * nu)))

    def isochoric(self, F, *, tangent: bool = True, H=None, G=None, J=None):
        J, G, I1 = _invariant_parts(F, G, J)
        a = J ** (-2.0 / 3.0)
        mu = self.mu
        W = 0.5 * mu * (a * I1 - 3.0)
        P = mu * a[..., None, None] * deviatoric_piola_factor(F - np.eye(3) if H is None else H, G)
        if not tangent:
            return W, P, None
        # dP_iJ/dF_kL = mu a [ d_ik d_JL - 2/3 (G_kL F_iJ + F_kL G_iJ)
        #                      + 2/9 I1 G_iJ G_kL + 1/3 I1 G_iL G_kJ ]
        eye = np.eye(3)
        A = np.einsum("ik,JL->iJkL", eye, eye) + np.zeros(F.shape[:-2] + (1, 1, 1, 1))
        A -= (2.0 / 3.0) * (
            np.einsum("...kL,...iJ->...iJkL", G, F) + np.einsum("...kL,...iJ->...iJkL", F, G)
        )
        I = I1[..., None, None, None, None]
        A += (2.0 / 9.0) * I * np.einsum("...iJ,...kL->...iJkL", G, G)
        A += (1.0 / 3.0) * I * np.einsum("...iL,...kJ->...iJkL", G, G)
        A *= (mu * a)[..., None, None, None, None]
        return W, P, A


@dataclass(frozen=True)
class MooneyRivlin(Material):
    """Two-parameter Mooney-Rivlin solid; ``mu = 2 (c10 + c01)``.

    Parameters
    ----------
    c10, c01 : float
        Mooney-Rivlin constants (Pa), c10 > 0, c01 >= 0.
    K : float
        Bulk modulus (Pa).

    Raises
    ------
    ValueError
        c10 or K not > 0, or c01 < 0.

    Examples
    --------
    >>> from fringekit.fea import MooneyRivlin
    >>> mat = MooneyRivlin(c10=0.5e6, c01=0.2e6, K=1e9)
    >>> mat.mu, mat.to_dict()["model"]
    (1400000.0, 'MooneyRivlin')
    """

    c10: float = 0.0
    c01: float = 0.0

    def __init__(self, c10: float, c01: float, K: float):
        _check_modulus("c10", c10)
        if not (math.isfinite(c01) and c01 >= 0):
            raise ValueError(f"c01 = {c01!r} is not allowed; it must be finite and >= 0 (Pa)")
        object.__setattr__(self, "c10", float(c10))
        object.__setattr__(self, "c01", float(c01))
        object.__setattr__(self, "mu", 2.0 * (c10 + c01))
        object.__setattr__(self, "K", float(K))
        self.__post_init__()

    def to_dict(self) -> dict:
        return {"model": "MooneyRivlin", "c10": self.c10, "c01": self.c01, "K": self.K}

    def isochoric(self, F, *, tangent: bool = True, H=None, G=None, J=None):
        J, G, I1 = _invariant_parts(F, G, J)
        C = np.einsum("...kI,...kJ->...IJ", F, F)
        FC = F @ C
        I2 = 0.5 * (I1 * I1 - np.einsum("...IJ,...IJ->...", C, C))
        a = J ** (-2.0 / 3.0)
        b = a * a
        ex = (..., None, None)
        W = self.c10 * (a * I1 - 3.0) + self.c01 * (b * I2 - 3.0)
        # with H the c10 term is free of cancellation; the c01 term still forms I1 F - F C
        # and I2 G from F (round-off about c01 * 1e-16 Pa)
        P1 = self.c10 * 2.0 * a[ex] * deviatoric_piola_factor(F - np.eye(3) if H is None else H, G)
        # d(I2)/dF = 2 (I1 F - F C); d(b)/dF = -4/3 b G
        dI2 = 2.0 * (I1[ex] * F - FC)
        P2 = self.c01 * b[ex] * (dI2 - (4.0 / 3.0) * I2[ex] * G)
        P = P1 + P2
        if not tangent:
            return W, P, None
        ex4 = (..., None, None, None, None)
        eye = np.eye(3)
        dd = np.einsum("ik,JL->iJkL", eye, eye) + np.zeros(F.shape[:-2] + (1, 1, 1, 1))
        GG = np.einsum("...iJ,...kL->...iJkL", G, G)
        GGt = np.einsum("...iL,...kJ->...iJkL", G, G)
        # c10 part: 2 c10 times the neo-Hookean bracket with mu = 1.
        A1 = dd - (2.0 / 3.0) * (
            np.einsum("...kL,...iJ->...iJkL", G, F) + np.einsum("...kL,...iJ->...iJkL", F, G)
        )
        A1 += (2.0 / 9.0) * I1[ex4] * GG + (1.0 / 3.0) * I1[ex4] * GGt
        A1 *= (2.0 * self.c10 * a)[ex4]
        # c01 part: P2 = c01 b Q with Q = dI2 - 4/3 I2 G.
        # dP2/dF_kL = c01 b [ -4/3 G_kL Q_iJ + dQ_iJ/dF_kL ]
        # dQ_iJ/dF_kL = 2 (2 F_kL F_iJ + I1 d_ik d_JL - d_ik C_LJ - F_iL F_kJ - (F F^T)_ik d_JL)
        #               - 4/3 dI2_kL G_iJ + 4/3 I2 G_iL G_kJ
        Q = dI2 - (4.0 / 3.0) * I2[ex] * G
        B = F @ F.swapaxes(-1, -2)
        dQ = 2.0 * (
            2.0 * np.einsum("...kL,...iJ->...iJkL", F, F)
            + I1[ex4] * dd
            - np.einsum("ik,...LJ->...iJkL", eye, C)
            - np.einsum("...iL,...kJ->...iJkL", F, F)
            - np.einsum("...ik,JL->...iJkL", B, eye)
        )
        dQ -= (4.0 / 3.0) * np.einsum("...kL,...iJ->...iJkL", dI2, G)
        dQ += (4.0 / 3.0) * I2[ex4] * GGt
        A2 = (self.c01 * b)[ex4] * (dQ - (4.0 / 3.0) * np.einsum("...kL,...iJ->...iJkL", G, Q))
        return W, P, A1 + A2


#: Photoelastic sheet default: E = 4 MPa (seed paper, "Sensing element": "low modulus of
#: elasticity of 4 MPa"); nu = 0.49 ASSUMED (polyurethane photoelastic rubbers are nearly
#: incompressible; no datasheet value in the seed paper).
SHEET_DEFAULT = NeoHookean.from_E_nu(4e6, 0.49)

#: Polycarbonate default: E = 2.3 GPa, nu = 0.37 (typical datasheet values for
#: bisphenol-A polycarbonate, e.g. Lexan/Makrolon sheet; ASSUMED, not measured).
POLYCARBONATE_DEFAULT = NeoHookean.from_E_nu(2.3e9, 0.37)

_MODELS = {"neo-hookean": NeoHookean, "mooney-rivlin": MooneyRivlin}


def material_from_dict(d: dict) -> Material:
    """Build a material from ``{"model": ..., ...}`` in SI units (a config table).

    Parameters
    ----------
    d : dict
        ``model`` is ``"neo-hookean"`` (the default; with ``E`` and ``nu``, or ``mu`` and
        ``K``) or ``"mooney-rivlin"`` (with ``c10``, ``c01``, ``K``); moduli in Pa.

    Returns
    -------
    Material

    Raises
    ------
    ValueError
        An unknown model, or parameters that do not match it.

    Examples
    --------
    >>> from fringekit.fea import SHEET_DEFAULT, material_from_dict
    >>> material_from_dict({"model": "neo-hookean", "E": 4e6, "nu": 0.49}) == SHEET_DEFAULT
    True
    >>> material_from_dict({"model": "mooney-rivlin", "c10": 0.5e6, "c01": 0.2e6, "K": 1e9}).mu
    1400000.0
    """
    d = dict(d)
    model = str(d.pop("model", "neo-hookean")).lower()
    if model not in _MODELS:
        raise ValueError(f"material model = {model!r} is not known; use one of {sorted(_MODELS)}")
    if model == "neo-hookean":
        if set(d) == {"E", "nu"}:
            return NeoHookean.from_E_nu(float(d["E"]), float(d["nu"]))
        if set(d) == {"mu", "K"}:
            return NeoHookean(mu=float(d["mu"]), K=float(d["K"]))
        raise ValueError(
            f"neo-hookean material parameters {sorted(d)} are not allowed; "
            "give E and nu, or mu and K"
        )
    if set(d) != {"c10", "c01", "K"}:
        raise ValueError(
            f"mooney-rivlin material parameters {sorted(d)} are not allowed; give c10, c01 and K"
        )
    return MooneyRivlin(float(d["c10"]), float(d["c01"]), float(d["K"]))


def cauchy_stress(material: Material, F: np.ndarray, jbar: np.ndarray) -> np.ndarray:
    """Cauchy stress of the mean-dilatation element: sigma = J^-1 P_iso F^T + U'(Jbar) I.

    The isochoric first Piola-Kirchhoff stress pushed forward with the point's own
    J = det F, plus the element's constant pressure U'(Jbar) (Simo, Taylor & Pister,
    Comput. Methods Appl. Mech. Eng. 51, 1985: the three-field Hu-Washizu element with
    piecewise-constant pressure and dilatation).

    Parameters
    ----------
    material : Material
    F : (c, q, 3, 3) deformation gradients at the quadrature points
    jbar : (c,) mean dilatation of each cell

    Returns
    -------
    sigma : (c, q, 3, 3) Cauchy stress (Pa)
    """
    J = np.linalg.det(F)
    _, P, _ = material.isochoric(F, tangent=False)
    _, dU, _ = material.volumetric(jbar)
    sigma = np.einsum("cqiJ,cqkJ->cqik", P, F) / J[..., None, None]
    return sigma + dU[:, None, None, None] * np.eye(3)
