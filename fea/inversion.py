"""Inverted states: a converged load state must have det F > 0 everywhere in every element.

The line search (:func:`fea.newton.line_search`) never accepts an iterate with
det F <= 0 at a quadrature point, but a quadratic tet can fold between its four
quadrature points: at a corner or mid-edge node det F may be negative while the
quadrature points stay positive. A state folded so is no physical state, and what comes
after the solve fails on it far from its cause (a library build with tangential ratio 1.5
crashed in the optics with "Triangulation is invalid" on its contact surface after 122 s,
issue 36). Every converged state is therefore checked at the quadrature points and at the
ten nodes of every element (:func:`inverted_elements`), and an inverted one is a
:class:`~fea.solver.SolverError` instead of a state.
"""

from __future__ import annotations

import numpy as np

from .element import TET_QUADRATURE, tet10_shape

__all__ = ["TET10_NODES", "det_f", "inverted_elements"]

#: Reference coordinates of the 10 nodes of the quadratic tet (VTK order, fea.element).
TET10_NODES = np.array(
    [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.5, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5],
        [0.5, 0.0, 0.5],
        [0.0, 0.5, 0.5],
    ]
)
#: Where det F is checked: the 4 quadrature points, then the 10 nodes.
_POINTS = np.vstack([TET_QUADRATURE[0], TET10_NODES])
_DN = tet10_shape(_POINTS)[1]  # (14, 10, 3)


def det_f(points: np.ndarray, cells: np.ndarray, u: np.ndarray) -> np.ndarray:
    """det F of every element at its 4 quadrature points and its 10 nodes.

    Parameters
    ----------
    points : (n, 3) float array
        Reference node positions (m).
    cells : (c, 10) int array
        Quadratic tets.
    u : (n, 3) float array
        Nodal displacements (m).

    Returns
    -------
    (c, 14) float array
        det F = det(dx/dr) / det(dX/dr), quadrature points first, then the nodes.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.fea.inversion import TET10_NODES, det_f
    >>> cells = np.arange(10)[None]
    >>> stretch = TET10_NODES * [0.0, 0.0, 1.0]  # u = z e_z: F = diag(1, 1, 2)
    >>> det_f(TET10_NODES, cells, stretch).round(12).ravel().tolist() == [2.0] * 14
    True
    """
    X = points[cells]
    return _det_dr(X + u[cells]) / _det_dr(X)


def _det_dr(x: np.ndarray) -> np.ndarray:
    """det(dx/dr) (c, 14) of node positions x (c, 10, 3): a tensordot and the 3 x 3
    determinant written out (a tenth of einsum and numpy.linalg.det's time: 0.03 s for
    the reference mesh's 8151 cells)."""
    M = np.tensordot(x, _DN, axes=([1], [1])).transpose(0, 2, 1, 3)  # (c, 14, I, r)
    return (
        M[..., 0, 0] * (M[..., 1, 1] * M[..., 2, 2] - M[..., 1, 2] * M[..., 2, 1])
        - M[..., 0, 1] * (M[..., 1, 0] * M[..., 2, 2] - M[..., 1, 2] * M[..., 2, 0])
        + M[..., 0, 2] * (M[..., 1, 0] * M[..., 2, 1] - M[..., 1, 1] * M[..., 2, 0])
    )


def inverted_elements(points: np.ndarray, cells: np.ndarray, u: np.ndarray) -> str:
    """What is inverted at displacements ``u``: "" when det F > 0 at every quadrature
    point and node of every element, else one line naming the count of inverted
    elements, the smallest det F and where it is.

    Parameters
    ----------
    points : (n, 3) float array
        Reference node positions (m).
    cells : (c, 10) int array
        Quadratic tets.
    u : (n, 3) float array
        Nodal displacements (m).

    Returns
    -------
    str
        Empty when no element is inverted.

    Examples
    --------
    One 1 mm quadratic tet whose top corner is pushed through the opposite face:

    >>> import numpy as np
    >>> from fringekit.fea.inversion import TET10_NODES, inverted_elements
    >>> X, cells = TET10_NODES * 1e-3, np.arange(10)[None]
    >>> inverted_elements(X, cells, np.zeros((10, 3)))
    ''
    >>> through = X * [0.0, 0.0, -1.5]  # z -> -z / 2: det F = -0.5
    >>> print(inverted_elements(X, cells, through))  # doctest: +ELLIPSIS
    1 of 1 elements inverted (det F = -0.5 at a quadrature point of element 0, near ...)
    """
    J = det_f(points, cells, u)
    bad = ~(J > 0)  # NaN counts as inverted
    if not bad.any():
        return ""
    e, q = np.unravel_index(int(np.argmin(np.where(np.isfinite(J), J, -np.inf))), J.shape)
    where = "a quadrature point" if q < len(TET_QUADRATURE[0]) else "a node"
    centre = (points[cells[e]] + u[cells[e]])[:4].mean(axis=0) * 1e3
    return (
        f"{int(bad.any(axis=1).sum())} of {len(cells)} elements inverted (det F = "
        f"{J[e, q]:.3g} at {where} of element {e}, near ({centre[0]:.3g}, {centre[1]:.3g}, "
        f"{centre[2]:.3g}) mm)"
    )
