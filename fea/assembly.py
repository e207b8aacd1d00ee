"""Vectorised element kernels and sparse assembly for 10-node tets.

Mean-dilatation formulation (Simo, Taylor & Pister, CMAME 51, 1985; de Souza Neto et
al., *Computational Methods for Plasticity*, 2008, section 15.4): the volumetric energy
of element ``e`` is evaluated at its mean dilatation ``Jbar_e = v_e / V_e`` (current over
reference volume), the isochoric energy pointwise. The discrete potential is

.. math::

    \\Pi_e(u) = \\sum_q w_q \\Psi_\\mathrm{iso}(F_q) + V_e\\, U(v_e / V_e), \\qquad
    v_e = \\sum_q w_q J_q ,

so the element residual and tangent are exact derivatives of one energy (symmetric,
testable against finite differences). With one pressure per element this is the P2/P0
pair, free of volumetric locking as nu -> 0.5 (checked in tests/test_fea.py).

Two passes: :func:`body_state` evaluates energy and internal forces and keeps the
kinematics (F - I, F^-T, J, U'(Jbar), U''(Jbar)); :func:`body_tangent` forms the element
tangents from them. A line search evaluates its trials with the first pass only, and
the accepted iterate gets its tangent without repeating it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from fringekit._threads import thread_pool

from .element import ReferenceGradients
from .materials import (
    Material,
    NeoHookean,
    cofactor,
    det_minus_one,
)

__all__ = ["BodyState", "body_state", "body_tangent", "cell_dofs", "Pattern"]


def cell_dofs(cells: np.ndarray) -> np.ndarray:
    """(c, 30) global DOF numbers of cells in the element tangent's order: row
    ``10 i + a`` is component ``i`` of node ``a`` (DOF ``3 node + i``).

    Parameters
    ----------
    cells : (c, 10) int array
    """
    return (3 * cells[:, None, :] + np.arange(3)[None, :, None]).reshape(len(cells), 30)


@dataclass(frozen=True)
class BodyState:
    """Element quantities at a displacement.

    Attributes
    ----------
    energy : float, stored energy (J).
    force : (n, 3) float array, internal nodal forces dPi/du (N).
    Ke : (c, 30, 30) float array or None, element tangents (N/m) in the DOF order of
        :func:`cell_dofs` (component-major); None until :func:`body_tangent` forms them.
    F : (c, q, 3, 3) deformation gradients.
    Jbar : (c,) element mean dilatation.
    min_J : float, smallest pointwise det F.
    H : (c, q, 3, 3) displacement gradients F - I, as formed from the displacements.
    G : (c, q, 3, 3) F^-T.
    J : (c, q) det F.
    dU, ddU : (c,) U'(Jbar) and U''(Jbar) of each element's material (Pa).
    """

    energy: float
    force: np.ndarray
    Ke: np.ndarray | None
    F: np.ndarray
    Jbar: np.ndarray
    min_J: float
    H: np.ndarray | None = None
    G: np.ndarray | None = None
    J: np.ndarray | None = None
    dU: np.ndarray | None = None
    ddU: np.ndarray | None = None


def body_state(
    u: np.ndarray,
    cells: np.ndarray,
    grads: ReferenceGradients,
    groups: list[tuple[np.ndarray, Material]],
    *,
    tangent: bool = True,
) -> BodyState:
    """Energy, internal force and (optionally) element tangents of the whole body.

    Parameters
    ----------
    u : (n, 3) float array
        Nodal displacements (m).
    cells : (c, 10) int array
    grads : ReferenceGradients
    groups : list of (cell indices, Material)
        One entry per material region.
    tangent : bool
        Also form the element tangent matrices (:func:`body_tangent`).
    """
    parts = _blockwise(
        lambda lo, hi, sub, sub_groups: _residual_block(u, cells[lo:hi], sub, sub_groups),
        len(cells),
        grads,
        groups,
    )
    min_J = min(p.min_J for p in parts)
    F = np.concatenate([p.F for p in parts])
    if min_J <= 0:
        return BodyState(np.inf, np.zeros_like(u), None, F, np.zeros(len(cells)), min_J)
    force = parts[0].force
    for p in parts[1:]:
        force += p.force
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in "H G J dU ddU".split()}
    energy = float(sum(p.energy for p in parts))
    Jbar = np.concatenate([p.Jbar for p in parts])
    st = BodyState(energy, force, None, F, Jbar, min_J, **cat)
    return body_tangent(st, grads, groups) if tangent else st


def body_tangent(
    st: BodyState, grads: ReferenceGradients, groups: list[tuple[np.ndarray, Material]]
) -> BodyState:
    """``st`` with its element tangents, formed from the kinematics it holds (the
    residual pass is not repeated: a line search evaluates residuals only and the
    accepted iterate gets its tangent here).

    Raises
    ------
    ValueError
        If ``st`` has an inverted element (no tangent exists).
    """
    if st.min_J <= 0:
        raise ValueError("no tangent at a state with an inverted element")
    c = len(st.F)
    Ke = np.empty((c, 3, 10, 3, 10))  # every block writes its rows whole (no zero pass)

    def run(lo, hi, sub, sub_groups):
        _tangent_block(st, slice(lo, hi), sub, sub_groups, Ke[lo:hi])

    _blockwise(run, c, grads, groups, _TANGENT_BLOCK)
    return replace(st, Ke=Ke.reshape(c, 30, 30))


#: cells per block of the residual pass: ~1000 keeps a block's temporaries in cache
#: (measured 2.4x faster than one block on 7.4k cells with 2 threads); blocks run on the
#: cores in threads
_BLOCK = 1000
#: cells per block of the tangent pass, whose temporaries are 30 times larger per cell
#: (on the reference model's 8151 cells, best of 25: 45 ms with 500, 59 ms with 1000)
_TANGENT_BLOCK = 500


def _blocks(c: int, groups, size: int) -> list[tuple[int, int]]:
    """Cell ranges of about ``size`` cells; when every material group is a contiguous
    range (fea.solver sorts the cells by region), no range straddles two groups, so each
    block is one material and runs on views (no gathers)."""
    cuts = [0, c]
    if all(len(i) == 0 or i[-1] - i[0] + 1 == len(i) for i, _ in groups):
        cuts += [int(i[0]) for i, _ in groups if len(i)]
    cuts = np.unique(cuts)
    out = []
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        n = max(1, round((hi - lo) / size))
        edges = np.linspace(lo, hi, n + 1).astype(int)
        out += list(zip(edges[:-1], edges[1:], strict=True))
    return out


def _blockwise(fn, c: int, grads: ReferenceGradients, groups, size: int = _BLOCK) -> list:
    """``fn(lo, hi, gradients, groups)`` on each block of cells, the gradients and the
    group indices restricted to the block; the element kernels are numpy batched
    products that release the GIL, so the blocks run on the cores in threads."""
    blocks = _blocks(c, groups, size)
    if len(blocks) == 1:
        return [fn(0, c, grads, groups)]

    def run(b):
        lo, hi = b
        sub = ReferenceGradients(grads.dNdX[lo:hi], grads.dV[lo:hi], grads.N)
        sub_groups = [(idx[(idx >= lo) & (idx < hi)] - lo, mat) for idx, mat in groups]
        return fn(lo, hi, sub, sub_groups)

    return list(thread_pool().map(run, blocks))


def _one_material(idx, c: int):
    """A view-making index: the whole block when the group covers it."""
    return slice(None) if len(idx) == c else idx


def _residual_block(u, cells, grads, groups) -> BodyState:
    """Energy, internal force and the kinematics of a block of cells."""
    c = len(cells)
    H = np.einsum("cai,cqaJ->cqiJ", u[cells], grads.dNdX, optimize=True)  # H_iJ = u_ai dN_aJ
    F = np.eye(3) + H
    # J - 1, Jbar - 1 and the stresses are formed from H, never as differences of numbers
    # near 1: that round-off (modulus * 1e-16) left a residual floor above the force
    # tolerance with a 1 TPa substrate
    dJ = det_minus_one(H)
    J = 1.0 + dJ
    min_J = float(J.min())
    if min_J <= 0:
        return BodyState(np.inf, np.zeros_like(u), None, F, np.zeros(c), min_J)
    G = cofactor(F) / J[..., None, None]
    dV = grads.dV
    Ve = dV.sum(axis=1)
    dJbar = (dJ * dV).sum(axis=1) / Ve
    energy = 0.0
    S = np.empty_like(F)  # P + U'(Jbar) J G: what the shape-function gradients integrate
    dU, ddU = np.empty(c), np.empty(c)
    for idx, mat in groups:
        if len(idx) == 0:
            continue
        idx = _one_material(idx, c)
        U, dU[idx], ddU[idx] = mat.volumetric(1.0 + dJbar[idx], dJbar[idx])
        W, P, _ = mat.isochoric(F[idx], tangent=False, H=H[idx], G=G[idx], J=J[idx])
        energy += float((W * dV[idx]).sum() + (U * Ve[idx]).sum())
        S[idx] = P + (dU[idx][:, None] * J[idx])[..., None, None] * G[idx]
    S *= dV[..., None, None]
    # f_ai = sum_q w (P_iJ + U' J G_iJ) dN_aJ; d v_e / d u_ai = sum_q w J G_iJ dN_aJ
    fe = np.einsum("cqaJ,cqiJ->cai", grads.dNdX, S, optimize=True)
    force = np.zeros_like(u)
    _scatter_add(force, cells, fe)
    return BodyState(energy, force, None, F, 1.0 + dJbar, min_J, H, G, J, dU, ddU)


def _tangent_block(st: BodyState, cut: slice, grads, groups, Ke) -> None:
    """Element tangents of the cells ``cut`` of ``st`` into ``Ke`` ((c, 3, 10, 3, 10),
    overwritten): the material and geometric part per group, plus the mean-dilatation term
    U''(Jbar) / V_e (dv_e/du)(dv_e/du)."""
    F, G, H, J = st.F[cut], st.G[cut], st.H[cut], st.J[cut]
    dU, ddU = st.dU[cut], st.ddU[cut]
    c = len(F)
    dV = grads.dV
    g = np.einsum("cqiJ,cqaJ->cqia", G, grads.dNdX, optimize=True)  # g_ai = G_iJ dN_aJ
    dv = ((dV * J)[..., None, None] * g).sum(axis=1).reshape(c, 30)  # d v_e / d u
    kv = ddU / dV.sum(axis=1)
    for idx, mat in groups:
        if len(idx) == 0:
            continue
        idx = _one_material(idx, c)
        pJ = dU[idx][:, None] * J[idx]  # (c, q): mean-dilatation pressure times J
        if isinstance(mat, NeoHookean):
            sel = (F[idx], g[idx], J[idx], pJ, grads.dNdX[idx], dV[idx])
            _neo_hookean_stiffness(mat, *sel, Ke, idx, vol=(dv[idx], kv[idx]))
            continue
        Ke[idx] = 0.0
        _, _, A = mat.isochoric(F[idx], tangent=True, H=H[idx], G=G[idx], J=J[idx])
        Gi = G[idx]
        # geometric part of the volume: d(J G_iJ)/dF_kL = J (G_iJ G_kL - G_iL G_kJ)
        At = A + pJ[..., None, None, None, None] * (
            np.einsum("cqiJ,cqkL->cqiJkL", Gi, Gi) - np.einsum("cqiL,cqkJ->cqiJkL", Gi, Gi)
        )
        wdN = grads.dNdX[idx] * dV[idx][..., None, None]
        T = np.einsum("cqaJ,cqiJkL->cqiakL", wdN, At, optimize=True)
        Ke[idx] += np.einsum("cqiakL,cqbL->ciakb", T, grads.dNdX[idx], optimize=True)
        dvi = dv[idx]
        Ke[idx] += (kv[idx][:, None, None] * dvi[:, :, None] * dvi[:, None, :]).reshape(
            -1, 3, 10, 3, 10
        )


def _scatter_add(target: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
    """target[cells[c, a]] += values[c, a] for a (n, 3) target, via bincount (fast)."""
    n = len(target)
    idx = cells.ravel()
    for i in range(3):
        target[:, i] += np.bincount(idx, weights=values[..., i].ravel(), minlength=n)


class Pattern:
    """Fixed sparsity pattern of the reduced system with precomputed scatter positions.

    The reduced system keeps only free DOFs. With ``symmetric=True`` only the upper
    triangle is stored (what PARDISO's symmetric matrix types expect).

    Parameters
    ----------
    n : int
        Number of reduced (free) DOFs.
    blocks : list of (b, k) int arrays
        DOF lists (reduced numbering, -1 for fixed) of dense blocks that will be
        assembled: element DOFs, contact face DOFs with the indenter DOFs, ...
    symmetric : bool
    """

    def __init__(self, n: int, blocks: list[np.ndarray], *, symmetric: bool = True):
        self.n = int(n)
        self.symmetric = bool(symmetric)
        keys = [self._keys(b)[0] for b in blocks]
        diag = np.arange(self.n, dtype=np.int64) * (self.n + 1)
        # sort and drop repeats: numpy's hash-based np.unique took 1.4 s on the reference
        # model's 3.8M keys, a sort takes 0.2 s
        allkeys = np.sort(np.concatenate(keys + [diag]))
        ukeys = allkeys[np.concatenate([[True], allkeys[1:] != allkeys[:-1]])]
        self.keys = ukeys
        rows = ukeys // self.n
        self.indices = (ukeys % self.n).astype(np.int32)
        self.indptr = np.searchsorted(rows, np.arange(self.n + 1)).astype(np.int32)
        self.nnz = len(ukeys)

    def _keys(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Global keys of the kept entries of dense blocks, and which local entries they are."""
        k = dofs.shape[1]
        if self.symmetric:
            ia, ib = np.triu_indices(k)
        else:
            ia, ib = np.indices((k, k)).reshape(2, -1)
        r, c = dofs[:, ia], dofs[:, ib]
        keep = (r >= 0) & (c >= 0)
        if self.symmetric:
            r, c = np.minimum(r, c), np.maximum(r, c)
        local = (np.arange(len(dofs))[:, None] * (k * k) + (ia * k + ib)[None, :])[keep]
        return r[keep].astype(np.int64) * self.n + c[keep], local

    def scatter(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions in the data array and local flat indices for blocks on ``dofs``.

        Raises
        ------
        KeyError
            If an entry is not in the pattern (the caller rebuilds the pattern).
        """
        keys, local = self._keys(dofs)
        pos = np.searchsorted(self.keys, keys)
        pos = np.minimum(pos, self.nnz - 1)
        if not np.array_equal(self.keys[pos], keys):
            raise KeyError("block entries outside the sparsity pattern")
        return pos, local

    def matrix(self, parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> sp.csr_matrix:
        """Assemble ``sum of blocks`` given (positions, local indices, flat block values)."""
        data = np.zeros(self.nnz)
        for pos, local, values in parts:
            data += np.bincount(pos, weights=values[local], minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def _neo_hookean_stiffness(mat, F, g, J, pJ, dNdX, wq, Ke, idx, vol):
    """Neo-Hookean + mean-dilatation tangent as sums of outer products.

    With f_a = F dN_a, g_a = G dN_a (G = F^-T), a = J^(-2/3), I1 = tr C, the tangent
    d^2 Pi / du_ai du_bk of the isochoric energy plus the volumetric geometric term
    (fea.materials.NeoHookean.isochoric contracted with the shape-function gradients) is

        sum_q w [ mu a (dN_a . dN_b) d_ik
                  - 2/3 mu a (f_ai g_bk + g_ai f_bk) + (2/9 mu a I1 + pJ) g_ai g_bk
                  + (1/3 mu a I1 - pJ) g_bi g_ak ],

    plus the mean-dilatation term k dv_ai dv_bk, which a batched matrix product of the
    stacked vectors evaluates several times faster than the 4th-order tensor
    contraction. ``g`` (c, q, 3, 10) holds g_ai as [i, a]; ``wq`` (c, q) are the volume
    weights (m^3); ``vol`` is (dv (c, 30), k (c,)). Writes ``Ke[idx]`` ((c, 3, 10, 3,
    10), DOF order (i, a)); with ``idx`` a full slice the product is formed in place.
    """
    I1 = np.einsum("...ij,...ij->...", F, F)
    mua = mat.mu * J ** (-2.0 / 3.0)
    c = len(F)
    f = np.einsum("cqiJ,cqaJ->cqia", F, dNdX, optimize=True)  # f_ai = F_iJ dN_aJ
    D = np.einsum("cqaJ,cqbJ->cab", dNdX * (wq * mua)[..., None, None], dNdX, optimize=True)
    c_fg = (wq * (-2.0 / 3.0) * mua)[..., None]
    c_gg = (wq * ((2.0 / 9.0) * mua * I1 + pJ))[..., None]
    c_sw = (wq * ((1.0 / 3.0) * mua * I1 - pJ))[..., None]
    fl = f.reshape(c, -1, 30)  # (c, q, 30), column index (i, a)
    gl = g.reshape(c, -1, 30)
    dv, k = vol
    left = np.concatenate([fl, gl, dv[:, None]], axis=1)  # (c, 2q + 1, 30)
    right = np.concatenate([c_fg * gl, c_fg * fl + c_gg * gl, (k[:, None] * dv)[:, None]], axis=1)
    whole = isinstance(idx, slice)
    K = np.matmul(
        left.transpose(0, 2, 1), right, out=Ke.reshape(c, 30, 30) if whole else None
    ).reshape(c, 3, 10, 3, 10)
    for i in range(3):
        K[:, i, :, i, :] += D
    # swap term: Y[(k,a),(i,b)] = sum_q c_sw g_ak g_bi, added as K[i,a,k,b]
    Y = np.matmul(gl.transpose(0, 2, 1), c_sw * gl).reshape(c, 3, 10, 3, 10)
    K += Y.transpose(0, 3, 2, 1, 4)
    if not whole:
        Ke[idx] = K
