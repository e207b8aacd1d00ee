"""Execution utilities shared by the pipeline stages: the cores and one thread pool.

The lowest layer of fringekit: it imports nothing of the project, so :mod:`fea` and
:mod:`optics` use it without depending on each other or on :mod:`meshes`.
"""

from .threads import thread_pool, usable_cores

__all__ = ["thread_pool", "usable_cores"]
