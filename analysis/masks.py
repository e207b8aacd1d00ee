"""Regions of interest as boolean masks (True = use the pixel).

Pixel coordinates are (row, col) with row 0 at the top, as in scikit-image.
"""

from __future__ import annotations

import numpy as np
from skimage.draw import polygon2mask

__all__ = ["border_anchor", "circle_mask", "polygon_mask", "exclude_circle", "check_mask"]


def _check_shape(shape) -> tuple[int, int]:
    shape = tuple(int(s) for s in shape[:2])
    if len(shape) != 2 or min(shape) < 1:
        raise ValueError(f"image shape {shape} is not allowed; need (rows, cols) >= 1")
    return shape


def circle_mask(shape, centre, radius: float) -> np.ndarray:
    """Pixels whose centres lie within ``radius`` (px) of ``centre`` (row, col)."""
    if not radius > 0:
        raise ValueError(f"circle radius = {radius!r} px is not allowed; must be > 0")
    rows, cols = _check_shape(shape)
    r, c = np.ogrid[:rows, :cols]
    return (r - centre[0]) ** 2 + (c - centre[1]) ** 2 <= radius**2


def exclude_circle(mask: np.ndarray, centre, radius: float) -> np.ndarray:
    """``mask`` with a disc removed (the indenter centre, where fringes are too dense)."""
    return np.asarray(mask, bool) & ~circle_mask(mask.shape, centre, radius)


def polygon_mask(shape, vertices) -> np.ndarray:
    """Pixels inside the polygon with ``vertices`` (k, 2) in (row, col), k >= 3."""
    v = np.asarray(vertices, float)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
        raise ValueError(f"polygon vertices shape {v.shape} is not allowed; need (k >= 3, 2)")
    return polygon2mask(_check_shape(shape), v)


def check_mask(mask, shape, name: str = "mask") -> np.ndarray:
    """A boolean mask of the image ``shape`` (None = all True)."""
    if mask is None:
        return np.ones(shape[:2], bool)
    m = np.asarray(mask)
    if m.shape != tuple(shape[:2]):
        raise ValueError(f"{name} shape {m.shape} does not match the image shape {shape[:2]}")
    m = m.astype(bool)
    if not m.any():
        raise ValueError(f"{name} selects no pixel")
    return m


def border_anchor(valid: np.ndarray) -> np.ndarray:
    """The valid pixels within 5 % of the image size from its border (the far field)."""
    rows, cols = valid.shape
    m = max(1, int(round(0.05 * min(rows, cols))))
    ring = np.ones_like(valid)
    ring[m:-m, m:-m] = False
    return valid & ring
