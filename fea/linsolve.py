"""Sparse direct solves: MKL PARDISO through pypardiso on x86-64, SciPy SuperLU elsewhere.

PARDISO keeps one solver object so the symbolic analysis (ordering, phase 11) is done
once per sparsity pattern and every Newton iteration only refactorises (phase 22) and
solves (phase 33). Symmetric matrices use ``mtype = -2`` (real symmetric indefinite: the
contact term and the mean-dilatation pressure can make the tangent indefinite) with the
upper triangle; unsymmetric ones (Coulomb slip) ``mtype = 11`` with the full matrix
(Intel oneMKL PARDISO reference, "pardiso mtype").
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["LinearSolver", "available_backends"]


def _pardiso_class():
    try:
        import pypardiso  # noqa: F401
        from pypardiso.pardiso_wrapper import PyPardisoSolver
    except Exception:  # pragma: no cover - depends on the platform
        return None
    return PyPardisoSolver


def available_backends() -> list[str]:
    """Backends usable on this machine, fastest first."""
    return (["pardiso"] if _pardiso_class() is not None else []) + ["scipy"]


class LinearSolver:
    """Factorise-and-solve with reuse of the symbolic analysis.

    Parameters
    ----------
    backend : {"auto", "pardiso", "scipy"}
        ``auto`` picks pardiso when pypardiso imports, else scipy.

    Attributes
    ----------
    time_analysis, time_factorize, time_solve : float
        Accumulated wall times (s).
    """

    def __init__(self, backend: str = "auto"):
        # set first: __del__ runs even when the checks below raise
        self._ps = None
        self._pattern_id = None
        self._mtype = None
        allowed = ("auto", "pardiso", "scipy")
        if backend not in allowed:
            raise ValueError(
                f"linear solver backend = {backend!r} is not allowed; use one of {allowed}"
            )
        if backend == "auto":
            backend = available_backends()[0]
        if backend == "pardiso" and _pardiso_class() is None:
            raise ValueError(
                "linear solver backend = 'pardiso' is not available: pypardiso does not import"
            )
        self.backend = backend
        self.time_analysis = self.time_factorize = self.time_solve = 0.0
        self.n_factorizations = 0

    def solve(
        self, A: sp.csr_matrix, b: np.ndarray, *, symmetric: bool, pattern_id: int
    ) -> np.ndarray:
        """Solve ``A x = b``.

        Parameters
        ----------
        A : csr_matrix
            Upper triangle when ``symmetric``, the full matrix otherwise.
        pattern_id : int
            Changes whenever the sparsity pattern changes (forces a new analysis).
        """
        if self.backend == "scipy":
            return self._solve_scipy(A, b, symmetric)
        mtype = -2 if symmetric else 11
        if self._ps is None or self._mtype != mtype or self._pattern_id != pattern_id:
            self.release()
            cls = _pardiso_class()
            self._ps = cls(mtype=mtype)
            self._mtype, self._pattern_id = mtype, pattern_id
            A.sort_indices()
            t = time.perf_counter()
            self._ps._check_A(A)
            self._ps.set_phase(11)
            self._ps._call_pardiso(A, np.zeros((A.shape[0], 1)))
            self.time_analysis += time.perf_counter() - t
        ps = self._ps
        t = time.perf_counter()
        ps.set_phase(22)
        ps._call_pardiso(A, np.zeros((A.shape[0], 1)))
        self.time_factorize += time.perf_counter() - t
        self.n_factorizations += 1
        t = time.perf_counter()
        ps.set_phase(33)
        x = ps._call_pardiso(A, np.asfortranarray(b.reshape(-1, 1)))
        self.time_solve += time.perf_counter() - t
        return x.ravel()

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
            try:
                self._ps.free_memory(everything=True)
            except Exception:  # pragma: no cover
                pass
        self._ps = None
        self._pattern_id = None

    def __del__(self):  # pragma: no cover - best effort
        self.release()
