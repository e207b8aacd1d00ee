"""``fringekit calibrate --disc IMAGE... --load-N P...``: the fringe value from photographs.

Reads the photographs (and the zero-load ``--reference``), finds the disc (given by
``--centre`` and ``--radius-px``; else :func:`analysis.find_disc`: its outline, else the
symmetry of its fringes), fits Frocht's field through
the polariscope to the intensities (:func:`fringekit.disc_photo.fit_disc_photos`) and
writes to ``--out``:

- ``disc_calibration.json`` - exactly ``f_sigma_N_per_m``, ``f_sigma_sd_N_per_m``,
  ``offset_order`` and ``images``: per photograph ``file``, ``load_N``, ``centre_order``
  (the load's part, without the offset) and ``residual_rms`` (fraction of the fringe
  amplitude);
- ``summary.json`` - how: the disc found (centre, radius, pixel size, method), the field,
  the wavelength, the uncertainty's method, warnings, time;
- ``disc_fit.png`` - the fitted fringe centres over each photograph.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from fringekit.analysis import find_disc, grey_channel, load_image
from fringekit.calibrate.disc_photo import (
    REFUSE_RESIDUAL,
    WARN_RESIDUAL,
    DiscGeometry,
    DiscImage,
    fit_disc_photos,
)
from fringekit.output.figures import disc_fit_figure

__all__ = ["is_photo", "run_disc_photos"]


def is_photo(path) -> bool:
    """Whether ``path`` is an image file (else a maps.npz or an analyze folder)."""
    return Path(path).suffix.lower() in (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")


def _geometry(photo, centre, radius_px, pixel_mm, diameter_mm) -> tuple[DiscGeometry, str]:
    """The disc in the photo: from the options, its outline, or its fringes' symmetry."""
    if pixel_mm and radius_px is None:
        radius_px = diameter_mm / 2 / pixel_mm
    if centre is not None and radius_px is not None:
        return DiscGeometry(centre[0], centre[1], radius_px), "--centre and --radius-px"
    try:
        c, how = find_disc(photo)
    except ValueError:
        raise ValueError(
            "--disc: no disc found in the photograph; give --centre ROW COL and --radius-px R"
        ) from None
    row, col = centre if centre is not None else (c.row, c.col)
    return DiscGeometry(row, col, radius_px or c.radius), how


def _order_map(shape, geometry: DiscGeometry, fit, load_N, diameter, thickness):
    """(rows, cols) fitted total order P g / f_sigma + N_0 inside the disc, NaN outside."""
    from fringekit.calibrate.disc_photo import disc_coordinates
    from fringekit.optics import DiametralDisc

    r, c = np.mgrid[: shape[0], : shape[1]]
    xy = disc_coordinates(r.ravel(), c.ravel(), geometry, diameter)
    inside = np.hypot(xy[:, 0], xy[:, 1]) < 0.98 * diameter / 2
    N = np.full(len(xy), np.nan)
    disc = DiametralDisc(P=max(load_N, 1e-12), D=diameter, t=thickness)
    N[inside] = thickness * disc.stress_difference(xy[inside]) / fit.f_sigma * (load_N > 0)
    return (N + fit.offset_order).reshape(shape)


def run_disc_photos(
    images, loads, *, diameter_mm, thickness_mm, out, wavelength_nm=None, reference=None,
    field="dark", centre=None, radius_px=None, pixel_mm=None, dark=None, echo=print,
) -> dict:  # fmt: skip
    """Fit f_sigma to disc photographs at known loads; write the outputs (module doc)."""
    t0 = time.perf_counter()
    if len(loads) != len(images):
        raise ValueError(
            f"--load-N: {len(loads)} load(s) for {len(images)} photograph(s); give one per photo"
        )
    photos = [grey_channel(load_image(p, dark=dark).data) for p in images]
    names, all_loads = [str(p) for p in images], [float(v) for v in loads]
    if reference is not None:
        photos.append(grey_channel(load_image(reference, dark=dark).data))
        names.append(str(reference))
        all_loads.append(0.0)
    shapes = {p.shape for p in photos}
    if len(shapes) > 1:
        raise ValueError(
            f"--disc: the photographs differ in size ({sorted(shapes)}); allowed: one size"
        )
    D, t = diameter_mm * 1e-3, thickness_mm * 1e-3
    strongest = photos[int(np.argmax(all_loads))]
    geometry, how = _geometry(strongest, centre, radius_px, pixel_mm, diameter_mm)
    echo(
        f"disc: centre ({geometry.row:.1f}, {geometry.col:.1f}) px, radius "
        f"{geometry.radius_px:.1f} px from the {how}; fitting {len(photos)} photograph(s)"
    )
    discs = [DiscImage(p, P, n) for p, P, n in zip(photos, all_loads, names, strict=True)]
    fit = fit_disc_photos(discs, geometry, diameter=D, thickness=t, field=field,
                          shared_light=reference is not None)  # fmt: skip
    worst = max(fit.residuals)
    if worst > REFUSE_RESIDUAL:
        raise ValueError(
            f"--disc: Frocht's field leaves an RMS residual of {100 * worst:.0f} % of the fringe "
            "amplitude: the photographs are not explained as a disc in diametral compression "
            "(check --load-N, --diameter-mm, --field, the disc found, or give --centre/--radius-px)"
        )
    warnings = []
    if worst > WARN_RESIDUAL:
        warnings.append(
            f"RMS residual {100 * worst:.0f} % of the fringe amplitude (a good fit leaves 1-2 "
            "%): f_sigma is uncertain beyond its stated sd; check the loads, the diameter, "
            "uneven residual stress, or fringes too dense for the pixels"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result = {
        "f_sigma_N_per_m": fit.f_sigma,
        "f_sigma_sd_N_per_m": fit.f_sigma_sd,
        "offset_order": fit.offset_order,
        "images": [
            {"file": n, "load_N": P, "centre_order": c, "residual_rms": r}
            for n, P, c, r in zip(names, all_loads, fit.centre_orders, fit.residuals, strict=True)
        ],
    }
    (out / "disc_calibration.json").write_text(json.dumps(result, indent=2))
    g = fit.geometry
    summary = {
        "disc": {"centre_px": [g.row, g.col], "radius_px": g.radius_px,
                 "load_axis_tilt_deg": float(np.degrees(g.angle_rad)), "found_from": how,
                 "pixel_mm": diameter_mm / 2 / g.radius_px},  # fmt: skip
        "diameter_mm": diameter_mm, "thickness_mm": thickness_mm, "field": field,
        "wavelength_nm": wavelength_nm, "reference": None if reference is None else str(reference),
        "sd_method": fit.sd_method, "model_evaluations": fit.evaluations,
        "warnings": warnings, "time_s": time.perf_counter() - t0,
    }  # fmt: skip
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    orders = [_order_map(p.shape, g, fit, P, D, t) for p, P in zip(photos, all_loads, strict=True)]
    titles = [f"{Path(n).name}: {P:g} N, centre {c:.3f}"
              for n, P, c in zip(names, all_loads, fit.centre_orders, strict=True)]  # fmt: skip
    disc_fit_figure(out / "disc_fit.png", photos, orders, titles)
    return {**result, "summary": summary}
