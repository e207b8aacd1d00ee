"""The six-step (phase) and colour (RGB) methods of ``fringekit analyze``: images and
options in, (order, reliable, extra maps, summary part, region mask) out."""

from __future__ import annotations

import colour
import numpy as np

from fringekit.analysis import (
    MIN_COLOUR_SPREAD,
    CalibrationTable,
    border_anchor,
    colour_spread,
    count_fringe_order,
    load_image,
    load_six_step,
    resolve_ambiguity,
    search,
    search_adapted,
    six_step,
    subtract_reference,
    unwrap_fringe_order,
)
from fringekit.errors import InputError
from fringekit.measurement.regions import data_region, order_anchors, order_at_anchor
from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source

__all__ = [
    "MAX_FOLD_DISAGREEMENT",
    "MAX_SEED_MISFIT",
    "analyse_phase",
    "analyse_rgb",
    "default_colour_table",
]


def _table(colour_table, chart: dict | None) -> CalibrationTable:
    if colour_table is not None:
        return CalibrationTable.from_csv(colour_table)
    return default_colour_table(**(chart or {}))


def default_colour_table(
    light: str = "LED", camera: str = "CIE1931", max_order: float = 7.0, exposure: float = 0.9
) -> CalibrationTable:
    """The colour table ``analyze --method rgb`` searches without ``--colour-table``.

    The optics' colour chart of PSM-4 (:func:`fringekit.optics.colour_chart`) in the light
    and camera named, on the wavelength grid ``predict`` renders white light on, 0.002
    fringe per row, scaled by the camera's exposure and, for the CIE observer (fringekit's
    PNGs, most cameras' JPEGs), sRGB-encoded: the colours an image carries.

    Parameters
    ----------
    light : str
        Light source (:func:`fringekit.optics.light_source`).
    camera : str
        Camera sensitivities (:class:`fringekit.optics.Camera`).
    max_order : float
        Highest fringe order of the table.
    exposure : float
        Fraction of full scale of a white pixel.

    Returns
    -------
    CalibrationTable

    Examples
    --------
    >>> from fringekit.measurement.methods import default_colour_table
    >>> t = default_colour_table(max_order=4.0)
    >>> len(t), float(t.orders[-1]), t.rgb[0].round(3).tolist()
    (2001, 4.0, [0.0, 0.0, 0.0])
    """
    lam = PSM4_ASSUMED.wavenumber_grid(31)  # the grid predict renders white light on
    orders, rgb = colour_chart(
        PSM4_ASSUMED,
        light_source(light, lam),
        Camera(sensitivities=camera),
        max_order=max_order,
        n=int(np.ceil(max_order * 500)) + 1,  # 0.002 fringe per row
    )
    rgb = np.clip(rgb * exposure, 0, 1)
    if camera == "CIE1931":
        rgb = np.clip(colour.cctf_encoding(rgb, function="sRGB"), 0, 1)
    return CalibrationTable.from_chart(orders, rgb, "synthetic colour chart (optics)")


#: Share of the region where the two fold resolutions may differ by more than a quarter
#: fringe before analyze warns.
MAX_FOLD_DISAGREEMENT = 0.05

#: Median colour distance of the rgb method's seeds to the table's colour at their orders
#: ([0, 1] scale) before analyze warns. Seeds at the right order measured 0.01-0.07 with
#: the table's camera and 0.10-0.13 with another white balance, exposure and tone curve;
#: a border assumed at order 0 that lies at 0.5-2, 0.77-1.5.
MAX_SEED_MISFIT = 0.3


def analyse_phase(
    paths,
    dark,
    mask_args,
    anchor_order,
    order_at=None,
    *,
    min_modulation=0.1,
    fold="count",
    reference=None,
):
    """Six-step images -> (order, reliable, extra maps, summary part, mask).

    Both fold resolutions run (counting fringes, and following the isoclinic); ``fold``
    picks the map, the other checks it. ``reference`` (six zero-load images): their
    retardation is subtracted vectorially first (:func:`analysis.subtract_reference`)."""
    frames = load_six_step(paths[0] if len(paths) == 1 else paths, dark=dark)
    mask, no_data_px = data_region(np.stack([f.data for f in frames], -1), mask_args)
    res = six_step(frames, mask=mask, min_modulation=min_modulation)
    if not res.valid.any():
        raise InputError(_no_modulation(paths, frames, res.modulation[mask], min_modulation))
    if reference:
        ref = load_six_step(reference[0] if len(reference) == 1 else reference, dark=dark)
        if ref[0].shape != frames[0].shape:
            raise InputError(
                f"--reference: images of {ref[0].shape} px, the loaded ones {frames[0].shape}; "
                "allowed: the same camera view"
            )
        res = subtract_reference(res, six_step(ref, mask=mask, min_modulation=min_modulation))
    anchor, known = order_anchors(
        frames[0].shape,
        res.valid,
        order_at,
        anchor_order,
        "not masked, modulation above --min-modulation",
    )
    if np.ndim(known) == 0:  # the border ring at --anchor-order
        by_iso = unwrap_fringe_order(
            res, resolve_ambiguity(res), anchor_mask=anchor, anchor_order=known
        )
    else:  # the --order-at points: a map of known orders
        by_iso = unwrap_fringe_order(res, resolve_ambiguity(res), reference_order=known)
    by_count = count_fringe_order(res, anchor_mask=anchor, anchor_order=np.nan_to_num(known))
    fo = by_count if fold == "count" else by_iso
    both = np.isfinite(by_iso.order) & np.isfinite(by_count.order)
    differ = (
        float(np.mean(np.abs(by_iso.order - by_count.order)[both] > 0.25)) if both.any() else 0.0
    )
    maps = {
        "isoclinic_rad": np.where(res.valid, fo.isoclinic, np.nan),
        "delta_eq3_rad": np.where(res.valid, res.delta_eq3, np.nan),
        "delta_axis_insensitive_rad": np.where(res.valid, res.delta_axis_insensitive, np.nan),
        "modulation": res.modulation,
    }
    part = {
        "phase": {
            "fold": fold,
            "reference": list(reference or []) or None,
            "info": fo.info,
            "offset": fo.offset,
            "anchor_order": anchor_order if np.ndim(known) == 0 else None,
            "fold_disagreement_fraction": differ,
            "order_at": [list(p) for p in order_at or []],
        }
    }
    if differ > MAX_FOLD_DISAGREEMENT:
        other = "isoclinic" if fold == "count" else "count"
        part["extra_warning"] = (
            f"the fringe count and the isoclinic continuity resolve the phase differently on "
            f"{100 * differ:.0f} % of the pixels (more than half a fringe apart): check "
            f"--order-at or --anchor-order, or compare with --fold {other}"
        )
    part["no_data_px"] = no_data_px
    return fo.order, fo.reliable, maps, part, mask


def _no_modulation(paths, frames, modulation, min_modulation) -> str:
    """Why six phase-stepped images give no pixel to unwrap: the same image twice, or
    no fringe modulation anywhere in the region."""
    names = [str(p) for p in paths] if len(paths) == 6 else [f"step {k + 1}" for k in range(6)]
    for i in range(6):
        for j in range(i + 1, 6):
            if np.array_equal(frames[i].data, frames[j].data):
                return (
                    f"the phase method's images {i + 1} and {j + 1} ({names[i]}, {names[j]}) are "
                    "identical, so no pixel is modulated; allowed: six images of the six "
                    "polariscope arrangements, in order"
                )
    top = float(np.max(modulation)) if modulation.size else 0.0
    return (
        f"no pixel in the region is modulated across the six images (largest modulation "
        f"{top:.3g}); allowed: at least --min-modulation {min_modulation:g} (check the images "
        "are the six polariscope arrangements, in order)"
    )


def _rgb_seeds(shape, mask, seeds, order_at, anchor_order) -> tuple[np.ndarray, str]:
    """The refined search's seeds as a map of orders (NaN off them) and where they came
    from: the ``--seed`` pixels and the ``--order-at`` discs, else the region's border
    ring at ``--anchor-order`` (as phase and mono)."""
    known = np.full(shape[:2], np.nan)
    for r, c, n in seeds:
        rr, cc = int(round(r)), int(round(c))
        if not (0 <= rr < shape[0] and 0 <= cc < shape[1]) or not mask[rr, cc]:
            raise InputError(
                f"--seed {r:g} {c:g} {n:g}: the pixel is outside the image or the region of "
                f"interest; allowed: a pixel with data in the {shape[0]} x {shape[1]} image"
            )
        known[rr, cc] = n
    anchor, orders = order_at_anchor(
        shape, mask, order_at, "in the region of interest, not clipped to white"
    )
    if anchor is not None:
        known = np.where(anchor, orders, known)
    if np.isfinite(known).any():
        return known, "--seed/--order-at pixels"
    ring = border_anchor(mask)
    if not ring.any():
        raise InputError(
            "no pixel of the region of interest lies on the image border, where the rgb "
            f"method's continuity search starts at --anchor-order ({anchor_order:g}); "
            "allowed: --seed ROW COL N or --order-at ROW COL N (a pixel of known order), "
            "or --search plain"
        )
    return np.where(ring, float(anchor_order), np.nan), "border at --anchor-order"


def analyse_rgb(
    paths,
    dark,
    mask_args,
    *,
    colour_table=None,
    chart=None,
    seeds=(),
    window=0.25,
    search_mode="refined",
    adapt="auto",
    order_at=(),
    anchor_order=0.0,
):
    """One colour image -> (order, reliable, extra maps, summary part, mask).

    ``search_mode="refined"`` (the default): the continuity search with colour adaptation
    (:func:`analysis.search_adapted`) from the seeds (:func:`_rgb_seeds`); ``"plain"``:
    every pixel against the whole table (reliable to about order 3)."""
    if len(paths) != 1:
        raise InputError(f"the rgb method takes one colour image, got {len(paths)}")
    frame = load_image(paths[0], dark=dark)
    if frame.data.ndim != 3:
        raise InputError(f"{paths[0]}: a grey image; the rgb method needs colour")
    # one channel at full scale still constrains the order (vivid fringe colours leave
    # the sRGB gamut and clip, in the chart exactly as in the image); a pixel with
    # every channel at full scale does not
    mask, no_data_px = data_region(frame.data, mask_args)
    mask &= ~np.all(frame.data >= 1.0, axis=-1)
    table = _table(colour_table, chart)
    info = {"refined": search_mode == "refined", "adapt": "off", "reach": None}
    misfit = 0.0  # the seeds' colour distance to the table at their orders
    if search_mode == "refined":
        known, origin = _rgb_seeds(frame.data.shape, mask, seeds, order_at, anchor_order)
        _check_seed_range(known, table, window)
        rr = search_adapted(frame.data, table, known, mask=mask, window=window, adapt=adapt)
        info.update(adapt=adapt, reach=rr.reach, seeds=origin, adaptation_px=rr.adaptation.pixels)
        info["adaptation"] = rr.adaptation.coefficients.round(4).tolist()
        misfit = _seed_misfit(frame.data, table, known)
        info["seed_colour_misfit"] = misfit
    else:
        rr = search(frame.data, table, mask=mask)
    reliable = rr.reliable  # an order within MAX_COLOUR_ERROR of a table colour
    spread = colour_spread(frame.data, mask)
    part = {
        "rgb": {
            "table": table.source,
            "rows": len(table),
            "orders": [float(table.orders[0]), float(table.orders[-1])],
            "colour_spread": spread,
            **info,
        }
    }
    if spread < MIN_COLOUR_SPREAD:  # single-colour light: colour cannot tell orders apart
        reliable = np.zeros_like(reliable)
        part["unreliable_reason"] = (
            f"the image's colours lie on a line (colour spread {spread:.2g} < "
            f"{MIN_COLOUR_SPREAD:g}): single-colour light or grey, where colour does not "
            "tell fringe orders apart; the rgb method needs white light (six phase-stepped "
            "images: --method phase)"
        )
    elif misfit > MAX_SEED_MISFIT:
        part["extra_warning"] = (
            f"the seeds' colours do not match the colour table at their orders (median "
            f"colour distance {misfit:.2f}, more than {MAX_SEED_MISFIT:g}; seeds from the "
            f"{origin}): the orders read from them may be off by a fringe or more; check "
            "--anchor-order, --order-at or --seed"
        )
    part["no_data_px"] = no_data_px
    return rr.order, reliable, {"colour_error": rr.error}, part, mask


def _seed_misfit(image, table: CalibrationTable, known) -> float:
    """Median colour distance of the seed pixels to the table's colour at their orders
    (a border assumed at order 0 that is at order 1 is black in the table, not yellow),
    after one brightness gain between the two (in [1/4, 4], least squares): an image
    exposed brighter or darker than the table is what the adaptation corrects, not a
    wrong seed (a rendered 96 px image's right seeds were 0.99 apart without it)."""
    seeded = np.isfinite(known)
    n = known[seeded]
    rgb = np.column_stack([np.interp(n, table.orders, table.rgb[:, k]) for k in range(3)])
    seen = image[seeded]
    gain = float(np.sum(rgb * seen) / max(float(np.sum(rgb * rgb)), 1e-12))
    gain = min(max(gain, 0.25), 4.0)
    return float(np.median(np.linalg.norm(seen - gain * rgb, axis=1)))


def _check_seed_range(known, table, window) -> None:
    """Every seed order inside the colour table's range, or a one-line error."""
    o = known[np.isfinite(known)]
    lo, hi = table.orders[0] - window, table.orders[-1] + window
    if o.size and (o.min() < lo or o.max() > hi):
        bad = float(o[(o < lo) | (o > hi)][0])
        raise InputError(
            f"seed order {bad:g} (--seed, --order-at or --anchor-order) is outside the colour "
            f"table's orders {table.orders[0]:g}..{table.orders[-1]:g}; allowed: an order in "
            "that range (raise --max-order for the synthetic chart)"
        )
