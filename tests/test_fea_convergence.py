"""Convergence rate of the solid elements on a smooth problem with an exact solution.

In the style of scikit-fem's convergence tests: the error of three successively halved
meshes, the slope of log(error) against log(h) fitted by least squares, compared with the
theoretical rate to +-0.1.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fringekit.fea import NeoHookean
from fringekit.fea.assembly import Pattern, body_state, cell_dofs
from fringekit.fea.element import reference_gradients, tet10_shape

# Kuhn's split of the unit cube into six tetrahedra along the diagonal (0,0,0)-(1,1,1):
# one per permutation of the axes, each a path of unit steps. The same split in every
# cube of a grid gives a conforming mesh, and every edge midpoint is a node of the grid
# of half the spacing.
_PATHS = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]
_MID = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])  # fea.element's order

# phi = exp(A x) sin(B y) cos(C z) with A^2 = B^2 + C^2 is harmonic, so u = grad(phi)
# has div u = 0 and div(grad u) = grad(lap phi) = 0: it solves the equations of linear
# elasticity without body force, for any Lame constants, with zero pressure.
A, B, C = np.sqrt(2.0), 1.0, 1.0


def _exact(x):
    ex, sy, cy = np.exp(A * x[..., 0]), np.sin(B * x[..., 1]), np.cos(B * x[..., 1])
    sz, cz = np.sin(C * x[..., 2]), np.cos(C * x[..., 2])
    u = np.stack([A * ex * sy * cz, B * ex * cy * cz, -C * ex * sy * sz], axis=-1)
    # grad u = the Hessian of phi (symmetric, trace 0)
    g = np.empty((*x.shape[:-1], 3, 3))
    g[..., 0, 0] = A * A * ex * sy * cz
    g[..., 1, 1] = -B * B * ex * sy * cz
    g[..., 2, 2] = -C * C * ex * sy * cz
    g[..., 0, 1] = g[..., 1, 0] = A * B * ex * cy * cz
    g[..., 0, 2] = g[..., 2, 0] = -A * C * ex * sy * sz
    g[..., 1, 2] = g[..., 2, 1] = -B * C * ex * cy * sz
    return u, g


def _cube_mesh(n: int):
    """Quadratic tets of the unit cube, n cubes per side (6 n^3 cells)."""
    m = 2 * n + 1  # nodes per side on the grid of half the spacing

    def node(ijk):
        return (ijk[..., 0] * m + ijk[..., 1]) * m + ijk[..., 2]

    g = np.arange(m) / (m - 1)
    points = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    corner = 2 * np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    cells = []
    for path in _PATHS:
        v = [np.zeros(3, int)]
        for axis in path:
            v.append(v[-1] + 2 * np.eye(3, dtype=int)[axis])
        verts = corner[:, None, :] + np.array(v)[None]  # (cubes, 4, 3), doubled coordinates
        if np.linalg.det(np.array(v[1:]) - v[0]) < 0:  # orient positively
            verts = verts[:, [0, 2, 1, 3]]
        mids = (verts[:, _MID[:, 0]] + verts[:, _MID[:, 1]]) // 2
        cells.append(node(np.concatenate([verts, mids], axis=1)))
    return points, np.concatenate(cells)


def _quadrature(order: int = 5):
    """Conical product Gauss rule on the reference tet (exact well beyond degree 6)."""
    x, w = np.polynomial.legendre.leggauss(order)
    x, w = (x + 1) / 2, w / 2
    a, b, c = np.meshgrid(x, x, x, indexing="ij")
    wa, wb, wc = np.meshgrid(w, w, w, indexing="ij")
    rst = np.stack([a, b * (1 - a), c * (1 - a) * (1 - b)], -1).reshape(-1, 3)
    return rst, (wa * wb * wc * (1 - a) ** 2 * (1 - b)).ravel()


def _errors(n: int, mat) -> tuple[float, float]:
    """L2 and H1-seminorm errors of the small-strain solution on the n-cube mesh.

    The linear problem is the solver's own: the tangent of fea.assembly.body_state at
    u = 0 (the neo-Hookean solid with mean dilatation, linearised), with the exact
    displacement on every boundary node and no load inside."""
    points, cells = _cube_mesh(n)
    grads = reference_gradients(points, cells)
    st = body_state(np.zeros_like(points), cells, grads, [(np.arange(len(cells)), mat)])
    dofs = cell_dofs(cells)
    pat = Pattern(3 * len(points), [dofs], symmetric=True)
    U = pat.matrix([(*pat.scatter(dofs), st.Ke.ravel())])
    K = (U + sp.triu(U, k=1).T).tocsr()
    on_boundary = np.any((points == 0) | (points == 1), axis=1)
    fixed = np.repeat(on_boundary, 3)
    u = np.zeros(3 * len(points))
    u[fixed] = _exact(points[on_boundary])[0].ravel()
    free = ~fixed
    u[free] = spla.spsolve(K[free][:, free].tocsc(), -K[free][:, fixed] @ u[fixed])
    u = u.reshape(-1, 3)

    rst, w = _quadrature()
    N, dN = tet10_shape(rst)
    X = points[cells]  # (c, 10, 3)
    Jm = np.einsum("caI,qar->cqIr", X, dN)
    dV = np.linalg.det(Jm) * w
    dNdX = np.einsum("qar,cqrJ->cqaJ", dN, np.linalg.inv(Jm))
    ue, ge = _exact(np.einsum("qa,caI->cqI", N, X))
    uh = np.einsum("qa,cai->cqi", N, u[cells])
    gh = np.einsum("cqaJ,cai->cqiJ", dNdX, u[cells])
    l2 = np.sqrt(np.sum(dV * np.sum((uh - ue) ** 2, axis=-1)))
    h1 = np.sqrt(np.sum(dV * np.sum((gh - ge) ** 2, axis=(-2, -1))))
    return float(l2), float(h1)


@pytest.mark.parametrize("nu", [pytest.param(0.3, marks=pytest.mark.slow), 0.49])
def test_quadratic_tets_converge_at_rate_3_in_l2_and_2_in_h1(nu):
    """P2 tetrahedra: the displacement error falls as h^3 in L2 and its gradient as h^2.

    A smooth solution of linear elasticity (the gradient of a harmonic function, zero
    pressure: the one-per-cell mean-dilatation pressure cannot lower the rate) on the
    unit cube, meshes of 2, 4 and 8 cubes per side (6 tets per cube), the exact field
    imposed on the boundary. At nu = 0.49 the bulk modulus is 50 times the shear
    modulus: the rates stay those of the element, no locking."""
    mat = NeoHookean.from_E_nu(1.0, nu)
    ns = np.array([2, 4, 8])
    errs = np.array([_errors(n, mat) for n in ns])
    h = 1.0 / ns
    slope_l2 = np.polyfit(np.log(h), np.log(errs[:, 0]), 1)[0]
    slope_h1 = np.polyfit(np.log(h), np.log(errs[:, 1]), 1)[0]
    print(f"nu = {nu}: errors {errs.tolist()}, slopes L2 {slope_l2:.3f}, H1 {slope_h1:.3f}")
    assert abs(slope_l2 - 3.0) <= 0.1, slope_l2
    assert abs(slope_h1 - 2.0) <= 0.1, slope_h1
