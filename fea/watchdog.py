"""Telling the user what a long Newton run is doing: loads and iteration on the progress
bar, and a warning when one increment runs long."""

from __future__ import annotations

import logging
import time

__all__ = ["STALL_WARN_S", "Watchdog"]

log = logging.getLogger("fringekit.fea")

#: wall time (s) of one increment after which the user is told it is still running
STALL_WARN_S = 60.0


class Watchdog:
    """Shows the loads and the Newton iteration on the progress bar, and tells the user,
    once per increment, when an increment runs longer than :data:`STALL_WARN_S`: which
    loads it is trying, how far Newton got, what to change."""

    def __init__(self, limit_s: float | None = None, bar=None) -> None:
        self.limit_s = STALL_WARN_S if limit_s is None else limit_s
        self.bar = bar  # a tqdm bar, or None
        self.started = time.perf_counter()
        self.target = ""
        self.warned = False

    def start(self, target: str) -> None:
        """A new increment towards ``target`` (the loads, in words) begins."""
        self.started, self.target, self.warned = time.perf_counter(), target, False
        if self.bar is not None:
            self.bar.set_postfix_str(f"{target}: Newton iteration 0")

    def check(self, iteration: int, residual: float, max_iterations: int) -> None:
        """Called after each Newton iteration; warns once past the limit."""
        if self.bar is not None:
            self.bar.set_postfix_str(
                f"{self.target}: Newton iteration {iteration + 1}, residual {residual:.2g} N"
            )
        elapsed = time.perf_counter() - self.started
        if self.warned or elapsed < self.limit_s:
            return
        self.warned = True
        log.warning(
            "fea: the increment to %s has run %.0f s (Newton iteration %d of %d, residual "
            "%.3g N) and goes on; if it is cut back again and again, add load states on the "
            "way (indenter.load_N), or raise solver.max_iterations",
            self.target,
            elapsed,
            iteration + 1,
            max_iterations,
            residual,
        )
