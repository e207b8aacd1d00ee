"""Sparse direct solves: MKL PARDISO on x86-64 (loaded through pypardiso), SciPy SuperLU elsewhere.

PARDISO keeps its symbolic analysis (ordering, phase 11) for as long as the sparsity
pattern stays, so every Newton iteration only refactorises (phase 22) and solves (phase
33). Symmetric matrices use ``mtype = -2`` (real symmetric indefinite: the contact term
and the mean-dilatation pressure can make the tangent indefinite) with the upper
triangle; unsymmetric ones (Coulomb slip) ``mtype = 11`` with the full matrix (Intel
oneMKL PARDISO reference, "pardiso" and "pardiso iparm Parameter").

Mixed precision (``precision="mixed"``, the default with PARDISO): the factorization is
done in single precision (``iparm[27] = 1``), about twice as fast (0.20 s against 0.37-0.42 s
on the 34k-DOF reference tangent), and the solution is refined in double precision,
x <- x + A^-1 (b - A x) with the residual formed from the double-precision matrix, until
the relative residual is below :data:`REFINE_RTOL`. A system that does not get there in
:data:`MAX_REFINE` steps (a condition number near 1/eps_single) is refactorised in double
precision, and the solver stays in double precision from then on.
"""

from __future__ import annotations

import ctypes
import time
from functools import cache

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = [
    "LinearSolver",
    "available_backends",
    "MAX_REFINE",
    "REFINE_RTOL",
    "REUSE_CONTRACTION",
]

#: relative residual |b - A x| / |b| a mixed-precision solve must reach
REFINE_RTOL = 1e-10
#: refinement steps before falling back to a double-precision factorization
MAX_REFINE = 6
#: a reused factor must shrink the residual by this factor in its first refinement step
REUSE_CONTRACTION = 0.05


@cache
def _mkl():
    """The loaded ``mkl_rt`` library (pypardiso finds and loads it), or None."""
    try:
        from pypardiso.pardiso_wrapper import PyPardisoSolver  # optional (x86 only)

        return PyPardisoSolver().libmkl
    except Exception:  # pragma: no cover - depends on the platform
        return None


def available_backends() -> list[str]:
    """The linear-solver backends usable on this machine, fastest first.

    Returns
    -------
    list of str
        ``["pardiso", "scipy"]`` where pypardiso loads MKL (x86-64), else ``["scipy"]``.

    Examples
    --------
    >>> from fringekit.fea import available_backends
    >>> available_backends()[-1]
    'scipy'
    """
    return (["pardiso"] if _mkl() is not None else []) + ["scipy"]


class _Pardiso:
    """One PARDISO handle: a matrix type, a precision and a sparsity pattern."""

    def __init__(self, lib, mtype: int, single: bool):
        self.fn = lib.pardiso
        i32 = ctypes.POINTER(ctypes.c_int32)
        # PARDISO's arguments, in its order (oneMKL reference)
        self.fn.argtypes = [
            ctypes.POINTER(ctypes.c_int64),  # pt
            i32,  # maxfct
            i32,  # mnum
            i32,  # mtype
            i32,  # phase
            i32,  # n
            ctypes.c_void_p,  # a
            i32,  # ia
            i32,  # ja
            i32,  # perm
            i32,  # nrhs
            i32,  # iparm
            i32,  # msglvl
            ctypes.c_void_p,  # b
            ctypes.c_void_p,  # x
            i32,  # error
        ]
        self.fn.restype = None
        self.pt = np.zeros(64, np.int64)
        self.iparm = np.zeros(64, np.int32)
        ip = self.iparm
        ip[0] = 1  # the values below, not MKL's defaults
        ip[1] = 2  # nested-dissection ordering (METIS)
        ip[9] = 13 if mtype == 11 else 8  # pivot perturbation 1e-13 / 1e-8
        ip[10] = ip[12] = 1 if mtype == 11 else 0  # scaling and matching (unsymmetric)
        ip[27] = 1 if single else 0  # single-precision factorization
        ip[34] = 1  # zero-based indices: scipy's arrays as they are
        self.mtype = mtype
        self.dtype = np.float32 if single else np.float64
        self.n = 0
        self._a = self._ia = self._ja = None

    def call(self, phase: int, b: np.ndarray | None = None) -> np.ndarray:
        n = self.n
        rhs = np.zeros((n, 1), self.dtype) if b is None else np.asfortranarray(b, self.dtype)
        x = np.zeros_like(rhs)
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        one = ctypes.c_int32(1)
        self.fn(
            self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),  # pt
            ctypes.byref(one),  # maxfct
            ctypes.byref(one),  # mnum
            ctypes.byref(ctypes.c_int32(self.mtype)),  # mtype
            ctypes.byref(ctypes.c_int32(phase)),  # phase
            ctypes.byref(ctypes.c_int32(n)),  # n
            self._a.ctypes.data,  # a
            self._ia.ctypes.data_as(i32),  # ia
            self._ja.ctypes.data_as(i32),  # ja
            None,  # perm
            ctypes.byref(ctypes.c_int32(rhs.shape[1])),  # nrhs
            self.iparm.ctypes.data_as(i32),  # iparm
            ctypes.byref(ctypes.c_int32(0)),  # msglvl
            rhs.ctypes.data,  # b
            x.ctypes.data,  # x
            ctypes.byref(err),  # error
        )
        if err.value != 0:
            raise RuntimeError(f"PARDISO phase {phase} failed with error {err.value}")
        return x

    def set_matrix(self, A: sp.csr_matrix) -> None:
        self.n = A.shape[0]
        self._a = np.ascontiguousarray(A.data, self.dtype)
        self._ia = np.ascontiguousarray(A.indptr, np.int32)
        self._ja = np.ascontiguousarray(A.indices, np.int32)

    def release(self) -> None:
        if self._a is not None:
            try:
                self.call(-1)
            except Exception:  # pragma: no cover - best effort
                pass
        self._a = None


class LinearSolver:
    """Factorise-and-solve with reuse of the symbolic analysis.

    Parameters
    ----------
    backend : {"auto", "pardiso", "scipy"}
        ``auto`` picks pardiso when pypardiso imports, else scipy.
    precision : {"mixed", "double"}
        PARDISO only: a single-precision factorization refined to double-precision
        accuracy (see the module docstring), or a double-precision factorization.

    Attributes
    ----------
    time_analysis, time_factorize, time_solve : float
        Accumulated wall times (s); refinement steps count as solve time.
    n_factorizations, n_refinements, n_fallbacks, n_reuses : int
        Factorizations, refinement steps, falls back to double precision, and solves
        done on an earlier factor.

    Raises
    ------
    ValueError
        An unknown backend or precision, or ``"pardiso"`` where pypardiso does not load.

    Examples
    --------
    A symmetric system is given by its upper triangle:

    >>> import numpy as np
    >>> import scipy.sparse as sp
    >>> from fringekit.fea import LinearSolver
    >>> upper = sp.csr_matrix(np.array([[4.0, 1.0], [0.0, 3.0]]))
    >>> lin = LinearSolver("scipy")
    >>> x = lin.solve(upper, np.array([1.0, 2.0]), symmetric=True, pattern_id=0)
    >>> np.round(x, 4).tolist(), lin.n_factorizations
    ([0.0909, 0.6364], 1)
    """

    def __init__(self, backend: str = "auto", precision: str = "mixed"):
        # set first: __del__ runs even when the checks below raise
        self._ps: _Pardiso | None = None
        self._key = None
        allowed = ("auto", "pardiso", "scipy")
        if backend not in allowed:
            raise ValueError(
                f"linear solver backend = {backend!r} is not allowed; use one of {allowed}"
            )
        if precision not in ("mixed", "double"):
            raise ValueError(
                f"linear solver precision = {precision!r} is not allowed; use 'mixed' or 'double'"
            )
        if backend == "auto":
            backend = available_backends()[0]
        if backend == "pardiso" and _mkl() is None:
            raise ValueError(
                "linear solver backend = 'pardiso' is not available: pypardiso does not import"
            )
        self.backend = backend
        self.single = backend == "pardiso" and precision == "mixed"
        self.time_analysis = self.time_factorize = self.time_solve = 0.0
        self.n_factorizations = self.n_refinements = self.n_fallbacks = self.n_reuses = 0

    def solve(
        self,
        A: sp.csr_matrix,
        b: np.ndarray,
        *,
        symmetric: bool,
        pattern_id: int,
        reuse: bool = False,
    ) -> np.ndarray:
        """Solve ``A x = b``.

        Parameters
        ----------
        A : csr_matrix
            Upper triangle when ``symmetric``, the full matrix otherwise.
        pattern_id : int
            Changes whenever the sparsity pattern changes (forces a new analysis).
        reuse : bool
            First try the factor of an earlier matrix of the same pattern (PARDISO): its
            solution is refined against ``A`` (x <- x + A_old^-1 (b - A x)); when the first
            step contracts the residual by at least :data:`REUSE_CONTRACTION` and the
            refinement reaches :data:`REFINE_RTOL`, the result is ``A``'s exact solution
            without a factorization. Otherwise ``A`` is factorised as usual.
        """
        if self.backend == "scipy":
            return self._solve_scipy(A, b, symmetric)
        A.sort_indices()
        mtype = -2 if symmetric else 11
        if reuse and self._ps is not None and self._key == (mtype, pattern_id, self.single):
            t = time.perf_counter()
            x0 = self._ps.call(33, b.reshape(-1, 1))[:, 0].astype(float)
            self.time_solve += time.perf_counter() - t
            x, ok = self._refine(A, b, x0, symmetric, contraction=REUSE_CONTRACTION)
            if ok:
                self.n_reuses += 1
                return x
        x = self._factor_and_solve(A, b, symmetric, pattern_id)
        if self.single:
            x, ok = self._refine(A, b, x, symmetric)
            if not ok:  # too ill-conditioned for a single-precision factor
                self.single = False
                self.n_fallbacks += 1
                x = self._factor_and_solve(A, b, symmetric, pattern_id)
        return x

    def _factor_and_solve(self, A, b, symmetric: bool, pattern_id: int) -> np.ndarray:
        mtype = -2 if symmetric else 11
        key = (mtype, pattern_id, self.single)
        if self._ps is None or self._key != key:
            self.release()
            self._ps = _Pardiso(_mkl(), mtype, self.single)
            self._key = key
            self._ps.set_matrix(A)
            t = time.perf_counter()
            self._ps.call(11)
            self.time_analysis += time.perf_counter() - t
        else:
            self._ps.set_matrix(A)
        ps = self._ps
        t = time.perf_counter()
        ps.call(22)
        self.time_factorize += time.perf_counter() - t
        self.n_factorizations += 1
        t = time.perf_counter()
        x = ps.call(33, b.reshape(-1, 1))[:, 0].astype(float)
        self.time_solve += time.perf_counter() - t
        return x

    def _refine(
        self, A, b, x, symmetric: bool, contraction: float = 1.0
    ) -> tuple[np.ndarray, bool]:
        """Iterative refinement in double precision on the current factor; gives up when
        the first step reduces the residual by less than ``contraction``."""
        t = time.perf_counter()
        if symmetric:  # A holds the upper triangle: A_full x = A x + A^T x - diag(A) x
            d = A.diagonal()

            def matvec(v):
                return A @ v + A.T @ v - d * v

        else:

            def matvec(v):
                return A @ v

        bnorm = float(np.linalg.norm(b)) or 1.0
        ok = False
        first = None
        for step in range(MAX_REFINE):
            r = b - matvec(x)
            rnorm = float(np.linalg.norm(r))
            if rnorm <= REFINE_RTOL * bnorm:
                ok = True
                break
            if step == 0:
                first = rnorm
            elif step == 1 and rnorm > contraction * first:
                break
            x = x + self._ps.call(33, r.reshape(-1, 1))[:, 0]
            self.n_refinements += 1
        self.time_solve += time.perf_counter() - t
        return x, ok and bool(np.all(np.isfinite(x)))

    def _solve_scipy(self, A, b, symmetric):
        t = time.perf_counter()
        if symmetric:
            A = (A + sp.triu(A, k=1).T).tocsc()
        lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")
        self.time_factorize += time.perf_counter() - t
        self.n_factorizations += 1
        t = time.perf_counter()
        x = lu.solve(b)
        self.time_solve += time.perf_counter() - t
        return x

    def release(self) -> None:
        """Free PARDISO's memory (the factor can be ~1 GB at 100k DOF)."""
        if self._ps is not None:
            self._ps.release()
        self._ps = None
        self._key = None

    def __del__(self):  # pragma: no cover - best effort
        self.release()
