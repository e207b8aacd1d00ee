"""Independent tasks on Dask: a local cluster by default, or an existing scheduler.

``fringekit sweep`` (cases) and ``fringekit library build`` (load branches) both hand
their unfinished tasks to :func:`run_tasks`: one single-threaded worker process per core
by default, so the direct solver of one task does not fight another for the cores.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence

from tqdm.auto import tqdm

__all__ = ["run_tasks"]


def run_tasks(
    fn: Callable,
    tasks: Sequence,
    keys: Sequence[str],
    *args,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    desc: str = "tasks",
    unit: str = "task",
    on_result: Callable | None = None,
) -> None:
    """Run ``fn(task, *args)`` for every task on Dask; ``on_result`` sees each result as
    it arrives (in completion order). A progress bar with an ETA shows when ``progress``.
    ``workers=0`` runs the tasks one after the other in this process (no cluster).
    """
    from dask.distributed import Client, LocalCluster, as_completed

    # importing distributed sets its logger to INFO (Dask's config): the cluster's
    # chatter (scheduler, nanny, connections) is not the run's progress
    logging.getLogger("distributed").setLevel(logging.WARNING)
    if not tasks:
        return
    if workers == 0 and not scheduler:
        for t in tqdm(tasks, desc=desc, unit=unit, disable=not progress):
            res = fn(t, *args)
            if on_result is not None:
                on_result(res)
        return
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        n = workers or max(1, min(len(tasks), os.cpu_count() or 1))
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    try:
        futures = [
            client.submit(fn, t, *args, key=k, pure=False) for t, k in zip(tasks, keys, strict=True)
        ]
        with tqdm(total=len(futures), desc=desc, unit=unit, disable=not progress) as bar:
            for fut in as_completed(futures):
                res = fut.result()
                bar.update(1)
                if on_result is not None:
                    on_result(res)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
