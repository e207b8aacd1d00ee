"""Cores and one shared thread pool for the vectorised kernels of fea and optics.

numpy's batched products and elementwise loops release the GIL, so blocks of cells
(fea.assembly) or rays (optics.jones) run on the cores in plain threads.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from functools import cache

__all__ = ["usable_cores", "thread_pool"]


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports it)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


@cache
def thread_pool() -> ThreadPoolExecutor:
    """The process-wide pool, one worker per usable core (created on first use)."""
    return ThreadPoolExecutor(max_workers=usable_cores(), thread_name_prefix="fringekit")
