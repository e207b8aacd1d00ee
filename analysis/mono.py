"""Fringe order from ONE monochrome photograph (circular polariscope, dark or bright field).

The classical method of counting fringes (Frocht, *Photoelasticity* Vol. 1, Wiley 1941,
ch. 8; Ramesh, *Digital Photoelasticity*, Springer 2000, ch. 4), made automatic:

1. **Normalise** (:mod:`analysis.envelope`): u = sin^2(pi N) in dark field (the bright
   field is turned into it by u -> 1 - u), from a flat field or the fringe envelope.
2. **Bands**: the image splits at u = 1/2 into dark bands, each around a whole order k
   (|N - k| <= 1/4), and bright bands around a half order (|N - k - 1/2| <= 1/4).
3. **Ordering**: neighbouring bands differ by half a fringe. From the anchor bands (those
   on the border of the region of interest, the far field, or the band of ``--order-at``)
   the bands are numbered by breadth-first search, counting up away from the anchor - the
   rule for fringes that rise towards a load (contact, load point). Bands out of reach of
   the anchor have no order; two touching bands whose numbers do not differ by 1/2 (a
   count that went round a hill both ways) are flagged. One image cannot tell a hill
   from a dip (Ramesh 2000): when a singular zone is in view, a rise that carries the far
   field (bands on the image's frame) more than one band beyond the anchor band goes
   away from it and is flagged, with all counted only through it
   (:func:`_towards_singular`).
4. **Fringe centres and sides**: in each band the centre line (the extreme of u) splits
   the pixels on the side of its lower neighbours from those on the side of its higher
   ones - a watershed of |u - 1/2| seeded on the two boundaries (scikit-image). Within the
   band N = n_band -/+ d with d = asin(sqrt u)/pi (dark bands) or acos(sqrt u)/pi (bright).
5. **Uncertainty**: the intensity noise (Immerkaer's estimate) and the envelope's error
   (its misfit at the fringe centres, growing away from them where it extrapolates)
   propagated through d(u); near a fringe centre d = sqrt(u)/pi to first order, so the
   noise enters as its square root.

A band whose neighbours are all lower (a cap: the top of a hill, or a band cut off by
the region of interest) has no higher boundary to seed: its centre line is the set of
pixels nearest its extreme intensity, and the parts it cuts off from the lower
neighbours lie beyond it. Where the count cannot tell, the pixels are flagged, not
guessed: everything when no half-order fringe centre sets the fringe amplitude (and no
flat field does: the image's own range would stretch orders below 1/2 to a half
fringe); in a cap whose extreme does not cut it (the hill's top may pass the fringe
centre or stop short of it) the pixels within :data:`CAP_AMBIGUOUS` fringe of the band's
centre value are unreliable; so are bands the anchor does not reach, pixels of low
fringe contrast, and pixels whose uncertainty exceeds ``max_sd``.

What a count cannot see: a local *minimum* of the order that is not an anchor (a pit, or
the far end of a disc, where the order falls back to zero) is counted up instead of
down - give an anchor there too; and fringes denser than the pixels (a disc's load
points, a contact edge at low magnification) alias into broad bands that look resolved
and connect bands that are fringes apart - leave them out of the region.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from skimage.segmentation import watershed

from .channels import grey_channel
from .envelope import Envelope, band_labels, band_neighbours, fit_envelope, flat_field_envelope
from .images import image_noise_sd
from .masks import border_anchor, check_mask

__all__ = [
    "CAP_AMBIGUOUS",
    "MonoResult",
    "mono_order",
]

#: In a cap band whose fringe centre was not seen, pixels closer than this (fringe) to
#: the band's centre value may lie beyond it: unreliable.
CAP_AMBIGUOUS = 0.1

#: A cap band's pixels within this (fringe) of its most extreme d hold its centre line.
CAP_EXTREME = 0.1

#: Width (px) of the edge of the region where a cap's side is not trusted.
EDGE_PX = 2

#: The anchor says which field the image is in when both its order and its normalised
#: intensity are this far from the half-way 1/2 (a whole or half order, dark or bright).
FIELD_CLEAR = 0.25

#: Pixels this close (px) to unresolved fringes (:func:`analysis.envelope.unresolved`)
#: are unreliable: loops smaller than a band may have been merged there.
NEAR_DENSE_PX = 3


@dataclass(frozen=True)
class MonoResult:
    """Fringe order of one monochrome image (made by :func:`mono_order`).

    Parameters
    ----------
    order : (rows, cols) float array
        Total fringe order; NaN outside the mask or where unordered.
    order_sd : (rows, cols) float array
        1-sigma uncertainty (fringe).
    reliable : (rows, cols) bool array
        Ordered, unambiguous, contrast and sd within limits.
    normalised : (rows, cols) float array
        u = sin^2(pi N) (dark-field sense).
    band_order : (rows, cols) float array
        The whole or half order of each pixel's band.
    centres : (rows, cols) bool array
        Fringe-centre pixels (dark: whole, bright: half orders).
    envelope : Envelope
        The fringe envelope the image was normalised by.
    info : dict
        Counts and the envelope's figures, for reports; ``field_implied`` is the field
        that the anchor's intensity and order imply (``""`` when the anchor sits between
        a dark and a bright fringe): a whole order is dark in dark field and bright in
        bright field, so a bright anchor at a whole order says the field given is wrong.

    Examples
    --------
    >>> from fringekit.analysis import mono_order
    >>> from fringekit.optics import dark_field_circular, indent_field, intensity
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> dark = intensity(q, dark_field_circular())  # a dark-field image, (48, 48) in [0, 1]
    >>> res = mono_order(dark, mask=mask)
    >>> res.info["bands"], int(res.reliable.sum()), sorted(set(res.band_order[mask].tolist()))
    (5, 2244, [0.5, 1.0, 1.5, 2.0, 2.5])
    """

    order: np.ndarray
    order_sd: np.ndarray
    reliable: np.ndarray
    normalised: np.ndarray
    band_order: np.ndarray
    centres: np.ndarray
    envelope: Envelope
    info: dict = field(default_factory=dict)


#: A band holding at least this share of the anchor pixels is an anchor band (a corner
#: of the far field cut off by the envelope's error holds ~1 %).
ANCHOR_SHARE = 0.005


def _order_bands(labels, is_bright, pairs, anchor_mask, anchor_order):
    """Breadth-first numbering of the bands from the anchor bands (see module doc).

    Every band holding at least :data:`ANCHOR_SHARE` of the anchor pixels starts at the
    whole (dark) or half (bright) order nearest the median ``anchor_order`` of its anchor
    pixels (a scalar, or a map for several anchors), from above - the anchor region spans
    the lowest orders; the count goes up by 1/2 per band away from them.
    Returns (nominal order per label (NaN = unreached), anchor labels (bool per label),
    conflicting labels: a band and a neighbour whose orders do not differ by 1/2, the
    median anchor order of each anchor label (NaN for the others))."""
    n = len(is_bright)
    hits = np.bincount(labels[anchor_mask], minlength=n)
    hits[0] = 0
    if not hits.any():
        raise ValueError("the anchor region lies on no fringe band (all masked)")
    sources = hits >= max(1.0, ANCHOR_SHARE * hits.sum())
    nominal = np.full(n, np.nan)
    ids = np.flatnonzero(sources)
    known = np.broadcast_to(np.asarray(anchor_order, float), labels.shape)
    a0 = np.full(n, np.nan)
    a0[ids] = ndimage.median(known, np.where(anchor_mask, labels, 0), ids)
    nominal[ids] = np.where(is_bright[ids], np.floor(a0[ids]) + 0.5, np.round(a0[ids]))
    adj = [[] for _ in range(n)]
    for a, b in pairs:
        adj[a].append(b)
        adj[b].append(a)
    queue = deque(np.flatnonzero(sources)[np.argsort(nominal[sources], kind="stable")])
    while queue:  # a graph of bands (tens to hundreds), not of pixels
        a = queue.popleft()
        for b in adj[a]:
            if np.isnan(nominal[b]):
                nominal[b] = nominal[a] + 0.5
                queue.append(b)
    conflict = np.zeros(n, bool)
    if len(pairs):
        bad = np.abs(nominal[pairs[:, 0]] - nominal[pairs[:, 1]]) != 0.5
        bad &= np.isfinite(nominal[pairs]).all(axis=1)
        conflict[pairs[bad].ravel()] = True
    return nominal, sources, conflict, a0


def _between(anchor_mask, anchor_order):
    """Envelope band selector: the bands the count from the anchors puts between a lower
    and a higher neighbour (they hold a whole fringe centre)."""

    def select(labels, is_bright, pairs):
        if not (anchor_mask & (labels > 0)).any():
            return np.zeros(len(is_bright), bool)
        nominal, sources, _, a0 = _order_bands(labels, is_bright, pairs, anchor_mask, anchor_order)
        lower = np.zeros(len(is_bright), bool)
        higher = np.zeros(len(is_bright), bool)
        a, b = pairs[:, 0], pairs[:, 1]
        np.logical_or.at(higher, a, nominal[b] > nominal[a])
        np.logical_or.at(lower, a, nominal[b] < nominal[a])
        np.logical_or.at(higher, b, nominal[a] > nominal[b])
        np.logical_or.at(lower, b, nominal[a] < nominal[b])
        # an anchor band holds its centre when its anchors sit clearly below it and the
        # count rises beyond it
        crossing = sources & higher & (nominal - a0 > CAP_EXTREME)
        return (lower & higher & ~sources) | crossing

    return select


def _neighbours(a: np.ndarray, fill):
    """The four 4-neighbour arrays of ``a`` (right, left, down, up), ``fill`` off the edge."""
    out = []
    for axis in (0, 1):
        for step in (1, -1):
            b = np.full_like(a, fill)
            src = [slice(None)] * 2
            dst = [slice(None)] * 2
            src[axis] = slice(step, None) if step > 0 else slice(None, step)
            dst[axis] = slice(None, -step) if step > 0 else slice(-step, None)
            b[tuple(dst)] = a[tuple(src)]
            out.append(b)
    return out


def _cap_sides(band, d_band, lower_band, elevation):
    """Sides in a cap band (no higher neighbour): the pixels within :data:`CAP_EXTREME` of
    the band's most extreme d hold its centre line if they cut the band; parts cut off
    from the lower neighbours lie beyond it and seed the higher side of a watershed as the
    higher neighbours do in other bands. Returns (watershed labels 1 (lower) / 2 (higher)
    in the band's box, whether the centre line was seen)."""
    near = band & (d_band <= np.nanmin(d_band[band]) + CAP_EXTREME)
    parts, _ = ndimage.label(band & ~near)
    touching = np.unique(parts[lower_band & (parts > 0)])
    beyond = (parts > 0) & ~np.isin(parts, touching)
    markers = np.where(lower_band, 1, 0) + np.where(beyond, 2, 0)
    return watershed(elevation, markers, mask=band), bool(beyond.any())


def _sides(u, d, labels, nominal, anchor_mask, start, doubtful):
    """+1 (higher side of the band's centre line), -1 (lower), 0 (unknown) per pixel, the
    fringe-centre pixels, which labels are caps whose centre line was not seen, which are
    caps, and the pixels on the side of a ``doubtful`` higher neighbour (its count is not
    trusted, so neither is the side)."""
    nom = np.where(labels > 0, nominal[labels], np.nan)
    lower = np.zeros(labels.shape, bool)
    higher = np.zeros(labels.shape, bool)
    shaky = np.zeros(labels.shape, bool)
    for nb, nl in zip(_neighbours(nom, np.nan), _neighbours(labels, 0), strict=True):
        lower |= nb < nom
        higher |= nb > nom
        shaky |= (nb > nom) & doubtful[nl]
    lower |= anchor_mask & start[labels]
    has_higher = np.bincount(labels[higher], minlength=len(nominal)) > 0
    blind = np.zeros(len(nominal), bool)
    side = np.zeros(labels.shape, np.int8)
    centres = np.zeros(labels.shape, bool)
    doubt = np.zeros(labels.shape, bool)
    elevation = np.abs(u - 0.5)
    for lab, sl in enumerate(ndimage.find_objects(labels), start=1):
        if sl is None or np.isnan(nominal[lab]):
            continue
        band = labels[sl] == lab
        if not has_higher[lab] and not start[lab]:
            ws, seen = _cap_sides(band, d[sl], lower[sl] & band, elevation[sl])
            blind[lab] = not seen
        else:
            markers = np.where(band & lower[sl], 1, 0) + np.where(band & higher[sl], 2, 0)
            markers[markers == 3] = 0  # a pixel touching both: let the flood decide
            markers[(markers == 2) & shaky[sl]] = 3
            if not markers.any():
                continue
            ws = watershed(elevation[sl], markers, mask=band)
            doubt[sl] |= band & (ws == 3)
        side[sl][band] = np.where(ws[band] >= 2, 1, -1).astype(np.int8)
        if (ws >= 2).any() and nominal[lab] > 0:
            meets = np.zeros(band.shape, bool)
            for nb in _neighbours(ws, 0):
                meets |= nb >= 2
            centres[sl] |= (ws == 1) & meets
    caps = ~has_higher & np.isfinite(nominal)
    caps[0] = False
    caps &= ~start
    return side, centres, blind, caps, doubt


def _towards_singular(labels, mask, nominal, start, pairs):
    """Which bands the count reached by rising towards a singular zone (per label).

    From one image a band counted up from a lower one may as well be one down: a ridge
    of a lower band looks the same from either side (Ramesh 2000, the hill-or-dip
    ambiguity of fringe ordering). Where the image shows a singular zone - fringes denser
    than the pixels (:func:`analysis.envelope.unresolved`) or a hole left out of the
    region (a contact) - the rise is towards it, and the fringes close about it inside
    the picture. The image's frame cuts the far field, away from it: the band next to an
    anchor band is one step from the anchor either way, but a band reached by a second
    step up that still reaches the frame would have the far field climb away from the
    singular zone, where it may as well fall back. Such a band, and all counted only
    through it, is not trusted. Without a singular zone in view every step is trusted
    (the rise is towards the image's edge, as in bending)."""
    frame = np.zeros(mask.shape, bool)
    frame[[0, -1], :] = frame[:, [0, -1]] = True
    out, _ = ndimage.label(~mask)
    holes = ~mask & ~np.isin(out, np.unique(out[frame & ~mask]))
    trusted = start.copy()
    if not ((mask & (labels == 0)).any() or holes.any()) or not len(pairs):
        return trusted | np.isfinite(nominal)
    open_ = np.bincount(labels[frame & mask], minlength=len(nominal)) > 0
    lo, hi = pairs.T
    flip = nominal[lo] > nominal[hi]
    lo, hi = np.where(flip, hi, lo), np.where(flip, lo, hi)
    up = nominal[hi] - nominal[lo] == 0.5
    lo, hi = lo[up], hi[up]
    for level in np.unique(nominal[hi]):  # a loop over the levels of the count
        s = nominal[hi] == level
        ok = trusted[lo[s]] & (~open_[hi[s]] | start[lo[s]])
        np.logical_or.at(trusted, hi[s], ok)
    return trusted


def _pit_or_hill(caps, start, nominal, pairs):
    """Caps whose only neighbours are anchor bands above order 0: the band may be a hill
    (order up by 1/2) or a pit (down by 1/2, an isotropic point of the far field, beside a
    crack tip) - the count cannot tell."""
    other = np.zeros(len(caps), bool)
    a, b = (pairs[:, 0], pairs[:, 1]) if len(pairs) else (np.zeros(0, int),) * 2
    np.logical_or.at(other, a, ~start[b])
    np.logical_or.at(other, b, ~start[a])
    lowest = np.full(len(caps), np.inf)
    np.minimum.at(lowest, a, np.where(start[b], nominal[b], np.inf))
    np.minimum.at(lowest, b, np.where(start[a], nominal[a], np.inf))
    return caps & ~other & np.isfinite(lowest) & (lowest >= 0.5)


def _implied_field(field, u, anchor, anchor_order):
    """The field that the anchor's intensity implies (module doc), its normalised
    intensity (dark-field sense u, median over the anchor) and its median order."""
    known = np.broadcast_to(np.asarray(anchor_order, float), u.shape)[anchor]
    seen = u[anchor]
    if not (np.isfinite(known).any() and np.isfinite(seen).any()):
        return "", float("nan"), float("nan")
    a0, seen = float(np.nanmedian(known)), float(np.nanmedian(seen))
    expect = np.sin(np.pi * a0) ** 2  # dark field, Dally and Riley ch. 6
    if abs(expect - 0.5) < FIELD_CLEAR or abs(seen - 0.5) < FIELD_CLEAR:
        return "", seen, a0  # the anchor sits between a dark and a bright fringe
    other = "bright" if field == "dark" else "dark"
    return (field if (seen > 0.5) == (expect > 0.5) else other), seen, a0


def _smoothed_noise_sd(image: np.ndarray, mask: np.ndarray, smooth_px: float) -> float:
    """Per-pixel noise of the smoothed image: :func:`analysis.images.image_noise_sd` times the
    Gaussian filter's noise gain 1 / (2 sqrt(pi) sigma)."""
    return image_noise_sd(image, mask) / max(2 * np.sqrt(np.pi) * smooth_px, 1.0)


def _order_sd(u, sd_u):
    """sd of d(u) (fringe): first order sd_u / |du/dd|, and sqrt(sd_u)/pi at the extremes
    where u is quadratic in d - whichever is smaller."""
    uu = np.clip(u, 1e-9, 1 - 1e-9)
    first = sd_u / (2 * np.pi * np.sqrt(uu * (1 - uu)))
    return np.minimum(first, np.sqrt(sd_u) / np.pi)


def mono_order(
    image: np.ndarray,
    *,
    mask: np.ndarray | None = None,
    field: str = "dark",
    anchor_mask: np.ndarray | None = None,
    anchor_order: float = 0.0,
    flat: np.ndarray | None = None,
    smooth_px: float = 0.5,
    min_contrast: float = 0.05,
    max_sd: float = 0.1,
    cut_dense: bool = True,
) -> MonoResult:
    """Total fringe order of one monochrome image, by counting fringes (module docstring).

    Parameters
    ----------
    image : (rows, cols) or (rows, cols, 3) float array in [0, 1]
        Dark- or bright-field photograph (a colour one is reduced by
        :func:`grey_channel`).
    mask : (rows, cols) bool array, optional
        Region of interest (default all).
    field : {"dark", "bright"}
        The polariscope's field: whole orders are dark fringes in dark field and bright
        ones in bright field.
    anchor_mask : (rows, cols) bool array, optional
        Pixels of known order ``anchor_order``; default the region's border ring
        (:func:`border_anchor`).
    anchor_order : float or (rows, cols) float array
        The anchors' order (a map for anchors of different orders).
    flat : (rows, cols) float array, optional
        Flat-field image (I_0 of the light); default the fringe envelope.
    smooth_px : float
        Gaussian smoothing before normalising (px).
    min_contrast : float
        Fringe amplitude I_0 (fraction of full scale) below which pixels are unreliable.
    max_sd : float
        Order uncertainty (fringe) above which pixels are unreliable.
    cut_dense : bool
        Cut out fringes denser than the pixels (:func:`analysis.envelope.band_labels`):
        a photograph's blur merges bands there. :func:`count_fringe_order` keeps them (the
        six steps give the folded order without blur, and it counted 2 px bands right on
        a 32 px prediction where the cut left 25 % of the region reliable).

    Returns
    -------
    MonoResult

    Raises
    ------
    ValueError
        An unknown field, a negative smoothing, or masks of another shape.

    Examples
    --------
    >>> from fringekit.analysis import mono_order
    >>> from fringekit.optics import dark_field_circular, indent_field, intensity
    >>> order, q, mask = indent_field(48, 48)  # a known order: 0.3 at the border, 2.9 inside
    >>> dark = intensity(q, dark_field_circular())  # a dark-field image, (48, 48) in [0, 1]
    >>> import numpy as np
    >>> res = mono_order(dark, mask=mask)
    >>> round(float(np.abs(res.order - order)[res.reliable].max()), 2)  # fringe
    0.05
    >>> round(float(np.nanmedian(res.order_sd[res.reliable])), 3)
    0.008
    """
    if field not in ("dark", "bright"):
        raise ValueError(f"field = {field!r} is not allowed; use 'dark' or 'bright'")
    img = np.asarray(image, float)
    mask = check_mask(mask, img.shape)
    img = grey_channel(img, mask)
    mask = mask & np.isfinite(img)
    img = np.where(mask, img, 0.0)
    if not (np.isfinite(smooth_px) and smooth_px >= 0):
        raise ValueError(f"smooth_px = {smooth_px!r} is not allowed; must be >= 0")
    smooth = ndimage.gaussian_filter(img, smooth_px) if smooth_px > 0 else img
    sign_img = smooth if field == "dark" else 1.0 - smooth
    if flat is not None and field == "dark":
        env = flat_field_envelope(flat)
    elif flat is not None:  # bright field: 1 - I / flat is the dark-field u
        sign_img = 1.0 - smooth / np.where(flat > 0, flat, np.nan)
        env = Envelope(np.zeros_like(img), np.ones_like(img), "flat field", sampled=("low", "high"))
    anchor = border_anchor(mask) if anchor_mask is None else check_mask(anchor_mask, img.shape)
    anchor &= mask
    if flat is None:
        env = fit_envelope(sign_img, mask, select=_between(anchor, anchor_order))
    u = np.where(mask, env.normalise(sign_img), np.nan)
    labels, is_bright = band_labels(u, mask, cut_dense=cut_dense)
    pairs = band_neighbours(labels)
    nominal, start, conflict, _ = _order_bands(labels, is_bright, pairs, anchor, anchor_order)
    su = np.sqrt(np.clip(np.nan_to_num(u), 0, 1))
    # d > 1/4 only on islands too small to be bands (merged into their surroundings)
    d = np.minimum(np.where(is_bright[labels], np.arccos(su), np.arcsin(su)) / np.pi, 0.25)
    trusted = _towards_singular(labels, mask, nominal, start, pairs)
    doubtful = np.isfinite(nominal) & ~trusted
    doubtful[0] = False
    side, centres, blind, caps, doubt = _sides(u, d, labels, nominal, anchor, start, doubtful)
    nom = np.where(labels > 0, nominal[labels], np.nan)
    order = np.where(side >= 0, nom + d, nom - d)
    order = np.abs(order)  # the anchor band of order 0 has no lower side: N = d
    order = np.where(mask & (side != 0), order, np.nan)
    amp = env.high - env.low
    sd_u = np.hypot(_smoothed_noise_sd(img, mask, smooth_px) / np.maximum(amp, 1e-6), env.sd())
    sd = np.where(np.isfinite(order), _order_sd(u, sd_u), np.nan)
    # near a fringe centre the side is a coin toss within the noise: the error is up to 2 d
    side_blur = d < np.sqrt(3 * sd_u) / np.pi
    sd = np.where(side_blur, np.maximum(sd, d), sd)
    cap_px = blind[labels] & (labels > 0) & (d < CAP_AMBIGUOUS)
    # where a cap's centre line runs into the edge of the region, the slivers beyond it
    # can reach the lower side along the edge: cap pixels on the edge off the line
    edge = mask & ~ndimage.binary_erosion(mask, iterations=EDGE_PX, border_value=1)
    cap_px |= caps[labels] & (labels > 0) & edge & (d >= CAP_EXTREME / 2)
    # fringes denser than the pixels (a crack tip, a load point) belong to no band; a cap
    # that runs into them may rise beyond what is seen, and next to them tiny loops were
    # merged as noise: neither is counted
    dense = mask & (labels == 0)
    near_dense = ndimage.binary_dilation(dense, iterations=NEAR_DENSE_PX) if dense.any() else dense
    touches = np.bincount(
        labels[ndimage.binary_dilation(dense) & (labels > 0)], minlength=len(caps)
    )
    cap_px |= ((caps & (touches > 0))[labels] & (labels > 0)) | near_dense
    cap_px |= _pit_or_hill(caps, start, nominal, pairs)[labels] & (labels > 0)
    # a pixel clearly on the other side of u = 1/2 than its band: an island merged as noise
    island = ((u > 0.5) != is_bright[labels]) & (np.abs(u - 0.5) > 3 * sd_u)
    reliable = np.isfinite(order) & ~cap_px & ~island & ~conflict[labels]
    reliable &= ~doubtful[labels] & ~doubt
    reliable &= (amp >= min_contrast) & (sd <= max_sd)
    # without a half-order fringe centre (or a flat field) the fringe amplitude is the
    # image's own range: a photo whose orders stay below 1/2 would be stretched to it
    reliable &= "high" in env.sampled
    implied, seen, a0 = _implied_field(field, u, anchor, anchor_order)
    info = {
        "field": field,
        "field_implied": implied,
        "anchor_intensity": seen,
        "anchor_order_median": a0,
        "bands": int(len(is_bright) - 1),
        "ordered_bands": int(np.isfinite(nominal[1:]).sum()),
        "blind_cap_bands": int(np.sum(blind[1:])),
        "anchor_bands": int(start.sum()),
        "conflicting_bands": int(conflict.sum()),
        "bands_rising_away": int(doubtful.sum()),
        "unresolved_px": int(dense.sum()),
        "pit_or_hill_bands": int(_pit_or_hill(caps, start, nominal, pairs).sum()),
        "envelope": env.method,
        "envelope_from_centres": list(env.sampled),
        "envelope_samples": env.samples,
        "envelope_residual": env.residual,
        "sd_u_median": float(np.nanmedian(sd_u[mask])),
    }
    return MonoResult(order, sd, reliable, u, nom, centres & mask, env, info)
