"""The one colour channel a mono stream of colour frames is read in (``track --method
mono``): :class:`MonoChannel`, held from frame to frame."""

from __future__ import annotations

import numpy as np

from fringekit.analysis import (
    brightest_channel,
    channel_agreement,
    featureless,
    strongest_channel,
)
from fringekit.measurement.mono import colour_as_grey

__all__ = ["DECIDE_RANGE", "MonoChannel"]


class MonoChannel:
    """The one colour channel a mono stream of colour frames is read in.

    Every frame of a stream has to be read in one channel: the noise level, the gain and
    the rest light are the stream's, not the frame's. The channel is the light's: the
    strongest (:func:`~fringekit.analysis.strongest_channel`) of the first frame whose
    pattern spans DECIDE_RANGE of full scale in that channel, whose channels must agree
    (monochromatic light; white light is refused, naming ``--method mono``). A frame
    without such a pattern (the sensor at rest in even light, each channel its own noise;
    a light touch, whose weak channels are mostly noise) is read in the channel held, or,
    before any frame has decided it, in its brightest; the decision is never made again,
    so a stream is refused at its first strong frame or not at all. ``switched`` is set
    when the decision changes the channel the frames before it were read in (their noise
    level is then not the stream's).

    Examples
    --------
    A sensor at rest under a green LED, then loaded:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> led = np.array([0.15, 1.0, 0.3])
    >>> rest = 0.02 * led + rng.normal(0, 0.002, (32, 32, 3))
    >>> fringes = np.sin(np.linspace(0, 9, 32))[None, :, None] ** 2 * led * np.ones((32, 1, 1))
    >>> pick = MonoChannel()
    >>> pick(rest, "rest.png"), pick(fringes, "loaded.png")
    (1, 1)
    >>> print(pick.note)
    colour frames of monochromatic light (loaded.png's channels agree, correlation 1.00): read
    in their green channel
    """

    def __init__(self):
        self.index: int | None = None
        self.note = ""
        self.decided = False
        self.switched = False

    def __call__(self, data: np.ndarray, name: str) -> int | None:
        """The channel frame ``data`` (normalised, (rows, cols[, 3])) named ``name`` is
        read in; None for a grey frame."""
        if np.ndim(data) != 3:
            return None
        if self.decided:
            return self.index
        span = float(np.ptp(np.percentile(data, [1, 99], axis=(0, 1)), axis=0).max())
        if span < DECIDE_RANGE or featureless(data):
            if self.index is None:
                self.index = brightest_channel(data)
                self.note = (
                    "colour frames without a light pattern: read in their brightest channel, "
                    f"{_CHANNELS[self.index]}"
                )
            return self.index
        colour_as_grey(data, None, name, "--method mono")  # white light is refused
        before, self.decided = self.index, True
        self.index = strongest_channel(data)
        self.switched = before is not None and before != self.index
        earlier = (
            f"; the frames before it in their brightest, {_CHANNELS[before]}"
            if self.switched
            else ""
        )
        self.note = (
            f"colour frames of monochromatic light ({name}'s channels agree, correlation "
            f"{channel_agreement(data)[0]:.2f}): read in their {_CHANNELS[self.index]} "
            f"channel{earlier}"
        )
        return self.index


_CHANNELS = ("red", "green", "blue")
#: A stream's channel is decided by the first frame whose strongest channel's 1-99 %
#: range reaches this share of full scale: in a weaker pattern the faint channels are
#: mostly noise and disagree though the light is one colour (a touch peaking at 0.1 of
#: full scale under a green LED was refused as white light), and white light's channels
#: only part beyond about half an order, whose dark-field light is brighter than this.
DECIDE_RANGE = 0.2
