"""``fringekit analyze --method mono`` and the ``--points`` table of every method.

:func:`analyse_mono` reads one monochrome photograph (dark or bright field; a colour
photo of monochromatic light is reduced to its strongest channel), the optional flat
field, builds the region and the anchor from the options, and runs
:func:`analysis.mono_order`. :func:`read_points` / :func:`write_points` turn a CSV of
points (``row,col`` pixels or ``x_mm,y_mm`` in the sensor frame) into ``points.csv``.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from fringekit.analysis import (
    AGREE_MIN,
    channel_agreement,
    grey_channel,
    load_image,
    mono_order,
    strongest_channel,
)
from fringekit.errors import InputError
from fringekit.measurement.regions import data_region, order_anchors

__all__ = [
    "POINTS_COLUMNS",
    "analyse_mono",
    "colour_as_grey",
    "field_note",
    "read_points",
    "write_points",
]

#: Columns of ``points.csv``, in order.
POINTS_COLUMNS = ("row", "col", "x_mm", "y_mm", "order", "order_sd", "reliable")


def colour_as_grey(data, mask, path, option: str) -> str:
    """For a monochrome method given a colour photograph: the note that says which
    channel is read, or an :class:`InputError` when its channels disagree (white light,
    whose colours the ``rgb`` method reads); ``""`` for a grey image.

    Examples
    --------
    >>> import numpy as np
    >>> order = np.linspace(0, 4, 200)[None, :] * np.ones((8, 1))
    >>> sodium = np.sin(np.pi * order[..., None]) ** 2 * np.array([0.8, 1.0, 0.3])
    >>> print(colour_as_grey(sodium, None, "photo.png", "--method mono"))
    photo.png is a colour image of monochromatic light (its channels agree, correlation
    1.00): read as its green channel
    """
    if np.ndim(data) != 3:
        return ""
    c, pair = channel_agreement(data, mask)
    if c < AGREE_MIN:
        raise InputError(
            f"{option}: {path} is a colour image whose {pair} channels disagree (correlation "
            f"{c:.2f}, allowed at least {AGREE_MIN:g}): white-light fringes; use --method rgb, "
            "or photograph in monochromatic light"
        )
    name = ("red", "green", "blue")[strongest_channel(data, mask)]
    return (
        f"{path} is a colour image of monochromatic light (its channels agree, correlation "
        f"{c:.2f}): read as its {name} channel"
    )


def field_note(info: dict, order_at) -> str:
    """The warning when the anchor's intensity contradicts ``--field`` (``""`` if not).

    Examples
    --------
    >>> info = {"field": "dark", "field_implied": "bright", "anchor_intensity": 0.97,
    ...         "anchor_order_median": 1.0}
    >>> print(field_note(info, [(10, 20, 1.0)]))
    --field dark contradicts the anchor: --order-at 10 20 1 is bright (normalised intensity
    0.97), and a whole order is dark in dark field; the image looks like bright field: give
    --field bright, or check the anchor's order
    """
    field, implied = info.get("field"), info.get("field_implied")
    if not implied or implied == field:
        return ""
    where = (
        " and ".join(f"--order-at {r:g} {c:g} {n:g}" for r, c, n in order_at)
        if order_at
        else f"the image border at --anchor-order {info['anchor_order_median']:g}"
    )
    seen = info["anchor_intensity"]
    kind = "whole" if abs(np.sin(np.pi * info["anchor_order_median"])) < 0.5 else "half"
    return (
        f"--field {field} contradicts the anchor: {where} is "
        f"{'bright' if seen > 0.5 else 'dark'} (normalised intensity {seen:.2f}), and a "
        f"{kind} order is {'dark' if (kind == 'whole') == (field == 'dark') else 'bright'} in "
        f"{field} field; the image looks like {implied} field: give --field {implied}, or check "
        "the anchor's order"
    )


def analyse_mono(paths, dark, mask_args, anchor_order, order_at, mono: dict):
    """One monochrome image -> (order, reliable, extra maps, summary part, mask)."""
    if len(paths) != 1:
        raise InputError(f"the mono method takes one image, got {len(paths)}")
    frame = load_image(paths[0], dark=dark)
    mask, no_data_px = data_region(frame.data, mask_args)
    mask &= ~frame.saturated
    colour_note = colour_as_grey(frame.data, mask, paths[0], "--method mono")
    flat = None
    if mono.get("flat"):
        flat_frame = load_image(mono["flat"], dark=dark)
        if flat_frame.shape != frame.shape:
            raise InputError(
                f"--flat {mono['flat']}: shape {flat_frame.shape} does not match the image's "
                f"{frame.shape}"
            )
        flat = grey_channel(flat_frame.data, mask)
    anchor, known = order_anchors(frame.shape, mask, order_at, anchor_order)
    res = mono_order(
        frame.data,
        mask=mask,
        field=mono.get("field", "dark"),
        anchor_mask=anchor,
        anchor_order=np.nan_to_num(known),
        flat=flat,
        smooth_px=mono.get("smooth_px", 0.5),
    )
    maps = {
        "order_sd": res.order_sd,
        "normalised_intensity": res.normalised,
        "fringe_centres": res.centres,
    }
    part = {
        "mono": {
            "field": mono.get("field", "dark"),
            "flat": mono.get("flat"),
            "anchor_order": anchor_order if not order_at else None,
            "order_at": [list(p) for p in order_at or []],
            **res.info,
        }
    }
    part["no_data_px"] = no_data_px
    notes = [n for n in (colour_note, field_note(res.info, order_at)) if n]
    if notes:
        part["extra_warning"] = "; ".join(notes)
    share = float(res.reliable[mask].mean())
    if res.info["ordered_bands"] == 0 or res.info["bands"] < 2:
        part["unreliable_reason"] = "no fringes found to count"
    elif "high" not in res.envelope.sampled:
        part["unreliable_reason"] = (
            "no half-order fringe centre (a bright fringe in dark field) sets the fringe "
            "amplitude; give --flat, an image of the light without the specimen's retardation"
        )
    elif share < 0.5:
        part["unreliable_reason"] = (
            "bands out of reach of the anchor, caps whose fringe centre is not seen, or low "
            "fringe contrast; give --order-at ROW COL N in each region, or a --flat image"
        )
    return res.order, res.reliable, maps, part, mask


def read_points(path, shape, pixel_size: float, origin_rc) -> np.ndarray:
    """(k, 2) float (row, col) px of the points in ``path`` (CSV with a header
    ``row,col`` or ``x_mm,y_mm``); errors name ``--points``, the line and what is allowed."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"--points {path}: the file does not exist")
    with path.open(newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    if not rows:
        raise InputError(f"--points {path}: empty; allowed: a header row,col or x_mm,y_mm")
    head = tuple(c.strip() for c in rows[0])
    if head not in (("row", "col"), ("x_mm", "y_mm")):
        raise InputError(
            f"--points {path}: header {','.join(head)!r} is not allowed; use row,col or x_mm,y_mm"
        )
    if head == ("x_mm", "y_mm") and not pixel_size:
        raise InputError(f"--points {path}: x_mm,y_mm points need --pixel-mm")
    try:
        values = np.array([[float(c) for c in r] for r in rows[1:]], float).reshape(-1, 2)
    except ValueError:
        raise InputError(
            f"--points {path}: every line after the header must be two numbers"
        ) from None
    if not len(values) or not np.isfinite(values).all():
        raise InputError(f"--points {path}: no points, or a value that is not finite")
    if head == ("x_mm", "y_mm"):
        step = pixel_size * 1e3
        values = np.column_stack(
            [origin_rc[0] - values[:, 1] / step, origin_rc[1] + values[:, 0] / step]
        )
    inside = (values >= -0.5).all(axis=1) & (values[:, 0] <= shape[0] - 0.5)
    inside &= values[:, 1] <= shape[1] - 0.5
    if not inside.all():
        k = int(np.flatnonzero(~inside)[0])
        raise InputError(
            f"--points {path}: point {k + 1} ({rows[k + 1][0].strip()}, "
            f"{rows[k + 1][1].strip()}) is outside the {shape[0]} x {shape[1]} image"
        )
    return values


def write_points(out: Path, points, maps: dict, pixel_size: float, origin_rc) -> None:
    """``points.csv``: :data:`POINTS_COLUMNS`, one row per point in input order (nearest
    pixel; x_mm, y_mm empty without a pixel size; order_sd empty where the method gives
    none)."""
    idx = np.rint(points).astype(int)
    r, c = idx[:, 0], idx[:, 1]
    order = maps["fringe_order"][r, c]
    sd = maps["order_sd"][r, c] if "order_sd" in maps else np.full(len(r), np.nan)
    rel = maps["reliable"][r, c]
    step = pixel_size * 1e3
    with (out / "points.csv").open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(POINTS_COLUMNS)
        for k, (pr, pc) in enumerate(points):
            xy = ((pc - origin_rc[1]) * step, (origin_rc[0] - pr) * step) if step else None
            w.writerow(
                [
                    f"{pr:.6g}",
                    f"{pc:.6g}",
                    f"{xy[0]:.6g}" if xy else "",
                    f"{xy[1]:.6g}" if xy else "",
                    f"{order[k]:.6g}" if np.isfinite(order[k]) else "",
                    f"{sd[k]:.6g}" if np.isfinite(sd[k]) else "",
                    "true" if rel[k] else "false",
                ]
            )
