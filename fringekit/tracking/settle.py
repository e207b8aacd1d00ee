"""A contact found in a later frame of a stream, settled on its axis.

The basin search (:func:`fringekit.inversion.hop.hop`) scans loads at a fixed axis, so a
touch detected off its axis can be fitted there with a tangential load it does not bear.
:func:`settle_new` searches the axes about such a contact when its fit leaves it far
worse explained than its neighbours. A stream's first frame is the quick start's
(:func:`fringekit.inversion.quick.quick_start`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fringekit.inversion.hop import hop_to
from fringekit.inversion.model import N_PARAMS, ImageModel, unpack
from fringekit.inversion.quick import near_residual, penalised_residual

__all__ = ["MISFIT_TIMES", "RING_MM", "RING_POINTS", "settle_new"]

#: A contact found in a redetection whose residual is this many times the held contacts'
#: (at least 3 noise sd) has the axes about it searched (:func:`settle_new`) ...
MISFIT_TIMES = 5.0
#: ... from RING_POINTS axes on each of these circles about it (mm).
RING_MM = (0.5, 1.0)
RING_POINTS = 8


def settle_new(model: ImageModel, p: np.ndarray, diam: list, n_held: int, noise: float) -> int:
    """Search the axes about each new contact (indices from ``n_held`` of ``p``, which is
    changed in place) whose residual stays MISFIT_TIMES above the held contacts' (their
    median, at least 3 ``noise`` sd's share): local fits from RING_MM rings about it
    (:func:`~fringekit.inversion.hop.hop_to`). The basin search scans loads at a fixed
    axis, and a touch detected 0.9 mm off its axis was fitted there with a tangential
    load it did not bear (residual 0.15 against 0.004 of its neighbours, under the
    warning level: taken as reliable). Returns how many moved.

    Examples
    --------
    No new contact, nothing searched:

    >>> settle_new(None, np.zeros(5), [3.5e-3], 1, 0.01)
    0
    """
    if n_held == 0 or len(diam) == n_held:
        return 0
    fixed = replace(model, keep=model.outside_contacts(unpack(p, diam)))
    r, gains, _ = penalised_residual(fixed, p, diam, noise)  # one synthesis
    rms = near_residual(fixed, p, r, gains)
    amp = float(np.mean(np.abs(gains))) or 1.0
    level = MISFIT_TIMES * max(float(np.median(rms[:n_held])), 3 * noise / amp)
    moved = 0
    angles = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    for k in range(n_held, len(diam)):  # the new contacts of one frame: one or two
        if not rms[k] > level:
            continue
        axis = p.reshape(-1, N_PARAMS)[k, :2]
        ring = [axis + d * np.array([np.cos(a), np.sin(a)]) for d in RING_MM for a in angles]
        q, changed = hop_to(model, p, diam, noise, k, ring)
        p[:], moved = q, moved + changed
    return moved
