"""Cores and one shared thread pool for the vectorised kernels of fea and optics.

numpy's batched products and elementwise loops release the GIL, so blocks of cells
(fea.assembly) or rays (optics.jones) run on the cores in plain threads. The inverse's
least-squares fits run with one BLAS thread (:func:`single_blas_thread`): the rays
between them already use the cores, and OpenBLAS's own threads made the fits' SVDs of
tall Jacobians (tens of thousands of residuals by 5-20 parameters) take 60-67 ms
instead of 2-20 ms; with one thread the colour tracker's cold start on its bench (four
contacts, 256 px, 2 cores) fell from 10.7-12.8 to 8.6-9.2 s (four runs each), and the
grey one stayed within its run-to-run spread. The tracker's frames run so too
(:meth:`fringekit.tracking.Tracker.step`): with the ``--show`` window's process beside it
the track bench ran at 5.07 frames a second with 84 redraws, against 4.42 with 28.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import cache

from threadpoolctl import ThreadpoolController

__all__ = ["single_blas_thread", "task_pool", "thread_pool", "usable_cores"]


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


@cache
def thread_pool() -> ThreadPoolExecutor:
    """The process-wide pool, one worker per usable core (created on first use)."""
    return ThreadPoolExecutor(max_workers=usable_cores(), thread_name_prefix="fringekit")


@cache
def task_pool() -> ThreadPoolExecutor:
    """A second pool, one worker per usable core, for tasks that themselves use
    :func:`thread_pool` (a task waiting on its own pool's workers could wait forever)."""
    return ThreadPoolExecutor(max_workers=usable_cores(), thread_name_prefix="fringekit-task")


@contextmanager
def single_blas_thread():
    """BLAS (OpenBLAS, MKL...) limited to one thread inside the block, restored after.

    The BLAS libraries are found once, on first use (threadpoolctl's search of the loaded
    libraries takes about 1 ms a time; the limit itself 13 us): those loaded by then, as
    numpy's and scipy's are once fringekit is imported.

    Examples
    --------
    >>> from threadpoolctl import threadpool_info
    >>> with single_blas_thread():
    ...     blas = [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    >>> set(blas) <= {1}
    True
    """
    with _blas_controller().limit(limits=1, user_api="blas"):
        yield


@cache
def _blas_controller() -> ThreadpoolController:
    """The process's thread-pool libraries, found on first use."""
    return ThreadpoolController()
