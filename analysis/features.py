"""Features of a fringe-order map about an indenter axis, the quantities a load-to-fringe
calibration fits (:mod:`analysis.calibrate`); :func:`fringe_features` gives:

- ``order_at_<r>mm`` - azimuthal mean of the fringe order on the circle of radius r;
- ``radius_mm_fringe_<k>`` - outermost radius (mm) where the azimuthal mean reaches order k
  (k = 1, 2, 3): the radii of the first, second and third dark fringes of a monochrome
  dark-field image;
- ``integrated_order_fringe_mm2`` - the order integrated over the annulus
  ``r_in <= r <= r_out`` (fringe mm^2), inside the contact-free zone at every calibrated load;
- ``centroid_x_mm``, ``centroid_y_mm`` - first moment of the order over that annulus about
  the axis (mm): the shift of the pattern that shear causes (seed paper Fig. 3b).
"""

from __future__ import annotations

import numpy as np

__all__ = ["RADII_MM", "fringe_features", "radial_profile"]

#: Radii (mm) at which the order is sampled; beyond the 8 N contact radius (1.2 mm).
RADII_MM = (1.5, 2.0, 3.0, 4.0, 6.0)


def radial_profile(order, pixel_size, centre_rc):
    """Azimuthal mean of a fringe-order map in 1-pixel annuli about an axis.

    Parameters
    ----------
    order : (rows, cols) float array
        Fringe order, NaN where unknown.
    pixel_size : float
        Pixel pitch (m).
    centre_rc : (row, col)
        The axis (px).

    Returns
    -------
    r_mm : (k,) float array
        Annulus radii (mm).
    mean : (k,) float array
        Azimuthal mean order, NaN where no pixel.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import radial_profile
    >>> r = np.hypot(*np.mgrid[-10:11, -10:11])
    >>> r_mm, mean = radial_profile(2.0 - 0.1 * r, 0.1e-3, (10, 10))
    >>> r_mm[:3].round(3).tolist(), mean[:3].round(3).tolist()
    ([0.0, 0.1, 0.2], [2.0, 1.879, 1.784])
    """
    rows, cols = order.shape
    r, c = np.mgrid[:rows, :cols]
    dist = np.hypot(r - centre_rc[0], c - centre_rc[1])
    ok = np.isfinite(order)
    k = np.round(dist).astype(np.int64)
    n = np.bincount(k[ok], minlength=k.max() + 1)
    s = np.bincount(k[ok], weights=order[ok], minlength=k.max() + 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, s / np.maximum(n, 1), np.nan)
    return np.arange(len(mean)) * pixel_size * 1e3, mean


def fringe_features(
    order: np.ndarray,
    pixel_size: float,
    centre_rc: tuple[float, float],
    *,
    radii_mm=RADII_MM,
    fringes=(1, 2, 3),
    r_in_mm: float = 2.0,
    r_out_mm: float = 6.0,
) -> dict[str, float]:
    """Scalar features of a fringe-order map about an indenter axis (module docstring).

    Parameters
    ----------
    order : (rows, cols) float array
        Fringe order, NaN where unknown (masks, the contact zone).
    pixel_size : float
        Pixel pitch (m).
    centre_rc : (row, col)
        The indenter axis (px).
    radii_mm : sequence of float
        Radii (mm) of the ``order_at_<r>mm`` features.
    fringes : sequence of int
        Orders k of the ``radius_mm_fringe_<k>`` features.
    r_in_mm, r_out_mm : float
        The annulus (mm) of ``integrated_order_fringe_mm2`` and the centroid.

    Returns
    -------
    dict of str -> float
        NaN where a feature is not defined (e.g. a fringe the load does not reach).

    Raises
    ------
    ValueError
        A map that is not 2-D, or a pixel size that is not > 0.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import fringe_features
    >>> r_mm = np.hypot(*np.mgrid[-60:61, -60:61]) * 0.1  # 0.1 mm pixels, axis at (60, 60)
    >>> order = 3.0 * np.exp(-((r_mm / 2.5) ** 2))  # an 8 N-like map, 3 fringes at the axis
    >>> f8 = fringe_features(order, 1e-4, (60, 60))
    >>> round(f8["order_at_2mm"], 3), round(f8["radius_mm_fringe_1"], 3)
    (1.581, 2.615)
    """
    order = np.asarray(order, float)
    if order.ndim != 2:
        raise ValueError(f"fringe order map shape {order.shape} is not allowed; need (rows, cols)")
    if not (pixel_size > 0 and np.isfinite(pixel_size)):
        raise ValueError(f"pixel_size = {pixel_size!r} m is not allowed; must be > 0")
    r_mm, prof = radial_profile(order, pixel_size, centre_rc)
    ok = np.isfinite(prof)
    out: dict[str, float] = {}
    for rr in radii_mm:
        inside = ok & (np.abs(r_mm - rr) <= 1.5 * pixel_size * 1e3)
        out[f"order_at_{rr:g}mm"] = (
            float(np.interp(rr, r_mm[ok], prof[ok])) if inside.any() else float("nan")
        )
    for k in fringes:
        above = ok & (prof >= k)
        if not above.any():
            out[f"radius_mm_fringe_{k}"] = float("nan")
            continue
        i = int(np.flatnonzero(above)[-1])  # the outermost annulus at or above order k
        j = next((m for m in range(i + 1, len(prof)) if ok[m]), None)
        if j is None:
            out[f"radius_mm_fringe_{k}"] = float("nan")  # the fringe runs off the image
            continue
        f = (prof[i] - k) / (prof[i] - prof[j])
        out[f"radius_mm_fringe_{k}"] = float(r_mm[i] + f * (r_mm[j] - r_mm[i]))
    rows, cols = order.shape
    r, c = np.mgrid[:rows, :cols]
    dx = (c - centre_rc[1]) * pixel_size * 1e3
    dy = -(r - centre_rc[0]) * pixel_size * 1e3  # rows grow downwards, y upwards
    dist = np.hypot(dx, dy)
    ring = np.isfinite(order) & (dist >= r_in_mm) & (dist <= r_out_mm)
    # the annulus must be covered (a masked or clipped annulus would bias the integral)
    full = (np.pi * (r_out_mm**2 - r_in_mm**2)) / (pixel_size * 1e3) ** 2
    if ring.sum() < 0.9 * full:
        out["integrated_order_fringe_mm2"] = float("nan")
        out["centroid_x_mm"] = out["centroid_y_mm"] = float("nan")
    else:
        w = np.where(ring, order, 0.0)
        out["integrated_order_fringe_mm2"] = float(w.sum() * (pixel_size * 1e3) ** 2)
        out["centroid_x_mm"] = float((w * dx).sum() / w.sum())
        out["centroid_y_mm"] = float((w * dy).sum() / w.sum())
    return out
