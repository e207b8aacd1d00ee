"""The progress and the time budget of ``fringekit invert``.

The fit reports each stage as it ends (detection, start scan, far fit, near fit, each
round of the basin search and of the model selection) through :class:`Budget`, one line
each with the time so far. The same calls are the fit's safe points: once the budget's
``max_seconds`` are spent, :meth:`Budget.spent` says so there and from then on, every
loop of the fit stops at its next safe point and the answer is what the stages so far
made, flagged (:attr:`Budget.stopped` names the last stage that ended). The clock is
read only at the safe points, so a budget of 0 stops after the first stage, whatever
the machine's speed.
"""

from __future__ import annotations

import math
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
    stopped : str or None
        The stage after which the budget was found spent; None while it lasts.

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
    """

    max_seconds: float = DEFAULT_MAX_SECONDS
    say: Callable[[str], None] = field(default=lambda s: None, repr=False)
    clock: Callable[[], float] = field(default=time.monotonic, repr=False)
    stopped: str | None = None
    start: float = field(init=False)

    def __post_init__(self):
        self.start = self.clock()

    def elapsed(self) -> float:
        """Seconds since the budget began."""
        return self.clock() - self.start

    def spent(self, stage: str, detail: str = "") -> bool:
        """Report that ``stage`` ended (one line) and whether the budget is spent, now or
        at an earlier safe point (then nothing is reported)."""
        if self.stopped is not None:
            return True
        t = self.elapsed()
        self.say(f"invert: {stage}" + (f": {detail}" if detail else "") + f" ({t:.1f} s)")
        if math.isfinite(self.max_seconds) and t >= self.max_seconds:
            self.stopped = stage
            self.say(
                f"invert: the time budget of {self.max_seconds:g} s is spent after {stage}; "
                "stopping there"
            )
        return self.stopped is not None
