"""Quadratic (10-node) tetrahedron and 6-node triangle: shape functions and quadrature.

Node order is VTK's (see :mod:`meshes.topology`): corners 0-3, then mid-edge nodes on
(0,1), (1,2), (2,0), (0,3), (1,3), (2,3). Reference coordinates ``(r, s, t)`` with
barycentric ``L = (1 - r - s - t, r, s, t)``; corner shape functions ``L_a (2 L_a - 1)``,
mid-edge ``4 L_a L_b`` (Zienkiewicz & Taylor, *The Finite Element Method*, vol. 1,
6th ed., section 6.8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "TET_QUADRATURE",
    "TRI_QUADRATURE",
    "tet10_shape",
    "tri6_shape",
    "ReferenceGradients",
    "reference_gradients",
]

_MID = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
_TRI_MID = np.array([[0, 1], [1, 2], [2, 0]])

# 4-point rule, exact for quadratics on the tetrahedron (Keast 1986, rule 2); weights
# sum to the reference volume 1/6.
_a, _b = 0.5854101966249685, 0.1381966011250105
TET_QUADRATURE = (
    np.array([[_b, _b, _b], [_a, _b, _b], [_b, _a, _b], [_b, _b, _a]]),
    np.full(4, 1.0 / 24.0),
)

# 7-point rule, exact for quintics on the triangle (Dunavant 1985, degree 5); weights
# sum to the reference area 1/2.
_t1, _t2 = 0.470142064105115, 0.101286507323456
_w0, _w1, _w2 = 0.225, 0.132394152788506, 0.125939180544827
TRI_QUADRATURE = (
    np.array(
        [
            [1 / 3, 1 / 3],
            [_t1, _t1],
            [1 - 2 * _t1, _t1],
            [_t1, 1 - 2 * _t1],
            [_t2, _t2],
            [1 - 2 * _t2, _t2],
            [_t2, 1 - 2 * _t2],
        ]
    ),
    np.array([_w0, _w1, _w1, _w1, _w2, _w2, _w2]) / 2.0,
)


def tet10_shape(rst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions and their reference gradients of the 10-node tetrahedron.

    Parameters
    ----------
    rst : (q, 3) float array
        Reference coordinates.

    Returns
    -------
    N : (q, 10) float array
    dN : (q, 10, 3) float array, d N_a / d(r, s, t).
    """
    rst = np.atleast_2d(np.asarray(rst, dtype=float))
    L = np.column_stack([1.0 - rst.sum(axis=1), rst])  # (q, 4)
    dL = np.array([[-1.0, -1.0, -1.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # (4, 3)
    N = np.empty((len(rst), 10))
    dN = np.empty((len(rst), 10, 3))
    N[:, :4] = L * (2 * L - 1)
    dN[:, :4] = (4 * L - 1)[:, :, None] * dL[None]
    a, b = _MID[:, 0], _MID[:, 1]
    N[:, 4:] = 4 * L[:, a] * L[:, b]
    dN[:, 4:] = 4 * (L[:, a, None] * dL[None, b] + L[:, b, None] * dL[None, a])
    return N, dN


def tri6_shape(rs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions and reference gradients of the 6-node triangle.

    Parameters
    ----------
    rs : (q, 2) float array

    Returns
    -------
    N : (q, 6) float array
    dN : (q, 6, 2) float array
    """
    rs = np.atleast_2d(np.asarray(rs, dtype=float))
    L = np.column_stack([1.0 - rs.sum(axis=1), rs])
    dL = np.array([[-1.0, -1.0], [1, 0], [0, 1]])
    N = np.empty((len(rs), 6))
    dN = np.empty((len(rs), 6, 2))
    N[:, :3] = L * (2 * L - 1)
    dN[:, :3] = (4 * L - 1)[:, :, None] * dL[None]
    a, b = _TRI_MID[:, 0], _TRI_MID[:, 1]
    N[:, 3:] = 4 * L[:, a] * L[:, b]
    dN[:, 3:] = 4 * (L[:, a, None] * dL[None, b] + L[:, b, None] * dL[None, a])
    return N, dN


@dataclass(frozen=True)
class ReferenceGradients:
    """Shape-function gradients in the reference (undeformed) configuration.

    Attributes
    ----------
    dNdX : (c, q, 10, 3) float array, d N_a / d X_J (1/m).
    dV : (c, q) float array, quadrature weight times Jacobian determinant (m^3).
    N : (q, 10) float array, shape functions at the quadrature points.
    """

    dNdX: np.ndarray
    dV: np.ndarray
    N: np.ndarray


def reference_gradients(points: np.ndarray, cells: np.ndarray) -> ReferenceGradients:
    """Gradients and volume weights of 10-node tets at the 4 quadrature points.

    Raises
    ------
    ValueError
        If an element has a non-positive Jacobian at a quadrature point.
    """
    rst, w = TET_QUADRATURE
    N, dN = tet10_shape(rst)
    X = points[cells]  # (c, 10, 3)
    Jm = np.einsum("caI,qar->cqIr", X, dN)  # dX_I / dr
    det = np.linalg.det(Jm)
    if np.any(det <= 0):
        bad = int(np.flatnonzero((det <= 0).any(axis=1))[0])
        raise ValueError(
            f"cell {bad} has a non-positive Jacobian in the reference mesh; "
            "the mesh must have positively oriented, untangled quadratic tets"
        )
    Jinv = np.linalg.inv(Jm)  # dr / dX
    dNdX = np.einsum("qar,cqrJ->cqaJ", dN, Jinv)
    return ReferenceGradients(dNdX=dNdX, dV=det * w[None, :], N=N)
