"""Unwrapping the resolved isochromatic phase into a total fringe-order map.

The signed wrapped phase of :func:`analysis.resolve_ambiguity` is unwrapped with
``skimage.restoration.unwrap_phase`` (Herraez et al., Appl. Opt. 41, 2002) on a masked
array. Each connected region carries its own global sign (the ambiguity is resolved up to
one sign per region) and its own integer offset: both are fixed from the region's anchor
pixels (zero order in the far field, or an RGB fringe-order map). The isochromatic order is
a magnitude, so each region takes the sign that puts its pixels above its anchor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from skimage.restoration import unwrap_phase

from .masks import border_anchor, check_mask
from .mono import mono_order
from .phase import TWO_PI, Resolution, SixStep, resolve_ambiguity, wrap

__all__ = ["FringeOrderMap", "count_fringe_order", "unwrap_fringe_order"]


@dataclass(frozen=True)
class FringeOrderMap:
    """Total isochromatic fringe order from phase shifting.

    Made by :func:`unwrap_fringe_order` and :func:`count_fringe_order`.

    Parameters
    ----------
    order : (rows, cols) float array
        Total fringe order; NaN where not valid.
    reliable : (rows, cols) bool array
        Valid, resolved, and no phase step above pi/2 between neighbouring pixels
        (fringes resolved by the pixel pitch).
    isoclinic : (rows, cols) float array
        Principal direction consistent with ``order`` (rad).
    offset : int
        Integer added to the unwrapped phase / 2 pi to meet the anchor, in the largest
        connected region (each region has its own).
    flipped_groups : int
        Groups of bands whose global sign was reversed.
    info : dict
        Counts for reports.

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> from fringekit.analysis import unwrap_fringe_order
    >>> fo = unwrap_fringe_order(result)
    >>> fo.order.shape, bool(fo.reliable.sum() == mask.sum()), fo.info["regions"]
    ((48, 48), True, 1)
    """

    order: np.ndarray
    reliable: np.ndarray
    isoclinic: np.ndarray
    offset: int
    flipped_groups: int
    info: dict = field(default_factory=dict)


def _unwrap(phase: np.ndarray, valid: np.ndarray) -> np.ndarray:
    out = unwrap_phase(np.ma.masked_array(phase, mask=~valid))
    return np.ma.filled(out, np.nan)


def _anchors(valid, anchor_mask, anchor_order, reference_order):
    """(anchor pixels (rows, cols) bool, target order (rows, cols)) from the options."""
    if reference_order is None:
        anchor = (
            border_anchor(valid)
            if anchor_mask is None
            else check_mask(anchor_mask, valid.shape, "anchor_mask") & valid
        )
        if not anchor.any():
            raise ValueError(
                "anchor_mask has no valid pixel: give anchor_mask (pixels of known order) "
                "or reference_order"
            )
        return anchor, np.full(valid.shape, anchor_order)
    ref = np.asarray(reference_order, float)
    if ref.shape != valid.shape:
        raise ValueError(
            f"reference_order shape {ref.shape} does not match the images {valid.shape}"
        )
    anchor = valid & np.isfinite(ref)
    if not anchor.any():
        raise ValueError("reference_order is NaN on every valid pixel")
    return anchor, ref


def _steep(valid: np.ndarray, unw: np.ndarray) -> np.ndarray:
    """Pixels whose neighbours differ by more than a quarter fringe: not resolved by the
    pixel pitch, so unwrapping there is a guess."""
    steep = np.zeros_like(valid)
    for ax in (0, 1):
        jump = np.abs(np.diff(np.where(valid, unw, 0.0), axis=ax)) > 0.25
        both = np.logical_and(
            np.take(valid, range(valid.shape[ax] - 1), axis=ax),
            np.take(valid, range(1, valid.shape[ax]), axis=ax),
        )
        jump &= both
        pad = [(0, 0), (0, 0)]
        pad[ax] = (0, 1)
        steep |= np.pad(jump, pad)
        pad[ax] = (1, 0)
        steep |= np.pad(jump, pad)
    return steep


def unwrap_fringe_order(
    result: SixStep,
    resolution: Resolution | None = None,
    *,
    anchor_mask=None,
    anchor_order: float = 0.0,
    reference_order=None,
) -> FringeOrderMap:
    """Unwrap the resolved isochromatic phase into a total fringe order map.

    Each connected region of valid pixels gets its sign (the order is a magnitude, above
    its anchor) and its integer offset from its own anchor pixels (module docstring).

    Parameters
    ----------
    result : SixStep
    resolution : Resolution, optional
        Computed with defaults (:func:`resolve_ambiguity`) when omitted.
    anchor_mask : (rows, cols) bool array, optional
        Pixels of known order ``anchor_order`` (default: the valid pixels within 5 % of
        the image border, the far field, at order 0; :func:`border_anchor`).
    anchor_order : float
        Order of the anchor pixels.
    reference_order : (rows, cols) float array, optional
        A fringe-order map (e.g. from RGB calibration); when given, the integer offset is
        the median of (reference - unwrapped) rounded, over pixels where both are finite,
        and ``anchor_mask`` is not used.

    Returns
    -------
    FringeOrderMap

    Raises
    ------
    ValueError
        An anchor mask with no valid pixel, or a reference of another shape or NaN on
        every valid pixel.

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> import numpy as np
    >>> from fringekit.analysis import unwrap_fringe_order
    >>> fo = unwrap_fringe_order(result)  # anchored in the far field, order 0.3 there
    >>> float(np.abs(fo.order - order)[fo.reliable].max()) < 1e-9
    True
    """
    res = resolution or resolve_ambiguity(result)
    valid = result.valid
    anchor, target = _anchors(valid, anchor_mask, anchor_order, reference_order)
    phase = res.phase.copy()
    unw = _unwrap(phase, valid) / TWO_PI
    # unwrap_phase treats disconnected regions independently, and each group of pixels
    # (= a connected region) carries its own global sign: both are fixed per group from
    # its own anchor pixels. A group without anchor pixels is reported unreliable.
    lab = np.where(valid, res.group + 1, 0)
    n_lab = int(lab.max())
    ids = np.arange(1, n_lab + 1)
    has_anchor = np.zeros(n_lab + 1, bool)
    has_anchor[np.unique(lab[anchor])] = True
    has_anchor[0] = False

    def group_median(values, where):
        out = np.zeros(n_lab + 1)
        if n_lab:
            out[1:] = ndimage.median(values, np.where(where, lab, 0), ids)
        return np.nan_to_num(out)

    # the isochromatic order is a magnitude: each group takes the sign that puts its
    # pixels above its anchor
    level = group_median(unw, anchor)
    rel = group_median(unw - level[lab], valid)
    flip = (rel < 0) & has_anchor
    flip_pixels = valid & flip[lab]
    flipped = int(flip.sum())
    if flipped:
        phase[flip_pixels] = wrap(-phase[flip_pixels])
        unw = _unwrap(phase, valid) / TWO_PI
    shift = np.round(group_median(target - unw, anchor))
    present, counts = np.unique(lab[valid], return_counts=True)
    offset = int(shift[present[np.argmax(counts)]]) if present.size else 0
    order = np.where(valid, unw + shift[lab], np.nan)
    iso = res.isoclinic.copy()
    iso[flip_pixels] = (iso[flip_pixels] + np.pi) % np.pi - np.pi / 2
    reliable = valid & res.reliable & ~_steep(valid, unw) & has_anchor[lab]
    info = {
        "valid_pixels": int(valid.sum()),
        "reliable_pixels": int(reliable.sum()),
        "conflicts": res.conflicts,
        "flipped_groups": flipped,
        "offset": offset,
        "regions": int(present.size),
        "regions_without_anchor": int((~has_anchor[present]).sum()),
    }
    return FringeOrderMap(order, reliable, iso, offset, flipped, info)


def count_fringe_order(
    result: SixStep, *, anchor_mask=None, anchor_order: float = 0.0
) -> FringeOrderMap:
    """Total fringe order from the six-step data by counting fringes, not following the isoclinic.

    The axis-insensitive phase d in [0, pi] folds the order: cos d = cos 2 pi N, which is
    the normalised intensity u = sin^2(d / 2) of one dark-field image without its noise
    and illumination. :func:`mono_order` counts its bands from the anchor and resolves
    each pixel's side of its fringe centre; the isoclinic then takes the branch that
    agrees with the sign of sin 2 pi N. Unlike :func:`unwrap_fringe_order` this does not
    hinge on the sign relations across fringe contours (sin d ~ 0), which become bands
    many pixels wide, and noise-driven, where the order changes slowly per pixel (far
    fields at camera resolution); it assumes the order rises away from the anchor.

    Parameters
    ----------
    result : SixStep
    anchor_mask : (rows, cols) bool array, optional
        Pixels of known order ``anchor_order``; default the border ring
        (:func:`border_anchor`).
    anchor_order : float
        Order of the anchor pixels.

    Returns
    -------
    FringeOrderMap

    Examples
    --------
    >>> from fringekit.analysis import six_step
    >>> from fringekit.optics import indent_field, intensity, six_step_arrangements
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> images = [intensity(q, a) for a in six_step_arrangements()]
    >>> result = six_step(images, mask=mask)
    >>> import numpy as np
    >>> from fringekit.analysis import count_fringe_order
    >>> fo = count_fringe_order(result)
    >>> round(float(np.abs(fo.order - order)[fo.reliable].max()), 2), fo.info["fold"]
    (0.05, 'count')
    """
    valid = result.valid
    u = np.where(valid, np.sin(0.5 * result.delta_axis_insensitive) ** 2, 0.0)
    mo = mono_order(
        u,
        mask=valid,
        flat=np.ones_like(u),
        smooth_px=0.0,
        anchor_mask=anchor_mask,
        anchor_order=anchor_order,
        cut_dense=False,
    )
    flip = np.sin(TWO_PI * np.nan_to_num(mo.order)) < 0
    iso = np.where(flip, result.isoclinic + np.pi / 2, result.isoclinic)
    iso = (iso + np.pi / 2) % np.pi - np.pi / 2
    reliable = mo.reliable & valid
    info = {
        "valid_pixels": int(valid.sum()),
        "reliable_pixels": int(reliable.sum()),
        "fold": "count",
        **mo.info,
    }
    offset = int(np.floor(np.nanmin(mo.order))) if np.isfinite(mo.order).any() else 0
    return FringeOrderMap(mo.order, reliable, iso, offset, 0, info)
