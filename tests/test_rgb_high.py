"""White-light (three-fringe) photoelasticity beyond order 3: colour adaptation, fringe-order
continuity and the method's reach, on photographs rendered through fringekit's own optics
(camera noise, vignetting, 8-bit, JPEG; white balance, exposure and tone curve other than
the colour table's). Seeded and deterministic; 128 px images."""

from __future__ import annotations

import numpy as np
import pytest

from fringekit import Region, RGBOptions, analyze
from fringekit.analysis import CalibrationTable, search, search_adapted
from fringekit.errors import InputError
from fringekit.measurement.methods import default_colour_table
from fringekit.optics import (
    PSM4_ASSUMED,
    Camera,
    PhotoModel,
    light_source,
    retarder,
    white_light_photograph,
    write_image,
)

N_PX = 128
BANDS = ((0.0, 3.0), (3.0, 4.5), (4.5, 6.0))

#: The table's camera (fringekit's default chart: CIE observer, sRGB, exposure 0.9) and
#: photographs through it: the same setting, and another white balance, exposure and tone.
CAMERAS = {
    "as the table": ({"exposure": 0.9}, {}),
    "another white balance, exposure and tone": (
        {"exposure": 0.8},
        {"white_balance": (1.08, 1.0, 0.9), "tone_gamma": 1.25},
    ),
}


def _field(peak: float, width: float = 0.38):
    """A smooth hill of fringe order, ``peak`` in the middle, principal axes radial; at
    most 0.11 (``width`` 0.38) to 0.17 fringe per pixel (0.25, order 0.1 on the border)."""
    r, c = np.mgrid[:N_PX, :N_PX].astype(float)
    x, y = (c - (N_PX - 1) / 2) / N_PX, ((N_PX - 1) / 2 - r) / N_PX
    rad = np.hypot(x, y)
    return peak * np.exp(-((rad / width) ** 2)), np.arctan2(y, x), rad > 0.04


def _photo(order, theta, camera: dict, extra: dict, seed=0) -> np.ndarray:
    led = light_source("LED", PSM4_ASSUMED.wavenumber_grid(31))
    k = PSM4_ASSUMED.relative_retardation(led.wavelengths)
    q = retarder(2 * np.pi * order[..., None] * k, theta[..., None])
    cam = Camera(full_well=2e4, read_noise=10.0, **camera)
    lab = PhotoModel(vignetting=0.15, jpeg_quality=90)
    return white_light_photograph(q, led, cam, lab, seed=seed, **extra)


@pytest.fixture(scope="module")
def table() -> CalibrationTable:
    """fringekit's default chart (as ``analyze`` makes it), to order 7."""
    return default_colour_table()


def _band_rms(est, order, use) -> list[float]:
    out = []
    for lo, hi in BANDS:
        m = use & (order >= lo) & (order < hi)
        out.append(float(np.sqrt(np.mean((est[m] - order[m]) ** 2))))
    return out


@pytest.mark.parametrize("camera", CAMERAS)
def test_orders_4_to_6_are_read_within_005_fringe(table, camera):
    """Continuity and adaptation read a photograph to order 6 within 0.05 fringe RMS in
    every band, on 90 % of the pixels or more; the plain search reads orders 4.5-6 off
    by more than 0.3 fringe RMS (colours repeat)."""
    order, theta, mask = _field(6.2)
    img = _photo(order, theta, *CAMERAS[camera]) / 255.0
    ring = np.zeros_like(mask)
    ring[[0, -1], :] = ring[:, [0, -1]] = True
    seeds = np.where(ring, order, np.nan)  # the far field's order known, as a no-load rim
    res = search_adapted(img, table, seeds, mask=mask)
    rms = _band_rms(res.order, order, res.reliable)
    assert max(rms) < 0.05, rms
    for lo, hi in BANDS:
        band = mask & (order >= lo) & (order < hi)
        assert res.reliable[band].mean() > 0.9, (lo, hi, res.reliable[band].mean())
    plain = search(img, table, mask=mask)
    assert _band_rms(plain.order, order, mask)[2] > 0.3


def test_adaptation_recovers_orders_the_table_misreads(table):
    """A photograph under another white balance, exposure and tone curve than the table:
    without adaptation the continuity search is off by more than 0.05 fringe RMS at
    orders 4.5-6; adapted to the image's own low orders it stays within 0.05."""
    order, theta, mask = _field(6.2)
    img = _photo(order, theta, *CAMERAS["another white balance, exposure and tone"]) / 255.0
    seeds = [((0, 0), float(order[0, 0]))]
    off = search_adapted(img, table, seeds, mask=mask, adapt="off")
    on = search_adapted(img, table, seeds, mask=mask, adapt="auto")
    assert _band_rms(off.order, order, mask)[2] > 0.05
    assert max(_band_rms(on.order, order, mask)) < 0.05
    gains = np.diag(on.adaptation.coefficients[1:])
    assert np.all(gains < 1.0) and on.adaptation.pixels > 5000  # a dimmer photograph


@pytest.mark.parametrize("camera", CAMERAS)
def test_orders_beyond_the_reach_are_unreliable_not_wrong(table, camera):
    """A hill to order 8.5, 0.15 fringe per pixel where it passes order 5: the colours wash
    out above about 6.2 and the search slips onto a lower branch (4.4-4.5) from order 4.9
    inward. Every pixel above the reported reach (plus the search window) is unreliable
    and the reliable pixels are right (0.03 fringe RMS, none of 16 304 off by half a
    fringe; 3 072 and 3 242 of them were called reliable and off by more than a quarter
    fringe before the colour check); what is lost is the band the search could not
    follow (4.9 to the reach, 11 % of the region) and the check's margin. The plain
    search calls pixels off by more than half a fringe reliable."""
    order, theta, mask = _field(8.5)
    img = _photo(order, theta, *CAMERAS[camera]) / 255.0
    res = search_adapted(img, table, [((0, 0), float(order[0, 0]))], mask=mask)
    assert 5.5 < res.reach < 7.0
    assert not res.reliable[order > res.reach + 0.25].any()
    err = np.abs(res.order - order)[res.reliable]
    assert err.size > 0.6 * mask.sum() and np.sqrt(np.mean(err**2)) < 0.05
    assert not (err > 0.5).any()
    plain = search(img, table, mask=mask)
    assert (np.abs(plain.order - order)[plain.reliable] > 0.5).any()


def test_analyze_reads_a_photograph_to_order_6_by_default(tmp_path):
    """``fringekit analyze IMG --method rgb --seed ...`` (the corners): by default the
    refined search with adaptation on the default chart, which reaches order 7."""
    order, theta, mask = _field(6.2)
    path = tmp_path / "white.png"
    write_image(path, _photo(order, theta, *CAMERAS["another white balance, exposure and tone"]))
    corners = [(r, c, float(order[r, c])) for r in (0, N_PX - 1) for c in (0, N_PX - 1)]
    region = Region(exclude_circles=[(63.5, 63.5, 5.5)])
    an = analyze([path], method="rgb", region=region, options=RGBOptions(seeds=corners))
    fo, ok = an.maps["fringe_order"], an.maps["reliable"]
    assert max(_band_rms(fo, order, ok & mask)) < 0.05
    assert ok[mask].mean() > 0.9
    assert an.summary["rgb"]["refined"] and an.summary["rgb"]["adapt"] == "auto"
    assert 6.0 < an.summary["rgb"]["reach"] < 7.0


@pytest.mark.parametrize(
    "options, words",
    [
        ({"search": "nearest"}, ["--search nearest", "refined or plain"]),
        ({"adapt": "yes"}, ["--adapt yes", "auto, seeds or off"]),
    ],
)
def test_bad_rgb_options_are_refused_in_one_line(options, words):
    with pytest.raises(InputError) as exc:
        RGBOptions(**options)
    msg = str(exc.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_a_seed_outside_the_table_or_the_region_is_refused(tmp_path):
    order, theta, _ = _field(3.0)
    path = tmp_path / "white.png"
    write_image(path, _photo(order, theta, {"exposure": 0.9}, {}))
    with pytest.raises(InputError, match=r"--seed 200 5 0: .*allowed"):
        analyze([path], method="rgb", options=RGBOptions(seeds=[(200, 5, 0.0)]))
    with pytest.raises(InputError, match=r"seed order 9 .*outside the colour table's orders"):
        analyze([path], method="rgb", options=RGBOptions(seeds=[(5, 5, 9.0)]))
    with pytest.raises(InputError) as exc:  # masked out: rgb has no --min-modulation
        analyze(
            [path], method="rgb", region=Region(circle=(63.5, 63.5, 20)), order_at=[(2, 2, 0.0)]
        )
    assert "--order-at 2 2 0: no valid pixel" in str(exc.value)
    assert "region of interest" in str(exc.value) and "modulation" not in str(exc.value)
    inner = Region(circle=(63.5, 63.5, 40))  # no pixel on the image border
    with pytest.raises(InputError, match=r"--seed ROW COL N or --order-at"):
        analyze([path], method="rgb", region=inner)


def test_seeds_whose_colours_misfit_the_table_are_named_in_one_line(tmp_path):
    """A specimen whose border is at order 1, read from the border at the default
    --anchor-order 0: the seeds' colours (order 1's) are far from the table's at order 0
    (black), and analyze says so, naming the options; at --anchor-order 1 it does not."""
    order, theta, _ = _field(2.5, width=0.2)
    order = order + 1.0  # the border at order 1.000-1.005
    path = tmp_path / "white.png"
    write_image(path, _photo(order, theta, *CAMERAS["another white balance, exposure and tone"]))
    wrong = analyze([path], method="rgb")
    msg = wrong.summary["warning"]
    assert "\n" not in msg and wrong.summary["rgb"]["seed_colour_misfit"] > 0.5
    assert all(w in msg for w in ("seeds' colours", "--anchor-order", "--order-at", "--seed"))
    right = analyze([path], method="rgb", anchor_order=1.0)
    assert right.summary["rgb"]["seed_colour_misfit"] < 0.2
    assert "seeds' colours" not in right.summary.get("warning", "")
    assert np.nanmedian(np.abs(right.maps["fringe_order"] - order)) < 0.02
