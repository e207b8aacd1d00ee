"""Line profiles and prediction-vs-measurement comparison of fringe-order maps."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import binary_erosion, map_coordinates
from scipy.optimize import least_squares
from skimage.registration import phase_cross_correlation

__all__ = ["Profile", "line_profile", "circle_profile", "Comparison", "compare_maps"]


@dataclass(frozen=True)
class Profile:
    """Values along a straight line (the seed paper's a-b and c-d lines).

    Made by :func:`line_profile`.

    Parameters
    ----------
    distance : (k,) float array
        Distance from the start, px (or m when a pixel size was given).
    values : (k,) float array
        Bilinear samples; NaN where the line crosses masked (NaN) pixels.
    start, end : (row, col)
        Pixel coordinates of the line's ends.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import line_profile
    >>> p = line_profile(np.arange(16.0).reshape(4, 4), (0, 0), (0, 3))
    >>> p.distance.tolist(), p.values.tolist(), p.end
    ([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 3.0], (0.0, 3.0))
    """

    distance: np.ndarray
    values: np.ndarray
    start: tuple[float, float]
    end: tuple[float, float]


def _read_bilinear(img: np.ndarray, rc) -> np.ndarray:
    """``img`` read bilinearly at (rows, cols) coordinates ``rc``: NaN where a NaN pixel
    is among the four read, or outside the image."""
    nan = ~np.isfinite(img)
    vals = map_coordinates(np.where(nan, 0.0, img), rc, order=1, cval=np.nan)
    vals[map_coordinates(nan.astype(float), rc, order=1, cval=1.0) > 0] = np.nan
    return vals


def line_profile(image, start, end, *, pixel_size: float | None = None, n=None) -> Profile:
    """Sample a map along the line ``start`` -> ``end`` (row, col), one sample per pixel.

    NaN pixels (masks) stay NaN in the profile instead of being blended with their
    neighbours.

    Parameters
    ----------
    image : (rows, cols) float array
        A map (fringe order, stress), NaN where unknown.
    start, end : (row, col)
        Line ends (px), inside the image.
    pixel_size : float, optional
        Pixel pitch (m); distances are then in m, else in px.
    n : int, optional
        Samples (default one per pixel of length, at least 2).

    Returns
    -------
    Profile

    Raises
    ------
    ValueError
        A map that is not 2-D, or an end outside the image.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import line_profile
    >>> order = np.tile(np.linspace(0.0, 2.0, 9), (3, 1))
    >>> order[1, 4] = np.nan  # a masked pixel
    >>> p = line_profile(order, (1, 0), (1, 8), pixel_size=0.1e-3)
    >>> p.values.tolist()
    [0.0, 0.25, 0.5, 0.75, nan, 1.25, 1.5, 1.75, 2.0]
    >>> round(float(p.distance[-1]) * 1e3, 3)  # mm
    0.8
    """
    img = np.asarray(image, float)
    if img.ndim != 2:
        raise ValueError(f"line_profile needs a (rows, cols) map, got shape {img.shape}")
    p0, p1 = np.asarray(start, float), np.asarray(end, float)
    for name, p in (("start", p0), ("end", p1)):
        if p.shape != (2,) or not (0 <= p[0] <= img.shape[0] - 1 and 0 <= p[1] <= img.shape[1] - 1):
            raise ValueError(f"profile {name} = {tuple(p)} is outside the image {img.shape}")
    length = float(np.hypot(*(p1 - p0)))
    k = int(n) if n is not None else max(int(np.ceil(length)) + 1, 2)
    s = np.linspace(0.0, 1.0, k)
    rc = p0[:, None] + (p1 - p0)[:, None] * s
    vals = _read_bilinear(img, rc)
    dist = s * length * (pixel_size if pixel_size else 1.0)
    return Profile(dist, vals, (float(p0[0]), float(p0[1])), (float(p1[0]), float(p1[1])))


def circle_profile(image, centre_rc, radius, *, pixel_size=None, n=720):
    """A map read bilinearly on a circle about a point, at ``n`` equal angles.

    The spread of the values over the angle on a circle about an axisymmetric load is the
    faceting of its fringes (zero on a perfect model; ``bench/rings.py``).

    Parameters
    ----------
    image : (rows, cols) float array
        The map (fringe order, intensity), NaN where unknown.
    centre_rc : (row, col)
        The circle's centre (px; fractional allowed).
    radius : float
        The circle's radius: in pixels, or in the unit of ``pixel_size`` when given.
    pixel_size : float, optional
        Pixel pitch (the unit of ``radius``, e.g. mm per px).
    n : int
        Angles, from the +col direction counter-clockwise as seen with rows running
        down (default 720: every 0.5 deg).

    Returns
    -------
    theta : (n,) float array
        The angles (rad).
    values : (n,) float array
        The map at each angle; NaN where a masked pixel is among the four read.

    Raises
    ------
    ValueError
        A map that is not 2-D, a radius that is not > 0, fewer than 3 angles, or a circle
        that leaves the image.

    Examples
    --------
    A cone of fringe order 2 - r (r in mm, 0.1 mm pixels) reads 1.5 all round at 0.5 mm,
    less the bilinear reading's 0.002 between the pixels at 45 deg:

    >>> import numpy as np
    >>> from fringekit.analysis import circle_profile
    >>> r_mm = 0.1 * np.hypot(*np.mgrid[-20:21, -20:21])
    >>> theta, v = circle_profile(2.0 - r_mm, (20, 20), 0.5, pixel_size=0.1, n=8)
    >>> np.degrees(theta)[:3].tolist(), v.round(3).tolist()
    ([0.0, 45.0, 90.0], [1.5, 1.498, 1.5, 1.498, 1.5, 1.498, 1.5, 1.498])
    """
    img = np.asarray(image, float)
    if img.ndim != 2:
        raise ValueError(f"circle_profile needs a (rows, cols) map, got shape {img.shape}")
    r_px = float(radius) / (pixel_size if pixel_size else 1.0)
    if not (np.isfinite(r_px) and r_px > 0):
        raise ValueError(f"circle_profile radius = {radius!r} is not allowed; it must be > 0")
    if int(n) < 3:
        raise ValueError(f"circle_profile n = {n!r} is not allowed; give at least 3 angles")
    row, col = (float(v) for v in centre_rc)
    if not (r_px <= row <= img.shape[0] - 1 - r_px and r_px <= col <= img.shape[1] - 1 - r_px):
        raise ValueError(
            f"the circle of radius {r_px:.4g} px about {(row, col)} leaves the image {img.shape}"
        )
    theta = np.linspace(0.0, 2.0 * np.pi, int(n), endpoint=False)
    rc = np.array([row - r_px * np.sin(theta), col + r_px * np.cos(theta)])
    return theta, _read_bilinear(img, rc)


@dataclass(frozen=True)
class Comparison:
    """A predicted fringe-order map registered onto a measured one (by :func:`compare_maps`).

    Parameters
    ----------
    predicted : (rows, cols) float array
        The prediction resampled on the measured grid.
    measured : (rows, cols) float array
    residual : (rows, cols) float array
        measured - predicted (NaN where either is missing or outside the mask).
    rms, p95 : float
        RMS and 95th percentile of |residual| (fringe orders).
    centre_measured : (row, col)
        Where the prediction's centre landed (px).
    scale : float
        Measured pixel size / predicted pixel size.
    rotation_deg : float
        Rotation applied to the prediction (degrees).
    info : dict
        ``pixels`` compared, and the registration's RMS when the centre was fitted.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import compare_maps
    >>> r = np.hypot(*np.mgrid[-20:21, -20:21])
    >>> pred = 2.0 * np.exp(-((r / 8) ** 2))
    >>> c = compare_maps(pred, pred + 0.01, predicted_pixel_size=1e-4, measured_pixel_size=1e-4)
    >>> round(c.rms, 4), round(c.p95, 4), c.centre_measured, c.info["pixels"]
    (0.01, 0.01, (20.0, 20.0), 1681)
    """

    predicted: np.ndarray
    measured: np.ndarray
    residual: np.ndarray
    rms: float
    p95: float
    centre_measured: tuple[float, float]
    scale: float
    rotation_deg: float
    info: dict = field(default_factory=dict)


def _resample(pred, centre_pred, shape, centre_meas, scale, rot):
    r, c = np.mgrid[: shape[0], : shape[1]].astype(float)
    dr, dc = r - centre_meas[0], c - centre_meas[1]
    cs, sn = np.cos(rot), np.sin(rot)
    pr = centre_pred[0] + scale * (cs * dr - sn * dc)
    pc = centre_pred[1] + scale * (sn * dr + cs * dc)
    return _read_bilinear(pred, [pr, pc])


def _register(pred, meas, cp, cm, scale, rot, res_pred):
    """The measured centre that best overlays the prediction: masked normalised
    cross-correlation for the whole-pixel shift (Padfield, IEEE Trans. Image Process. 21,
    2012; ``skimage.registration.phase_cross_correlation`` with masks - the two maps'
    holes differ, and filling them biased the plain correlation by 3.5 px on a one-photo
    map), then least squares of the residual over the sub-pixel shift on the pixels both
    maps hold (eroded by 2 px so that the set stays valid). Returns (centre, RMS)."""
    a_ok, b_ok = np.isfinite(meas), np.isfinite(res_pred)
    a = np.where(a_ok, meas, 0.0)
    b = np.where(b_ok, res_pred, 0.0)
    shift = phase_cross_correlation(a, b, reference_mask=a_ok, moving_mask=b_ok)[0]
    start = (cm[0] + shift[0], cm[1] + shift[1])
    both = a_ok & np.isfinite(_resample(pred, cp, meas.shape, start, scale, rot))
    both = binary_erosion(both, iterations=2)
    if both.sum() < 10:
        return start, float("nan")

    def resid(d):
        v = _resample(pred, cp, meas.shape, (start[0] + d[0], start[1] + d[1]), scale, rot)
        return np.nan_to_num(meas[both] - v[both])

    sol = least_squares(
        resid, [0.0, 0.0], bounds=([-1.5, -1.5], [1.5, 1.5]), loss="soft_l1", f_scale=0.1
    )
    centre = (start[0] + float(sol.x[0]), start[1] + float(sol.x[1]))
    return centre, float(np.sqrt(np.mean(sol.fun**2)))


def compare_maps(
    predicted,
    measured,
    *,
    predicted_pixel_size: float,
    measured_pixel_size: float,
    centre_predicted=None,
    centre_measured=None,
    rotation_deg: float = 0.0,
    mask=None,
) -> Comparison:
    """Register ``predicted`` onto ``measured`` and compute residual statistics.

    Parameters
    ----------
    predicted, measured : (rows, cols) float arrays
        Fringe-order maps, NaN where unknown.
    predicted_pixel_size, measured_pixel_size : float
        Pixel pitches (m).
    centre_predicted : (row, col), optional
        The indenter centre in the prediction (default: the image centre).
    centre_measured : (row, col), optional
        The indenter centre in the measurement; when omitted it is fitted (masked
        cross-correlation, then least squares to a fraction of a pixel) after scaling and
        rotating the prediction.
    rotation_deg : float
        Rotation of the prediction about its centre (degrees).
    mask : (rows, cols) bool array, optional
        Pixels of the measurement to compare.

    Returns
    -------
    Comparison

    Raises
    ------
    ValueError
        Maps that are not 2-D, pixel sizes that are not > 0, a mask of another shape, or
        no pixel in common.

    Examples
    --------
    A measurement at twice the resolution whose indenter sits 3 px right of the centre:

    >>> import numpy as np
    >>> from fringekit.analysis import compare_maps
    >>> def indent(shape, centre, px_mm):
    ...     r, c = np.mgrid[: shape[0], : shape[1]]
    ...     r_mm = np.hypot(r - centre[0], c - centre[1]) * px_mm
    ...     return 2.0 * np.exp(-((r_mm / 1.5) ** 2))
    >>> pred = indent((41, 41), (20, 20), 0.1)
    >>> meas = indent((81, 81), (40, 43), 0.05)
    >>> c = compare_maps(pred, meas, predicted_pixel_size=1e-4, measured_pixel_size=5e-5)
    >>> [round(v, 1) for v in c.centre_measured], c.scale, c.rms < 0.01
    ([40.0, 43.0], 0.5, True)
    """
    pred = np.asarray(predicted, float)
    meas = np.asarray(measured, float)
    if pred.ndim != 2 or meas.ndim != 2:
        raise ValueError(
            f"the fringe-order maps to compare have {pred.ndim} and {meas.ndim} dimensions; "
            "allowed: two (rows, cols) maps"
        )
    for name, v in (
        ("predicted_pixel_size", predicted_pixel_size),
        ("measured_pixel_size", measured_pixel_size),
    ):
        if not (v and v > 0 and np.isfinite(v)):
            raise ValueError(f"{name} = {v!r} m is not allowed; must be > 0")
    scale = measured_pixel_size / predicted_pixel_size
    cp = (
        ((pred.shape[0] - 1) / 2, (pred.shape[1] - 1) / 2)
        if centre_predicted is None
        else tuple(centre_predicted)
    )
    rot = np.radians(rotation_deg)
    fitted = centre_measured is None
    cm = ((meas.shape[0] - 1) / 2, (meas.shape[1] - 1) / 2) if fitted else tuple(centre_measured)
    res_pred = _resample(pred, cp, meas.shape, cm, scale, rot)
    info = {}
    if fitted:
        cm, rms = _register(pred, meas, cp, cm, scale, rot, res_pred)
        res_pred = _resample(pred, cp, meas.shape, cm, scale, rot)
        info["registration_rms_fringe"] = rms
    m = np.isfinite(meas) & np.isfinite(res_pred)
    if mask is not None:
        mk = np.asarray(mask, bool)
        if mk.shape != meas.shape:
            raise ValueError(f"mask shape {mk.shape} does not match the measurement {meas.shape}")
        m &= mk
    if not m.any():
        raise ValueError("the registered prediction and the measurement share no pixel")
    resid = np.where(m, meas - res_pred, np.nan)
    a = np.abs(resid[m])
    return Comparison(
        predicted=res_pred,
        measured=meas,
        residual=resid,
        rms=float(np.sqrt(np.mean(a**2))),
        p95=float(np.percentile(a, 95)),
        centre_measured=(float(cm[0]), float(cm[1])),
        scale=float(scale),
        rotation_deg=float(rotation_deg),
        info={**info, "pixels": int(m.sum())},
    )
