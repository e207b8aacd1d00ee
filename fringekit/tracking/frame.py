"""One frame's answer of the tracker: each contact's id, loads and their uncertainty."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TrackedFrame"]


@dataclass(frozen=True)
class TrackedFrame:
    """One frame's contacts.

    Attributes
    ----------
    index : int
        The frame's position in the stream.
    time_s : float
        Its time (s) from the stream's start (NaN when the stream has no clock).
    ids : (n,) int array
        Each contact's id, kept from its touch to its release.
    params : (n, 5) array
        x, y (mm), Fz, Fx, Fy (N).
    sd : (n, 5) array
        Their stated 1-sigma (as ``invert``'s).
    residual_rms : (n,) array
        The residual within 3 mm of each contact, in fringe amplitudes.
    reliable : (n,) bool array
        Residual below ``invert``'s warning level, and the loads within the library's
        range (a fit held at its largest normal load or ratio, which ``invert`` would
        refuse, is not).
    events : tuple of str
        What happened besides a warm fit: ``"start"``, ``"touch <id>"``,
        ``"release <id>"``, ``"recover"``.
    times_s : dict
        Seconds spent per stage of this frame.
    """

    index: int
    time_s: float
    ids: np.ndarray
    params: np.ndarray
    sd: np.ndarray
    residual_rms: np.ndarray
    reliable: np.ndarray
    events: tuple = ()
    times_s: dict = field(default_factory=dict)
