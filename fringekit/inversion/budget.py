"""The progress and the time budget of ``fringekit invert``.

The fit reports each stage as it ends (detection, start scan, far fit, near fit, each
round of the basin search and of the model selection) through :class:`Budget`, one line
each with the time so far. The same calls are the fit's safe points: once the budget's
``max_seconds`` are spent, :meth:`Budget.spent` says so there and from then on, every
loop of the fit stops at its next safe point and the answer is what the stages so far
made, flagged (:attr:`Budget.stopped` names the last stage that ended). The budget is
judged only at the safe points, so a budget of 0 stops after the first stage, whatever
the machine's speed. The stages are timed on a second clock (``timer``, the real one),
so a test's clock sees the same readings: the time between two safe points (the first
from :meth:`Budget.begin_stages`) is the stage's that ended at the second;
:meth:`Budget.stage_times` sums them per kind of stage (every round of the basin search
together), which ``invert`` writes to ``summary.json``.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["DEFAULT_MAX_SECONDS", "Budget"]

#: The default time budget of ``invert`` (s): the reference bench's six sheared heads
#: took up to 307 s on 2 cores (docs/cli.md), so twice that.
DEFAULT_MAX_SECONDS = 600.0


@dataclass
class Budget:
    """Stage lines and the time budget of one inversion.

    Attributes
    ----------
    max_seconds : float
        The budget (s); ``inf`` never stops.
    say : callable
        Where the stage lines go (nothing by default).
    clock : callable
        Seconds, read at the safe points only (default ``time.monotonic``).
    timer : callable
        Seconds, for the stages' times (default ``time.perf_counter``).
    stopped : str or None
        The stage after which the budget was found spent; None while it lasts.
    stages : dict
        Seconds per kind of stage so far (``"far fit"``, ``"basin search"``...), in the
        order they first ended.

    Examples
    --------
    >>> from fringekit.inversion.budget import Budget
    >>> b = Budget(0.0, say=print)
    >>> b.spent("detection", "1 candidate(s)")
    invert: detection: 1 candidate(s) (0.0 s)
    invert: the time budget of 0 s is spent after detection; stopping there
    True
    >>> b.spent("far fit"), b.stopped
    (True, 'detection')

    The time of each kind of stage, on a timer that advances 2 s a reading:

    >>> ticks = iter(range(0, 100, 2))
    >>> b = Budget(timer=lambda: next(ticks))
    >>> for stage in ("detection", "basin search, round 1", "basin search, round 2"):
    ...     _ = b.spent(stage)
    >>> b.stage_times()
    {'detection_s': 2.0, 'basin_search_s': 4.0, 'other_s': 2.0, 'total_s': 8.0}
    """

    max_seconds: float = DEFAULT_MAX_SECONDS
    say: Callable[[str], None] = field(default=lambda s: None, repr=False)
    clock: Callable[[], float] = field(default=time.monotonic, repr=False)
    timer: Callable[[], float] = field(default=time.perf_counter, repr=False)
    stopped: str | None = None
    stages: dict = field(default_factory=dict, init=False)
    start: float = field(init=False)
    _last: float = field(init=False, repr=False)
    _begun: float = field(init=False, repr=False)

    def __post_init__(self):
        self.start = self.clock()
        self._last = self._begun = self.timer()

    def begin_stages(self) -> None:
        """Start timing the stages here (the fit's start; the budget itself still counts
        from its creation)."""
        self._begun = self._last = self.timer()
        self.stages.clear()

    def elapsed(self) -> float:
        """Seconds since the budget began."""
        return self.clock() - self.start

    def spent(self, stage: str, detail: str = "") -> bool:
        """Report that ``stage`` ended (one line) and whether the budget is spent, now or
        at an earlier safe point (then nothing is reported)."""
        if self.stopped is not None:
            return True
        t = self.elapsed()
        now = self.timer()
        kind = re.sub(r", round \d+$", "", stage)
        self.stages[kind] = self.stages.get(kind, 0.0) + (now - self._last)
        self._last = now
        self.say(f"invert: {stage}" + (f": {detail}" if detail else "") + f" ({t:.1f} s)")
        if math.isfinite(self.max_seconds) and t >= self.max_seconds:
            self.stopped = stage
            self.say(
                f"invert: the time budget of {self.max_seconds:g} s is spent after {stage}; "
                "stopping there"
            )
        return self.stopped is not None

    def stage_times(self) -> dict[str, float]:
        """Seconds per kind of stage, keyed ``"<stage>_s"`` (spaces as underscores);
        ``other_s``, the work after the last safe point (the retries' own stages are
        counted with their kind; the refits after a dropped or merged contact, the
        verdict and the uncertainty are the rest); and ``total_s``, all since
        :meth:`begin_stages`."""
        out = {f"{k.replace(' ', '_')}_s": float(v) for k, v in self.stages.items()}
        total = float(self.timer() - self._begun)
        return {**out, "other_s": max(0.0, total - sum(out.values())), "total_s": total}
