"""Output folders that hold exactly one finished run.

A run writes into a fresh hidden folder beside its output folder (:func:`work_folder`)
and replaces the output folder with it when it has finished (:func:`swap_in`): a run that
fails or is interrupted leaves an earlier result as it was.
"""

from __future__ import annotations

import os
import shutil
import uuid
from contextlib import contextmanager
from pathlib import Path

__all__ = ["run_folder", "swap_in", "work_folder"]


def work_folder(out: Path) -> Path:
    """A new empty folder beside ``out`` (same parent, so the swap is a rename)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    work = out.with_name(f".{out.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.part")
    work.mkdir()
    return work


def swap_in(work: Path, dest: Path) -> None:
    """Replace ``dest`` by the finished run folder ``work``."""
    old = None
    if dest.exists():
        old = dest.with_name(f".{dest.name}.old-{os.getpid()}")
        os.replace(dest, old)
    os.replace(work, dest)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


@contextmanager
def run_folder(out):
    """``with run_folder(out) as work:`` write into ``work``; it replaces ``out`` when
    the block ends normally and is removed when it raises."""
    out = Path(out)
    work = work_folder(out)
    try:
        yield work
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    swap_in(work, out)
