"""Line profiles and prediction-vs-measurement comparison of fringe-order maps."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import binary_erosion, map_coordinates
from scipy.optimize import least_squares
from skimage.registration import phase_cross_correlation

__all__ = ["Profile", "line_profile", "Comparison", "compare_maps"]


@dataclass(frozen=True)
class Profile:
    """Values along a straight line (the seed paper's a-b and c-d lines).

    Attributes
    ----------
    distance : (k,) from the start, px (or m when a pixel size was given)
    values : (k,) bilinear samples; NaN where the line crosses masked (NaN) pixels
    start, end : (row, col) pixel coordinates
    """

    distance: np.ndarray
    values: np.ndarray
    start: tuple[float, float]
    end: tuple[float, float]


def line_profile(image, start, end, *, pixel_size: float | None = None, n=None) -> Profile:
    """Sample a map along the line ``start`` -> ``end`` (row, col), one sample per pixel.

    NaN pixels (masks) stay NaN in the profile instead of being blended with their
    neighbours.
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
    nan = ~np.isfinite(img)
    vals = map_coordinates(np.where(nan, 0.0, img), rc, order=1)
    near_nan = map_coordinates(nan.astype(float), rc, order=1) > 0
    vals[near_nan] = np.nan
    dist = s * length * (pixel_size if pixel_size else 1.0)
    return Profile(dist, vals, tuple(p0), tuple(p1))


@dataclass(frozen=True)
class Comparison:
    """A predicted fringe-order map registered onto a measured one.

    Attributes
    ----------
    predicted : (rows, cols) the prediction resampled on the measured grid
    measured : (rows, cols)
    residual : measured - predicted (NaN where either is missing or outside the mask)
    rms, p95 : RMS and 95th percentile of |residual| (fringe orders)
    centre_measured : (row, col) where the prediction's centre landed
    scale : measured pixel size / predicted pixel size
    rotation_deg : rotation applied to the prediction
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
    nan = ~np.isfinite(pred)
    v = map_coordinates(np.where(nan, 0.0, pred), [pr, pc], order=1, cval=np.nan)
    bad = map_coordinates(nan.astype(float), [pr, pc], order=1, cval=1.0) > 0
    v[bad] = np.nan
    return v


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
    predicted, measured : (rows, cols) fringe-order maps, NaN where unknown
    predicted_pixel_size, measured_pixel_size : float (m)
    centre_predicted : (row, col), optional — the indenter centre in the prediction
        (default: the image centre)
    centre_measured : (row, col), optional — the indenter centre in the measurement;
        when omitted it is fitted (masked cross-correlation, then least squares to a
        fraction of a pixel) after scaling and rotating the prediction
    rotation_deg : float — rotation of the prediction about its centre
    mask : (rows, cols) bool, optional — pixels of the measurement to compare
    """
    pred = np.asarray(predicted, float)
    meas = np.asarray(measured, float)
    if pred.ndim != 2 or meas.ndim != 2:
        raise ValueError("compare_maps needs two (rows, cols) fringe-order maps")
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
