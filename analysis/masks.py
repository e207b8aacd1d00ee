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
    """Pixels whose centres lie within ``radius`` of ``centre``.

    Parameters
    ----------
    shape : (rows, cols)
        Image shape (a longer shape is cut to its first two entries).
    centre : (row, col)
        Circle centre (px).
    radius : float
        Radius (px), > 0.

    Returns
    -------
    (rows, cols) bool array

    Raises
    ------
    ValueError
        A radius that is not > 0, or an empty shape.

    Examples
    --------
    >>> from fringekit.analysis import circle_mask
    >>> circle_mask((5, 5), (2, 2), 1.5).astype(int).tolist()
    [[0, 0, 0, 0, 0], [0, 1, 1, 1, 0], [0, 1, 1, 1, 0], [0, 1, 1, 1, 0], [0, 0, 0, 0, 0]]
    """
    if not radius > 0:
        raise ValueError(f"circle radius = {radius!r} px is not allowed; must be > 0")
    rows, cols = _check_shape(shape)
    r, c = np.ogrid[:rows, :cols]
    return (r - centre[0]) ** 2 + (c - centre[1]) ** 2 <= radius**2


def exclude_circle(mask: np.ndarray, centre, radius: float) -> np.ndarray:
    """``mask`` with a disc removed (the indenter centre, where fringes are too dense).

    Parameters
    ----------
    mask : (rows, cols) bool array
    centre : (row, col)
        Circle centre (px).
    radius : float
        Radius (px), > 0.

    Returns
    -------
    (rows, cols) bool array

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import exclude_circle
    >>> int(exclude_circle(np.ones((5, 5), bool), (2, 2), 1).sum())  # 25 - 5
    20
    """
    return np.asarray(mask, bool) & ~circle_mask(mask.shape, centre, radius)


def polygon_mask(shape, vertices) -> np.ndarray:
    """Pixels inside a polygon.

    Parameters
    ----------
    shape : (rows, cols)
        Image shape.
    vertices : (k, 2) float array
        Polygon corners in (row, col), k >= 3.

    Returns
    -------
    (rows, cols) bool array

    Raises
    ------
    ValueError
        Fewer than 3 vertices, or vertices not (k, 2).

    Examples
    --------
    >>> from fringekit.analysis import polygon_mask
    >>> polygon_mask((4, 4), [(0, 0), (0, 3), (3, 0)]).astype(int).tolist()
    [[1, 1, 1, 1], [1, 1, 1, 0], [1, 1, 0, 0], [1, 0, 0, 0]]
    """
    v = np.asarray(vertices, float)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
        raise ValueError(f"polygon vertices shape {v.shape} is not allowed; need (k >= 3, 2)")
    return polygon2mask(_check_shape(shape), v)


def check_mask(mask, shape, name: str = "mask") -> np.ndarray:
    """A boolean mask of the image ``shape`` (None = all True).

    Parameters
    ----------
    mask : (rows, cols) array or None
    shape : tuple
        The image's shape; its first two entries count.
    name : str
        Name used in error messages.

    Returns
    -------
    (rows, cols) bool array

    Raises
    ------
    ValueError
        A mask of another shape, or one that selects no pixel.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import check_mask
    >>> check_mask(None, (2, 3, 3)).tolist()  # a colour image's shape: its pixels
    [[True, True, True], [True, True, True]]
    >>> check_mask(np.eye(2), (2, 2)).dtype.name
    'bool'
    """
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
    """The valid pixels within 5 % of the image size from its border (the far field).

    The default anchor of the fringe count and of unwrapping: where the order is known,
    0 for a sensor whose border is unloaded.

    Parameters
    ----------
    valid : (rows, cols) bool array

    Returns
    -------
    (rows, cols) bool array

    Examples
    --------
    A ring 2 pixels wide in a 40 x 40 image:

    >>> import numpy as np
    >>> from fringekit.analysis import border_anchor
    >>> int(border_anchor(np.ones((40, 40), bool)).sum())  # 40^2 - 36^2
    304
    """
    rows, cols = valid.shape
    m = max(1, int(round(0.05 * min(rows, cols))))
    ring = np.ones_like(valid)
    ring[m:-m, m:-m] = False
    return valid & ring
