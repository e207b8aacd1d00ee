"""The start of ``fringekit invert``: each candidate's load from a scan of one-indenter
images.

For a candidate at (x, y) every library state of START_LOADS normal loads x tangential
ratios every START_RATIO_STEP x START_DIRECTIONS directions (and every diameter) is
synthesised on the candidate's own far-field pixels (:func:`fringekit.inversion.fit._start`
chooses them) with one equivalent retarder per ray, whose intensities come from the
polariscope's table (:class:`fringekit.inversion.hop.RetarderTable`). Each image gets its
own gain and offset in closed form, a positive gain (a negative one would turn the
fringes' dark and bright over and is not a camera's); the least squares picks the start.

A start without tangential load, the earlier rule, put sheared heads at the library's
largest load when the image was the grey one: on the coarse bench's four-head images
synthesised by the library (8-bit with camera noise), three of four starts were at 4 N
for heads of 2.1-3.1 N, and two of three such images were refused.
"""

from __future__ import annotations

import numpy as np

from fringekit.inversion.hop import retarder_lookup
from fringekit.inversion.model import ImageModel, line_fit
from fringekit.library.lattice import interpolate_turned

__all__ = ["START_DIRECTIONS", "START_RATIO_STEP", "projected_cost", "scan_start"]

START_DIRECTIONS = 12
START_RATIO_STEP = 0.2


def projected_cost(lin: np.ndarray, measured: np.ndarray, groups) -> np.ndarray:
    """Least-squares cost (M,) of M model images ``lin`` (M, P, C) against ``measured``
    (P, C), each with its own gain (>= 0) and offset per channel group
    (:func:`fringekit.inversion.model.line_fit`, vectorised over the images). A negative
    best gain counts as gain 0 (the measured variance about its mean)."""
    cost = np.zeros(len(lin))
    for g in groups:  # one, or three colour channels
        cost += line_fit(lin[:, :, g], measured[:, g], True)[2]
    return cost


def scan_start(model: ImageModel, x_mm: float, y_mm: float, pixels: np.ndarray, loads, table=None):
    """The best one-indenter load for a candidate at (``x_mm``, ``y_mm``) on ``pixels``
    (bool (P,) or indices) of ``model``.

    Returns
    -------
    row : (5,) x, y (mm), Fz, Fx, Fy (N)
    diameter : float (m)
    table : the intensity table used (pass it to the next call)
    """
    lib = model.lib
    sub = model.restrict(pixels)
    dx = (sub.xy[:, 0] - x_mm * 1e-3)[None]
    dy = (sub.xy[:, 1] - y_mm * 1e-3)[None]
    psi = np.linspace(0.0, 2 * np.pi, START_DIRECTIONS, endpoint=False)
    ratios = np.arange(0.0, lib.max_ratio + 1e-9, START_RATIO_STEP)
    tots, rows, diams = [], [], []
    for d in lib.diameters_mm:  # one or a few
        for fz in loads:  # each load state vectorised over directions and pixels
            for ratio in ratios:
                AB = lib.state(d, float(fz), float(ratio))[0].sum(axis=2, keepdims=True)
                dirs = psi if ratio > 0 else psi[:1]
                tots.append(interpolate_turned(AB, lib.lattice, dx, dy, dirs[:, None])[..., 0, :])
                ft = ratio * fz
                rows += [[x_mm, y_mm, fz, ft * np.cos(a), ft * np.sin(a)] for a in dirs]
                diams += [d * 1e-3] * len(dirs)
    tots = np.concatenate(tots)
    if sub.residual_ab is not None:  # the candidate alone, in the sheet's residual
        tots = tots + sub.residual_ab[None]
    lin, table = retarder_lookup(sub, tots, table)
    best = int(np.argmin(projected_cost(lin, sub.measured, sub.groups)))
    return np.array(rows[best]), diams[best], table
