"""Regions of interest and anchors of ``fringekit analyze`` from its options."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from fringekit.analysis import (
    border_anchor,
    circle_mask,
    exclude_circle,
    find_disc,
    load_image,
    polygon_mask,
)
from fringekit.errors import InputError
from fringekit.output.figures import NO_DATA_IMAGE_LEVEL

__all__ = [
    "NO_DATA_MIN_PX",
    "DISC_ROI_SHARE",
    "ORDER_AT_RADIUS_PX",
    "data_region",
    "disc_region",
    "mask_file",
    "no_data_regions",
    "order_anchors",
    "order_at_anchor",
    "region_mask",
]


#: A region filled with the no-data level in every channel, at least this many pixels,
#: is no data (the contact discs of ``predict``'s images; a real photograph's noise does
#: not hold 12 pixels at one level in every channel).
NO_DATA_MIN_PX = 12


def no_data_regions(data: np.ndarray) -> np.ndarray:
    """(rows, cols) bool: where an image (rows, cols[, channels]) in [0, 1] holds the
    no-data level of fringekit's own images in every channel, in connected regions of at
    least :data:`NO_DATA_MIN_PX` pixels (``predict`` fills its contact zones so).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.random.default_rng(0).uniform(0, 1, (32, 32))
    >>> img[10:16, 10:16] = 0.5  # a 36-pixel disc of predict's fill
    >>> int(no_data_regions(img).sum())
    36
    """
    stack = np.asarray(data, float)
    stack = stack.reshape(*stack.shape[:2], -1)
    hit = np.all(np.abs(stack - NO_DATA_IMAGE_LEVEL) < 0.6 / 255, axis=-1)
    lab, n = ndimage.label(hit)
    if not n:
        return hit
    sizes = ndimage.sum(hit, lab, np.arange(1, n + 1))
    return np.concatenate([[False], sizes >= NO_DATA_MIN_PX])[lab]


def data_region(data: np.ndarray, mask_args) -> tuple[np.ndarray, int]:
    """The region of interest of the options ``mask_args`` (:func:`region_mask`) without
    the no-data regions of the image ``data`` (rows, cols[, channels])
    (:func:`no_data_regions`), and how many pixels those hold.

    Examples
    --------
    >>> img = np.random.default_rng(0).uniform(0, 1, (32, 32))
    >>> img[10:16, 10:16] = 0.5
    >>> mask, no_data = data_region(img, (None, []))
    >>> int(mask.sum()), no_data
    (988, 36)
    """
    nodata = no_data_regions(data)
    return region_mask(np.shape(data), *mask_args) & ~nodata, int(nodata.sum())


def mask_file(path, shape) -> np.ndarray:
    """(rows, cols) bool: the pixels a mask image (``--mask``, as ``predict``'s
    ``mask.png``: data where it is bright, above half scale) marks as data."""
    frame = load_image(path)
    data = frame.data if frame.data.ndim == 2 else frame.data.mean(-1)
    if data.shape != tuple(shape[:2]):
        raise InputError(
            f"--mask {path}: {data.shape[0]} x {data.shape[1]} px; allowed: the image's size, "
            f"{shape[0]} x {shape[1]} px"
        )
    return data > 0.5


def region_mask(
    shape, roi_circle, exclude, roi_polygon=None, exclude_polygons=(), mask_path=None
) -> np.ndarray:
    """The region of interest (circle and/or polygon; default the whole image) without
    the excluded circles and polygons (cracks, labels, load points) and outside the mask
    image's data (``--mask``); errors name the option when nothing is left."""
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
    if mask_path is not None:
        mask &= mask_file(mask_path, shape)
    if not mask.any():
        raise InputError(
            "the region of interest holds no pixel (--roi-circle, --roi-rect or --roi-polygon "
            "minus --exclude-circle, --exclude-polygon and --mask); allowed: a region inside the "
            f"{shape[0]} x {shape[1]} image"
        )
    return mask


#: Radius (px) of the anchor disc about ``--order-at ROW COL N``.
ORDER_AT_RADIUS_PX = 3.0


def order_at_anchor(shape, valid, order_at, valid_is: str = "in the region of interest"):
    """(anchor mask, anchor orders (rows, cols), NaN off the anchors) from ``--order-at``
    points (row, col, order), each checked; (None, None) without any. ``valid_is`` says
    in the error what makes a pixel valid for the method."""
    if not order_at:
        return None, None
    anchor = np.zeros(shape[:2], bool)
    orders = np.full(shape[:2], np.nan)
    for r, c, n in order_at:
        disc = circle_mask(shape, (r, c), ORDER_AT_RADIUS_PX)
        if not (disc & valid).any():
            raise InputError(
                f"--order-at {r:g} {c:g} {n:g}: no valid pixel within {ORDER_AT_RADIUS_PX:g} px "
                f"of ({r:g}, {c:g}); allowed: a point inside the image with fringe data "
                f"({valid_is})"
            )
        anchor |= disc & valid
        orders[disc & valid] = n
    return anchor, orders


def order_anchors(
    shape, valid, order_at, anchor_order: float, valid_is: str = "in the region of interest"
):
    """The anchors of the count or the unwrap: the ``--order-at`` points when given (mask,
    orders map NaN off them), else the valid pixels on the image border at
    ``--anchor-order`` (mask, that order); an error naming the options when there are
    none. ``valid_is`` as :func:`order_at_anchor`."""
    anchor, orders = order_at_anchor(shape, valid, order_at, valid_is)
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
