"""Regions of interest and anchors of ``fringekit analyze`` from its options."""

from __future__ import annotations

import numpy as np

from fringekit.analysis import (
    border_anchor,
    circle_mask,
    exclude_circle,
    find_disc,
    load_image,
    polygon_mask,
)
from fringekit.errors import InputError

__all__ = [
    "DISC_ROI_SHARE",
    "ORDER_AT_RADIUS_PX",
    "disc_region",
    "order_anchors",
    "order_at_anchor",
    "region_mask",
]


def region_mask(shape, roi_circle, exclude, roi_polygon=None, exclude_polygons=()) -> np.ndarray:
    """The region of interest (circle and/or polygon; default the whole image) without
    the excluded circles and polygons (cracks, labels, load points); errors name the
    option when nothing is left."""
    rows, cols = shape[:2]
    named = [("--roi-circle", roi_circle)] if roi_circle is not None else []
    for name, (r, c, rad) in named + [("--exclude-circle", e) for e in exclude or ()]:
        # the distance from the circle's centre to the image's nearest pixel
        dr, dc = max(0.0, -r, r - (rows - 1)), max(0.0, -c, c - (cols - 1))
        if np.hypot(dr, dc) >= rad:
            raise InputError(
                f"{name} {r:g} {c:g} {rad:g} lies outside the {rows} x {cols} image; allowed: "
                f"a circle that covers pixels of rows 0..{rows - 1} and columns 0..{cols - 1}"
            )
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
        raise InputError(
            "the region of interest holds no pixel (--roi-circle, --roi-rect or --roi-polygon "
            "minus --exclude-circle and --exclude-polygon); allowed: a region inside the "
            f"{shape[0]} x {shape[1]} image"
        )
    return mask


#: Radius (px) of the anchor disc about ``--order-at ROW COL N``.
ORDER_AT_RADIUS_PX = 3.0


def order_at_anchor(shape, valid, order_at):
    """(anchor mask, anchor orders (rows, cols), NaN off the anchors) from ``--order-at``
    points (row, col, order), each checked; (None, None) without any."""
    if not order_at:
        return None, None
    anchor = np.zeros(shape[:2], bool)
    orders = np.full(shape[:2], np.nan)
    for r, c, n in order_at:
        disc = circle_mask(shape, (r, c), ORDER_AT_RADIUS_PX)
        if not (disc & valid).any():
            raise InputError(
                f"--order-at {r:g} {c:g} {n:g}: no valid pixel within {ORDER_AT_RADIUS_PX:g} px "
                f"of ({r:g}, {c:g}); allowed: a point inside the image with fringe data (not "
                "masked, modulation above --min-modulation)"
            )
        anchor |= disc & valid
        orders[disc & valid] = n
    return anchor, orders


def order_anchors(shape, valid, order_at, anchor_order: float):
    """The anchors of the count or the unwrap: the ``--order-at`` points when given (mask,
    orders map NaN off them), else the valid pixels on the image border at
    ``--anchor-order`` (mask, that order); an error naming the options when there are
    none."""
    anchor, orders = order_at_anchor(shape, valid, order_at)
    if anchor is not None:
        return anchor, orders
    anchor = border_anchor(valid)
    if not anchor.any():
        raise InputError(
            "no pixel with fringe data in the region of interest lies on the image border, "
            f"where --anchor-order ({anchor_order:g}) applies; give --order-at ROW COL N, a "
            "pixel of known order"
        )
    return anchor, anchor_order


#: Share of the found disc's radius kept as the region of interest (the rim's pixels mix
#: disc and background).
DISC_ROI_SHARE = 0.97


def disc_region(image_path, diameter_m: float, dark=None) -> dict:
    """``--roi-disc``: the circular specimen in the first image (:func:`analysis.find_disc`:
    its outline, or else the symmetry of its fringes). Returns ``roi_circle`` (row, col, radius px),
    ``pixel_size`` (m, from the known diameter), ``origin_px`` (its centre) and ``info``."""
    try:
        c, how = find_disc(load_image(image_path, dark=dark).data)
    except ValueError:
        raise InputError(
            f"--roi-disc: no circular specimen found in {image_path}; give --roi-circle "
            "ROW COL R and --pixel-mm"
        ) from None
    return {
        "roi_circle": (c.row, c.col, DISC_ROI_SHARE * c.radius),
        "pixel_size": diameter_m / (2 * c.radius),
        "origin_px": (c.row, c.col),
        "info": {
            "centre_px": [c.row, c.col],
            "radius_px": c.radius,
            "found_from": how,
            "support": c.support,
        },
    }
