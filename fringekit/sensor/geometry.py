"""Where the sheet lies in the image: its pixel pitch, origin and rotation from the
contacts' fitted image positions and their known positions on the sheet.

The image's axes are x to the right, y up (mm about the pixel grid's origin, as
:class:`~fringekit.optics.PixelGrid`); a point q on the sheet (mm) lies at image pixel
(col, -row) = R(rho) q / pitch + (col_0, -row_0). With two or more known positions the
similarity transform is the least-squares one (S. Umeyama, "Least-squares estimation of
transformation parameters between two point patterns", IEEE TPAMI 13, 1991; through
:class:`skimage.transform.SimilarityTransform`); with one, the pitch is the nominal one
and the rotation that of the tangential loads (or none); with none, the nominal geometry
stands.

The 1-sigma follow from the position scatter sigma (px: the transform's RMS residual
with three or more points, and at least the fitted positions' own 1-sigma) over the
known positions' spread S (px, RMS distance from their centroid, times sqrt(n)): pitch
and rotation (rad) sigma / S relative, origin sigma / sqrt(n) (isotropic errors,
Umeyama's estimator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from skimage.transform import SimilarityTransform

__all__ = ["Geometry", "MIN_SPREAD_MM", "sheet_geometry"]

#: Known positions closer together than this (RMS about their centroid, mm) give the
#: origin only: their pitch and rotation would rest on the contacts' fitted positions'
#: own errors.
MIN_SPREAD_MM = 1.0


@dataclass(frozen=True)
class Geometry:
    """Pixel pitch (mm), origin pixel (row, col), rotation (deg), their 1-sigma and the
    number of known positions they came from."""

    pixel_mm: float
    origin_px: tuple
    rotation_deg: float
    sd: dict
    n_known: int


def _pixels(xy_mm: np.ndarray, pixel_mm: float, origin_px) -> np.ndarray:
    """(n, 2) image positions (mm about the origin) as (col, -row) in pixels."""
    r0, c0 = origin_px
    return np.column_stack([c0 + xy_mm[:, 0] / pixel_mm, -r0 + xy_mm[:, 1] / pixel_mm])


def sheet_geometry(
    image_mm: np.ndarray,
    image_sd_mm: np.ndarray,
    sheet_mm: np.ndarray,
    pixel_mm: float,
    origin_px,
    rotation_deg: float = 0.0,
    rotation_sd_deg: float = math.nan,
) -> Geometry:
    """The sheet's geometry in the image (module docstring).

    Parameters
    ----------
    image_mm : (n, 2) the contacts' fitted positions in the image's axes (mm about
        ``origin_px`` at ``pixel_mm``)
    image_sd_mm : (n, 2) their 1-sigma
    sheet_mm : (n, 2) their known positions on the sheet (NaN rows: not known)
    pixel_mm, origin_px : the nominal pitch (mm) and origin pixel (row, col)
    rotation_deg, rotation_sd_deg : the rotation the tangential loads gave (deg), used
        when fewer than two positions are known

    Examples
    --------
    Three contacts seen 2 degrees turned, 0.4 mm off and at a 1 % finer pitch:

    >>> q = np.array([[-4.0, 0.0], [4.0, 1.0], [0.0, -5.0]])
    >>> t = np.radians(2.0)
    >>> R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    >>> img = (q @ R.T + [0.4, 0.0]) / 0.99
    >>> g = sheet_geometry(img, np.full((3, 2), 1e-3), q, 0.1, (50.0, 50.0))
    >>> round(g.pixel_mm, 6), round(g.rotation_deg, 6), [round(v, 4) for v in g.origin_px]
    (0.099, 2.0, [50.0, 54.0404])
    """
    known = np.all(np.isfinite(sheet_mm), axis=1)
    n = int(known.sum())
    dst = _pixels(np.asarray(image_mm, float), pixel_mm, origin_px)
    pos_sd = float(np.max(image_sd_mm[known])) / pixel_mm if n else 0.0
    q = np.asarray(sheet_mm, float)[known]
    spread_mm = math.sqrt(float(np.sum((q - q.mean(0)) ** 2))) if n else 0.0
    if n >= 2 and spread_mm < MIN_SPREAD_MM:  # one place, several times: its mean
        dst_mean = dst[known].mean(0)
        known = np.zeros(len(known), bool)
        known[np.flatnonzero(np.all(np.isfinite(sheet_mm), axis=1))[0]] = True
        dst[known] = dst_mean
        q, n = q.mean(0, keepdims=True), 1
        sheet_mm = np.where(known[:, None], q[0], np.nan)
    if n >= 2:
        tf = SimilarityTransform.from_estimate(q, dst[known])
        resid = tf(q) - dst[known]
        scatter = math.sqrt(float(np.sum(resid**2)) / max(2 * n - 4, 1)) if n > 2 else 0.0
        sigma = max(scatter, pos_sd)
        spread = math.sqrt(float(np.sum((q - q.mean(0)) ** 2))) / (1.0 / tf.scale)
        pitch = float(1.0 / tf.scale)
        rot = math.degrees(float(tf.rotation))
        t = tf.translation
        sd = {
            "pixel_mm": pitch * sigma / spread,
            "rotation_deg": math.degrees(sigma / spread),
            "origin_px": sigma / math.sqrt(n),
        }
        return Geometry(pitch, (float(-t[1]), float(t[0])), rot, sd, n)
    rot = rotation_deg if math.isfinite(rotation_deg) else 0.0
    if n == 1:
        r = math.radians(rot)
        q = np.asarray(sheet_mm, float)[known][0]
        turned = np.array(
            [math.cos(r) * q[0] - math.sin(r) * q[1], math.sin(r) * q[0] + math.cos(r) * q[1]]
        )
        t = dst[known][0] - turned / pixel_mm
        sd = {"pixel_mm": 0.0, "rotation_deg": rotation_sd_deg, "origin_px": pos_sd}
        return Geometry(pixel_mm, (float(-t[1]), float(t[0])), rot, sd, n)
    sd = {"pixel_mm": 0.0, "rotation_deg": rotation_sd_deg, "origin_px": 0.0}
    return Geometry(pixel_mm, tuple(float(v) for v in origin_px), rot, sd, 0)
