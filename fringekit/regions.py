"""Regions of interest and anchors of ``fringekit analyze`` from its options."""

from __future__ import annotations

import numpy as np

from analysis import circle_mask, exclude_circle, polygon_mask

__all__ = ["ORDER_AT_RADIUS_PX", "order_at_anchor", "region_mask"]


def region_mask(shape, roi_circle, exclude, roi_polygon=None, exclude_polygons=()) -> np.ndarray:
    """The region of interest (circle and/or polygon; default the whole image) without
    the excluded circles and polygons (cracks, labels, load points); errors name the
    option when nothing is left."""
    mask = np.ones(shape[:2], bool)
    if roi_circle is not None:
        r, c, rad = roi_circle
        mask &= circle_mask(shape, (r, c), rad)
    if roi_polygon is not None:
        mask &= polygon_mask(shape[:2], roi_polygon)
    for r, c, rad in exclude or ():
        mask = exclude_circle(mask, (r, c), rad)
    for poly in exclude_polygons or ():
        mask &= ~polygon_mask(shape[:2], poly)
    if not mask.any():
        raise ValueError(
            "the region of interest holds no pixel (--roi-circle, --roi-rect or --roi-polygon "
            "minus --exclude-circle and --exclude-polygon); allowed: a region inside the "
            f"{shape[0]} x {shape[1]} image"
        )
    return mask


#: Radius (px) of the anchor disc about ``--order-at ROW COL N``.
ORDER_AT_RADIUS_PX = 3.0


def order_at_anchor(shape, valid, order_at):
    """(anchor mask or None, anchor order) from ``--order-at`` (row, col, order), checked."""
    if order_at is None:
        return None, None
    r, c, n = order_at
    anchor = circle_mask(shape, (r, c), ORDER_AT_RADIUS_PX)
    if not (anchor & valid).any():
        raise ValueError(
            f"--order-at {r:g} {c:g} {n:g}: no valid pixel within {ORDER_AT_RADIUS_PX:g} px of "
            f"({r:g}, {c:g}); allowed: a point inside the image with fringe data (not masked, "
            "modulation above --min-modulation)"
        )
    return anchor, n
