"""Candidates moved onto their indenters' axes by matching one-indenter images.

:func:`fringekit.inversion.detect.detect` finds where fringes crowd (the peaks of the
image's gradient energy). That is near an indenter, not on its axis: the energy peaks
where the pattern is steepest, which a sheared indenter, a neighbour's fringes or the
image's border move. On the track bench's first frame (four sheared 3.5 mm heads of
2-3 N, 256 px over 16 mm) its candidates were 0.2-2.2 mm from the axes, with a fifth
between two heads, and the quick start fitted two heads into wrong minima from there.

Here the library's own one-indenter images (MATCH_LOADS normal loads x MATCH_RATIOS in
MATCH_DIRECTIONS directions, and no tangential load) are matched to the image by
normalised cross-correlation, restricted to the usable pixels under the template (the
masked form of Padfield, "Masked object registration in the Fourier domain", IEEE Trans.
Image Processing 21(5), 2012, so that a template reaching over the border or over a
no-data disc is judged on the pixels it has), and ranked by Fisher's z times the root of
those pixels' count. Each candidate moves to the best match within MATCH_WITHIN_MM of
it, and candidates that land within a sphere diameter of a better one are one. On the
frame above: four candidates within 0.04-0.16 mm of the axes and a fifth, 4 mm from any,
that the fit drops. The match alone is no detector: in empty regions a neighbour's far
fringes match a light template as well as a head matches its own (z 42-48, the heads
21-77), so it only refines what the energy found.

It serves the tracker's first frame (:func:`fringekit.inversion.quick.quick_start`),
whose answer is kept only where it explains the frame to the camera's noise, and
``invert``'s last retry (:func:`fringekit.inversion.fit.invert_image`), taken only when
an indenter is still flagged, which also matches the residual's peaks beyond a sphere
diameter of every fitted axis (``taken``): two heads that detection gave one candidate
leave their residual peak between them, 2 mm from the fitted one, inside detection's
exclusion. It is not ``invert``'s first start: on a frame of the tests' tiny library (a
1 mm mesh, 2 and 4 N) it moved a 2.5 N contact's candidate 0.6 mm off, and the contact
came back 0.3 mm off with a residual of 0.10, under the warning level that FEM images
need, so no retry would have mended it.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import irfft2, next_fast_len, rfft2

from fringekit.inversion.detect import axis_separation_mm, far_from
from fringekit.inversion.hop import retarder_lookup
from fringekit.inversion.model import ImageModel
from fringekit.library.lattice import interpolate_turned

__all__ = [
    "MATCH_CHUNK",
    "MATCH_DIRECTIONS",
    "MATCH_HALF_MM",
    "MATCH_LOADS",
    "MATCH_RATIOS",
    "MATCH_WITHIN_MM",
    "masked_ncc",
    "match_candidates",
    "one_indenter_templates",
]

#: Normal loads of the templates, spaced evenly in log from half the library's first
#: load to its largest: a dark-field ring pattern between two library loads is out of
#: phase with both (on the tiny test library's 2 and 4 N, a 3 N contact matched best
#: 1.9 mm off its axis).
MATCH_LOADS = 10
#: Templates correlated at once (each holds a few spectra of the image's size).
MATCH_CHUNK = 16
#: Half-width of the templates (mm): the fringes within about twice a contact radius.
MATCH_HALF_MM = 2.5
#: Tangential load ratios (of the normal load) of the templates, beyond zero.
MATCH_RATIOS = (0.2, 0.4)
#: Directions of the sheared templates.
MATCH_DIRECTIONS = 8
#: A candidate moves to the best match at most this far (mm).
MATCH_WITHIN_MM = 2.5
#: A shift counts only where the usable pixels cover this share of the template.
MIN_OVERLAP = 0.5


def one_indenter_templates(model: ImageModel, half_mm: float = MATCH_HALF_MM) -> np.ndarray:
    """The library's one-indenter images about the axis, on ``model``'s pixel pitch.

    Parameters
    ----------
    model : ImageModel
        Its library, pixel pitch and polariscope (its pixels are not used).
    half_mm : float
        The templates' half-width (mm).

    Returns
    -------
    (K, h, h, C) float array
        Intensities before gain and offset, one equivalent retarder per ray; h =
        2 round(half_mm / pitch) + 1, rows downwards (y falls), columns along x. For
        every diameter of the library: MATCH_LOADS normal loads from half the library's
        first load to its largest, without tangential load and at MATCH_RATIOS in
        MATCH_DIRECTIONS directions.

    Examples
    --------
    See :func:`match_candidates`, which correlates them with an image, and
    ``tests/test_match.py``.
    """
    lib = model.lib
    px = model.grid.pixel_size
    h = int(round(half_mm * 1e-3 / px))
    o = np.arange(-h, h + 1) * px
    dx, dy = np.meshgrid(o, -o)
    dx, dy = dx.ravel()[None], dy.ravel()[None]
    psi = np.linspace(0.0, 2 * np.pi, MATCH_DIRECTIONS, endpoint=False)
    tots = []
    for d in lib.diameters_mm:  # one or a few
        for fz in np.geomspace(0.5 * lib.load_N[1], lib.max_load_N, MATCH_LOADS):
            for ratio in (0.0, *MATCH_RATIOS):
                if ratio > lib.max_ratio + 1e-9:
                    continue
                AB = lib.state(d, float(fz), float(ratio))[0].sum(axis=2, keepdims=True)
                dirs = psi if ratio > 0 else psi[:1]
                tots.append(interpolate_turned(AB, lib.lattice, dx, dy, dirs[:, None])[..., 0, :])
    sub = model.restrict(np.zeros(dx.size, int))  # the polariscope's table only
    lin, _ = retarder_lookup(sub, np.concatenate(tots))
    size = 2 * h + 1
    return lin.reshape(-1, size, size, lin.shape[-1])


def masked_ncc(image: np.ndarray, valid: np.ndarray, templates: np.ndarray):
    """Normalised cross-correlation of templates at every shift, over valid pixels only.

    Parameters
    ----------
    image : (H, W) float array
    valid : (H, W) bool array
        The pixels that count (the others neither add to the sums nor to the count).
    templates : (K, h, w) or (h, w) float array, h and w odd
        Centred: shift (i, j) puts a template's centre on pixel (i, j).

    Returns
    -------
    ncc : (K, H, W) or (H, W) float array
        At each pixel, the Pearson correlation between a template and the valid image
        pixels under it (Padfield 2012, eq. 11-12, with the template fully valid), by
        FFT; NaN where fewer than MIN_OVERLAP of the template's pixels are valid or
        either side is constant.
    count : (H, W) float array
        The valid pixels under a template there (0 where ``ncc`` is NaN).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> img = rng.normal(size=(32, 32))
    >>> c, n = masked_ncc(img, np.ones((32, 32), bool), img[10:17, 20:27])
    >>> np.unravel_index(np.nanargmax(c), c.shape), round(float(np.nanmax(c)), 6)
    ((np.int64(13), np.int64(23)), 1.0)
    """
    one = np.ndim(templates) == 2
    t = np.asarray(templates, float).reshape(-1, *np.shape(templates)[-2:])[:, ::-1, ::-1]
    (H, W), (h, w) = image.shape, t.shape[1:]
    shape = (next_fast_len(H + h - 1, True), next_fast_len(W + w - 1, True))
    crop = (..., slice(h // 2, h // 2 + H), slice(w // 2, w // 2 + W))

    def conv(fa, fb):  # "same" linear convolution from two spectra
        return irfft2(fa * fb, shape)[crop]

    m = valid.astype(float)
    f = np.where(valid, image, 0.0)
    fm, ff, fff = rfft2(m, shape), rfft2(f, shape), rfft2(f * f, shape)
    box = rfft2(np.ones((h, w)), shape)
    n, s_f, s_ff = conv(fm, box), conv(ff, box), conv(fff, box)
    ft, ftt = rfft2(t, shape), rfft2(t * t, shape)
    s_t, s_tt, s_ft = conv(fm, ft), conv(fm, ftt), conv(ff, ft)
    with np.errstate(invalid="ignore", divide="ignore"):
        nn = np.maximum(n, 1.0)
        var_f = s_ff - s_f**2 / nn
        var_t = s_tt - s_t**2 / nn
        tiny = 1e-9 * max(float(np.abs(s_ff).max()), 1e-300)
        ok = (n >= MIN_OVERLAP * h * w - 0.5) & (var_f > tiny) & (var_t > 0)
        den = np.sqrt(np.where(ok, var_f * var_t, 1.0))
        ncc = np.where(ok, (s_ft - s_f * s_t / nn) / den, np.nan)
    count = np.where(ok.any(axis=0), np.rint(n), 0.0)
    return (ncc[0] if one else ncc), count


def _significance(img: np.ndarray, valid: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """The best over ``templates`` (K, h, w, C) of Fisher's z of the channels' mean masked
    correlation times the square root of the pixels it rests on (H, W): how far a match
    stands above chance, so that a shift at the border, on part of a template, must
    correlate better to win."""
    best = np.full(img.shape[:2], -np.inf)
    for k in range(0, len(templates), MATCH_CHUNK):  # bounded memory: K spectra at once
        chunk = templates[k : k + MATCH_CHUNK]
        c, n = zip(
            *(masked_ncc(img[..., ch], valid, chunk[..., ch]) for ch in range(img.shape[-1])),
            strict=True,
        )
        r = np.clip(np.mean(c, axis=0), -0.999, 0.999)
        z = np.arctanh(r) * np.sqrt(np.maximum(n[0] - 3.0, 0.0))
        best = np.fmax(best, np.nanmax(np.where(np.isnan(z), -np.inf, z), axis=0))
    return best


def match_candidates(model: ImageModel, cand: np.ndarray, taken=()) -> np.ndarray:
    """Candidates moved to the best one-indenter match near each.

    Parameters
    ----------
    model : ImageModel
        The image (every pixel of its grid; :func:`fringekit.inversion.fit.subsample`
        for a coarser pitch).
    cand : (k, 2) float array
        Candidate axes (mm), :func:`fringekit.inversion.detect.detect`'s.
    taken : (m, 2) array_like, optional
        Axes already fitted (mm): no candidate moves to within a sphere diameter of one
        (a residual's peak beside a fitted contact is looked for beyond it).

    Returns
    -------
    (k', 2) float array
        The moved candidates (mm), best match first; a candidate on an unusable pixel (a
        no-data disc, which marks its contact) or with no valid match within
        MATCH_WITHIN_MM stays where it was (and is dropped if that is within a sphere
        diameter, at least MIN_SEPARATION_MM, of a taken axis), and one that lands closer
        than a sphere diameter to a better-matched one is dropped: two axes cannot be
        closer.

    Examples
    --------
    See ``tests/test_match.py``: a candidate 1.5 mm off a library-synthesised indenter
    moves onto its axis.
    """
    cand = np.reshape(np.asarray(cand, float), (-1, 2))
    if not len(cand):
        return cand
    rows, cols = model.grid.shape
    img = model.measured.reshape(rows, cols, -1)
    valid = model.usable.reshape(rows, cols)
    templates = one_indenter_templates(model)
    best = _significance(img, valid, templates)
    xy = model.xy.reshape(rows, cols, 2) * 1e3
    apart_mm = axis_separation_mm(model.lib)
    taken = np.reshape(np.asarray(taken, float), (-1, 2))
    free = np.ones((rows, cols), bool)
    for tx, ty in taken:  # a handful
        free &= np.hypot(xy[..., 0] - tx, xy[..., 1] - ty) >= apart_mm
    moved, score = [], []
    r, c = model.grid.xy_to_pixel(cand[:, 0] * 1e-3, cand[:, 1] * 1e-3)
    r = np.clip(np.rint(r).astype(int), 0, rows - 1)
    c = np.clip(np.rint(c).astype(int), 0, cols - 1)
    for (x, y), on_hole in zip(cand, ~valid[r, c], strict=True):  # a handful
        if on_hole:  # a no-data disc's centre: the disc marks its contact
            moved.append(np.array([x, y]))
            score.append(np.inf)
            continue
        near = np.hypot(xy[..., 0] - x, xy[..., 1] - y) <= MATCH_WITHIN_MM
        s = np.where(near & free & np.isfinite(best), best, -np.inf)
        k = np.unravel_index(int(np.argmax(s)), s.shape)
        moved.append(xy[k] if np.isfinite(s[k]) else np.array([x, y]))
        score.append(s[k])
    far = [len(far_from(m, taken, apart_mm)) == 1 for m in moved]
    kept: list[int] = []
    for i in np.argsort(score)[::-1]:
        if not far[i]:
            continue
        if all(np.hypot(*(moved[i] - moved[j])) >= apart_mm for j in kept):
            kept.append(int(i))
    return np.reshape([moved[i] for i in kept], (-1, 2))
