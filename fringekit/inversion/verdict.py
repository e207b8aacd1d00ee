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
    """An image the library cannot explain is refused, not returned. The tangential ratio
    is named first: a fit held at the library's largest ratio makes up the missing
    tangential fringes with normal load, so a ratio out of range also drives the normal
    load to the library's edge."""
    for i, v in enumerate(q):
        where = f"indenter {i + 1} at ({v[0]:.2f}, {v[1]:.2f}) mm"
        at_load = v[2] >= AT_LARGEST * lib.max_load_N
        ratio = np.hypot(v[3], v[4]) / max(v[2], 1e-12)
        if ratio >= AT_LARGEST * lib.max_ratio:  # the fit is held at the largest ratio
            also = (
                f"; its normal load, pushed to the library's largest ({lib.max_load_N:g} N) "
                "to make up the missing tangential fringes, is not to be trusted either"
                if at_load
                else ""
            )
            raise InvertError(
                f"{where} needs a tangential load ratio (tangential / normal) beyond the "
                f"library's largest, {lib.max_ratio:g} (the fit stops there, at {v[2]:.3g} N "
                f"normal){also}; build a library with larger --shear-ratio, or with larger "
                "--load-N if the image may hold more normal load than the library's largest, "
                f"{lib.max_load_N:g} N (the fit reads the extra fringes as tangential load)"
            )
        if at_load:
            raise InvertError(
                f"{where} needs a normal load at or beyond the library's largest, "
                f"{lib.max_load_N:g} N; build a library with larger --load-N"
            )
    if not np.isfinite(total) or total > MAX_RESIDUAL:
        left = (
            f"leaves an RMS residual of {total:.2f} of the fringe amplitude over the whole image"
            if np.isfinite(total)
            else "leaves a residual that is not a number"
        )
        raise InvertError(
            f"the library cannot explain this image: the fit {left} (at most {MAX_RESIDUAL} "
            "is accepted); check the sensor, --pixel-mm, --origin-px and --method, and that "
            f"the loads are within the library's range (normal loads up to {lib.max_load_N:g} "
            "N; build a library with larger --load-N for more)"
        )
