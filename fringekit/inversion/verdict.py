"""The verdict on an inversion: refusals and flags (the uncertainties are
:mod:`fringekit.inversion.uncertainty`'s).

An image the library cannot explain is refused (:class:`InvertError`, exit 2, one line)
rather than answered: an indenter at the edge of the library's range (the fit is held
there, not converged), or an RMS residual over the whole fitted image above
MAX_RESIDUAL of the fringe amplitude. An indenter whose ``residual_rms`` (the RMS
residual within ``fringekit.inversion.fit.WINDOW_MM`` of it, the figure ``invert``
reports) is above WARN_RESIDUAL is returned but flagged.
"""

from __future__ import annotations

import numpy as np

from fringekit.errors import RefusedError

__all__ = [
    "AT_LARGEST",
    "InvertError",
    "MAX_RESIDUAL",
    "WARN_RESIDUAL",
    "refuse",
    "residual_warnings",
]

MAX_RESIDUAL = 0.2
#: An indenter whose residual near it (within fringekit.inversion.fit.WINDOW_MM) is above this
#: fraction of the fringe amplitude is flagged as not reliable. Measured on the coarse
#: bench: accepted fits within 3 % of their loads left 0.04-0.19 (20 indenters, three
#: methods); a fit that explained a neighbour's fringes with one indenter's tangential
#: load (Fz 32 % and 22 % off, total residual under MAX_RESIDUAL) left 0.25 and 0.31 near
#: the two wrong ones.
WARN_RESIDUAL = 0.22
#: A normal load (or a tangential ratio) at or above this fraction of the library's
#: largest sits at its edge.
AT_LARGEST = 0.995


class InvertError(RefusedError):
    """An image the library cannot explain (exit 2, one line naming the quantity).

    Examples
    --------
    >>> import fringekit
    >>> issubclass(fringekit.InvertError, fringekit.RefusedError)
    True
    """


def residual_warnings(params: np.ndarray, residual_rms: np.ndarray) -> list[str]:
    """One warning per indenter whose residual near it is above WARN_RESIDUAL."""
    return [
        f"indenter {i + 1} at ({v[0]:.2f}, {v[1]:.2f}) mm is not reliable: its residual_rms "
        f"is {r:.2f} of the fringe amplitude (above {WARN_RESIDUAL}); the fit may explain a "
        "neighbour's fringes with its load"
        for i, (v, r) in enumerate(zip(params, residual_rms, strict=True))
        if r > WARN_RESIDUAL
    ]


def refuse(q: np.ndarray, lib, total: float) -> None:
    """An image the library cannot explain is refused, not returned."""
    for i, v in enumerate(q):
        if v[2] >= AT_LARGEST * lib.max_load_N:
            raise InvertError(
                f"indenter {i + 1} at ({v[0]:.2f}, {v[1]:.2f}) mm needs a normal load at or "
                f"beyond the library's largest, {lib.max_load_N:g} N; build a library with "
                "larger --load-N"
            )
        ratio = np.hypot(v[3], v[4]) / max(v[2], 1e-12)
        if ratio >= AT_LARGEST * lib.max_ratio:  # the fit is held at the largest ratio
            raise InvertError(
                f"indenter {i + 1} at ({v[0]:.2f}, {v[1]:.2f}) mm needs a load at or beyond "
                f"the library's range: {v[2]:.3g} N with a tangential load of {ratio:.2f} of it "
                f"(the library goes to {lib.max_ratio:g}, up to {lib.max_load_N:g} N); build "
                "a library with larger --shear-ratio or --load-N"
            )
    if total > MAX_RESIDUAL:
        raise InvertError(
            f"the library cannot explain this image: the fit leaves an RMS residual of "
            f"{total:.2f} of the fringe amplitude over the whole image (at most "
            f"{MAX_RESIDUAL} is accepted); check the sensor, the pixel size, the origin and "
            "the method"
        )
