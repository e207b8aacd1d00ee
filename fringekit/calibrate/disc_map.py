"""The material fringe value from a diametral disc in compression (Frocht's field).

A disc of diameter D and thickness t under a diametral load P has a closed-form stress
field (M. M. Frocht, *Photoelasticity*, Vol. 2, Wiley 1948; see ``docs/theory.md``,
"Reference formulas"); in transmission its fringe order is N = t (sigma1 - sigma2) /
f_sigma. Fitting that field to a measured order map gives f_sigma. The field comes from
:class:`optics.DiametralDisc`, so this fit belongs to the application layer.
"""

from __future__ import annotations

import numpy as np

from fringekit.errors import InputError
from fringekit.optics import DiametralDisc

__all__ = ["disc_outline", "fringe_value_from_disc", "WARN_RESIDUAL", "REFUSE_RESIDUAL"]

#: RMS residual of the fit, relative to the RMS measured order, above which the result
#: carries a warning, and above which the map is refused as not a disc. A rendered disc
#: fits to 1e-4; an indenter map (fitted as a disc) leaves 0.84 fringe.
WARN_RESIDUAL = 0.05
REFUSE_RESIDUAL = 0.25


def disc_outline(valid: np.ndarray, pixel_size: float, diameter: float) -> tuple[float, float]:
    """Centre (row, col) px of a disc map from the outline of its data region.

    The region with data (finite order) must be the disc: its equivalent diameter
    2 sqrt(A / pi) within 10 % of ``diameter`` (m) and 95 % of the circle of that diameter
    about its centroid covered. A photograph analysed without a region of interest has
    data everywhere; it is refused rather than fitted about the image centre.
    """
    n = int(valid.sum())
    d_eq = 2 * np.sqrt(n / np.pi) * pixel_size
    rows, cols = np.nonzero(valid)
    centre = (float(rows.mean()), float(cols.mean())) if n else (0.0, 0.0)
    rr, cc = np.mgrid[: valid.shape[0], : valid.shape[1]]
    circle = np.hypot(rr - centre[0], cc - centre[1]) * pixel_size <= d_eq / 2
    covered = float(valid[circle].mean()) if circle.any() else 0.0
    if not n or abs(d_eq / diameter - 1) > 0.1 or covered < 0.95:
        raise InputError(
            f"--centre is missing and the map's data region ({n} pixels, equivalent diameter "
            f"{d_eq * 1e3:.3g} mm, {100 * covered:.0f} % round) does not outline a "
            f"{diameter * 1e3:.3g} mm disc; give --centre ROW COL, the disc centre in pixels "
            "(or analyze with --roi-circle on the disc)"
        )
    return centre


def fringe_value_from_disc(
    order: np.ndarray,
    pixel_size: float,
    centre_rc: tuple[float, float],
    *,
    load_N: float,
    diameter: float,
    thickness: float,
    r_max: float = 0.45,
) -> dict:
    """Fringe value f_sigma (N/m per fringe) of a diametral disc at a known load.

    Least squares over the pixels within ``r_max`` D of the centre (away from the load
    points) of N = t (sigma1 - sigma2)(x, y) / f_sigma (transmission, Frocht's field);
    the load axis is the image's vertical. Also returns the centre-only estimate
    8 P / (pi D N_centre) (docs/theory.md).
    """
    order = np.asarray(order, float)
    for name, v in (
        ("load_N", load_N),
        ("diameter", diameter),
        ("thickness", thickness),
        ("pixel_size", pixel_size),
    ):
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"{name} = {v!r} is not allowed; must be > 0")
    rows, cols = order.shape
    r, c = np.mgrid[:rows, :cols]
    xy = np.stack([(c - centre_rc[1]) * pixel_size, -(r - centre_rc[0]) * pixel_size], -1)
    disc = DiametralDisc(P=load_N, D=diameter, t=thickness)
    inside = np.hypot(xy[..., 0], xy[..., 1]) <= r_max * diameter
    use = inside & np.isfinite(order)
    if use.sum() < 10:
        raise InputError(
            "fewer than 10 measured pixels inside the disc: check the centre, pixel size "
            "and diameter"
        )
    S = thickness * disc.stress_difference(xy[use])  # N/m: N = S / f_sigma
    Nm = order[use]
    inv_f = float((S * Nm).sum() / (S * S).sum())
    f = 1.0 / inv_f
    resid = Nm - S * inv_f
    rms = float(np.sqrt(np.mean(resid**2)))
    rel = rms / max(float(np.sqrt(np.mean(Nm**2))), 1e-12)
    if rel > REFUSE_RESIDUAL or not f > 0:
        raise InputError(
            f"the map does not look like a diametral disc at {load_N:g} N: Frocht's field "
            f"leaves an RMS residual of {rms:.3g} fringe ({100 * rel:.0f} % of the measured "
            "order); check the centre, the pixel size, the diameter and that the image is a disc"
        )
    rc, cc = int(round(centre_rc[0])), int(round(centre_rc[1]))
    n_c = order[rc, cc] if 0 <= rc < rows and 0 <= cc < cols else np.nan
    out = {
        "f_sigma_N_per_m": f,
        "rms_residual_fringe": rms,
        "relative_residual": rel,
        "pixels": int(use.sum()),
        "f_sigma_centre_N_per_m": float(8 * load_N / (np.pi * diameter * n_c))
        if np.isfinite(n_c) and n_c > 0
        else None,
    }
    if rel > WARN_RESIDUAL:
        out["warning"] = (
            f"Frocht's field leaves an RMS residual of {100 * rel:.0f} % of the measured order: "
            "the fringe value is uncertain by about that much"
        )
    return out
