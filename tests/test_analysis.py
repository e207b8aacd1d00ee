"""Image analysis against exact answers: synthetic disc and indentation images (optics)."""

from __future__ import annotations

import numpy as np
import pytest

from fringekit.analysis.compare import circle_profile, compare_maps, line_profile
from fringekit.analysis.images import load_image, load_six_step, normalise
from fringekit.analysis.masks import circle_mask, exclude_circle, polygon_mask
from fringekit.analysis.phase import principal_stress_difference, resolve_ambiguity, six_step, wrap
from fringekit.analysis.rgb import CalibrationTable, search, search_refined
from fringekit.analysis.unwrap import unwrap_fringe_order
from fringekit.optics import (
    PSM4_ASSUMED,
    Boussinesq,
    Camera,
    DiametralDisc,
    PixelGrid,
    colour_chart,
    intensity,
    light_source,
    optical_map,
    six_step_arrangements,
    white_light_image,
    write_image,
)
from fringekit.output.figures import comparison_figure

LAW = PSM4_ASSUMED
LAM = PSM4_ASSUMED.wavenumber_grid(31)  # as predict and the analyze chart


# -- synthetic specimens ---------------------------------------------------------------


def _disc(n=161, centre_order=3.0, wavelengths=None):
    """Diametral disc in transmission; the load points masked (the orders diverge there)."""
    D = 0.04
    P = centre_order * np.pi * D * LAW.f_sigma / 8
    m = optical_map(
        DiametralDisc(P=P, D=D, t=5e-3),
        PixelGrid((n, n), D / n),
        LAW,
        wavelengths,
        n_samples=3,
        reflection=False,
    )
    mask = m.mask.copy()
    for row in (0, n - 1):
        mask = exclude_circle(mask, (row, n // 2), 0.16 * n)
    return m, mask


def _indentation(n=160, F=3.0, wavelengths=None):
    """Boussinesq point load on the 3 mm sheet viewed in reflection, core r < 1.3 mm masked."""
    field = Boussinesq(F=F, nu=0.49, z_top=3e-3, thickness=3e-3, core=1.3e-3)
    m = optical_map(
        field, PixelGrid.from_field_of_view(10e-3, (n, n)), LAW, wavelengths, n_samples=48
    )
    return m, m.mask.copy()


def _six(m, k=0, noise=0.0, seed=1, **err):
    q = np.nan_to_num(m.q[..., k, :])
    imgs = [intensity(q, a) for a in six_step_arrangements(**err)]
    if noise:
        rng = np.random.default_rng(seed)
        imgs = [np.clip(i + noise * rng.standard_normal(i.shape), 0, 1) for i in imgs]
    return imgs


def _rms(a):
    return float(np.sqrt(np.mean(np.asarray(a) ** 2)))


@pytest.fixture(scope="module")
def disc():
    return _disc()


@pytest.fixture(scope="module")
def dent():
    return _indentation()


# -- phase shifting --------------------------------------------------------------------


@pytest.mark.parametrize("specimen", ["disc", "dent"])
@pytest.mark.parametrize("noise,tol", [(0.0, 0.02), (0.01, 0.05)])
def test_six_step_total_fringe_order(specimen, noise, tol, request):
    """Total fringe order within 0.02 RMS without noise, 0.05 with 1 % intensity noise;
    isoclinic within 1 degree where the modulation and sin(delta) are adequate."""
    m, mask = request.getfixturevalue(specimen)
    truth = m.fringe_order()
    res = six_step(_six(m, noise=noise), mask=mask)
    if specimen == "disc":  # no zero-order far field: anchor on one known pixel
        r0, c0 = 80, 5
        anchor = np.zeros_like(mask)
        anchor[r0, c0] = True
        fo = unwrap_fringe_order(res, anchor_mask=anchor, anchor_order=truth[r0, c0])
    else:
        fo = unwrap_fringe_order(res)  # far field at the border is order ~0
    assert truth[mask].max() > 1.5  # delta well beyond pi: the ambiguity case
    ok = fo.reliable & mask
    assert ok.sum() > 0.9 * mask.sum()
    err = (fo.order - truth)[ok]
    assert _rms(err) < tol, _rms(err)
    # adequate modulation: |(i4 - i6, i5 - i3)| / (i1 + i2) = m |sin d| above 0.3
    good = ok & (res.modulation * np.sin(res.delta_axis_insensitive) > 0.3)
    d_iso = (fo.isoclinic - m.principal_angle() + np.pi / 2) % np.pi - np.pi / 2
    assert np.degrees(_rms(d_iso[good])) < 1.0


def test_paper_equations_show_the_reversed_zones_that_resolution_removes(disc):
    """Eq. 2 + eq. 3 give 2 pi - delta where sin(delta) < 0 ("reversed phasemap");
    the resolved phase equals the true wrapped phase everywhere."""
    m, mask = disc
    truth = m.fringe_order()
    res = six_step(_six(m), mask=mask)
    true_wrapped = wrap(2 * np.pi * truth)
    err_eq3 = np.abs(wrap(res.delta_eq3 - true_wrapped))[mask]
    reversed_fraction = np.mean(err_eq3 > 0.1)
    assert 0.02 < reversed_fraction < 0.9
    r = resolve_ambiguity(res)
    # up to one global sign
    e_plus = np.abs(wrap(r.phase - true_wrapped))[mask]
    e_minus = np.abs(wrap(-r.phase - true_wrapped))[mask]
    assert min(np.percentile(e_plus, 99), np.percentile(e_minus, 99)) < 1e-6
    # axis-insensitive eq. 4 is the folded phase
    np.testing.assert_allclose(
        res.delta_axis_insensitive[mask], np.abs(true_wrapped)[mask], atol=1e-9
    )


def test_wrapped_phase_round_trip_on_masked_arrays():
    """A known smooth phase (6 fringes, centre masked, isoclinic winding around the hole)
    turned into six intensities, resolved and unwrapped, comes back to 1e-9."""
    n = 128
    r, c = np.mgrid[:n, :n] - (n - 1) / 2
    rho = np.hypot(r, c)
    order = 6.0 * np.exp(-((rho / 35.0) ** 2))
    theta = np.arctan2(r, c)  # radial principal direction, winds by 2 pi around the centre
    d = 2 * np.pi * order
    table = (
        1 + np.cos(d),
        1 - np.cos(d),
        1 - np.sin(2 * theta) * np.sin(d),
        1 + np.cos(2 * theta) * np.sin(d),
        1 + np.sin(2 * theta) * np.sin(d),
        1 - np.cos(2 * theta) * np.sin(d),
    )
    imgs = [0.02 + 0.45 * t for t in table]
    mask = (rho > 12) & (rho < 60)
    res = six_step(imgs, mask=mask)
    fo = unwrap_fringe_order(res)
    np.testing.assert_allclose(fo.order[mask], order[mask], atol=1e-9)
    assert np.isnan(fo.order[~mask]).all()
    assert fo.info["conflicts"] == 0
    assert fo.info["regions"] == 1 and fo.info["regions_without_anchor"] == 0


def test_quarter_wave_error_is_reported(dent):
    """A 10 degree quarter-wave retardance error and 2 degree misalignment degrade the
    result, and the consistency map says so; perfect optics report ~0."""
    m, mask = dent
    truth = m.fringe_order()
    good = six_step(_six(m), mask=mask)
    bad = six_step(_six(m, qwp_error=np.radians(10), qwp_out=np.radians(2)), mask=mask)
    assert np.nanmax(good.consistency[mask]) < 1e-9
    assert np.median(bad.consistency[mask]) > 0.02
    err_good = _rms((unwrap_fringe_order(good).order - truth)[mask])
    fo_bad = unwrap_fringe_order(bad)
    err_bad = _rms(np.nan_to_num(fo_bad.order - truth)[mask])
    assert err_bad > 10 * max(err_good, 1e-4)
    # modulation no longer 1 either: both quality maps flag the optics
    assert np.median(np.abs(bad.modulation[mask] - 1)) > np.median(
        np.abs(good.modulation[mask] - 1)
    )


def test_saturated_and_masked_pixels_are_excluded(dent):
    m, mask = dent
    imgs = [(np.clip(i, 0, 1) * 255).round().astype(np.uint8) for i in _six(m)]
    imgs[0][:5, :5] = 255
    frames = [normalise(i) for i in imgs]
    res = six_step(frames, mask=mask)
    assert not res.valid[:5, :5].any()
    assert res.valid[mask & ~np.pad(np.ones((5, 5), bool), ((0, 155), (0, 155)))].mean() > 0.95


def test_stress_difference_from_order():
    s = principal_stress_difference(np.array([1.0, 2.0]), 400.0, 3e-3)
    np.testing.assert_allclose(s, [400 / 6e-3, 800 / 6e-3])
    with pytest.raises(ValueError, match="thickness = 0"):
        principal_stress_difference(1.0, 400.0, 0)


# -- RGB ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def white():
    """Disc and indentation white-light images (16-bit sRGB) and a chart table."""
    spec, cam = light_source("LED", LAM), Camera(bit_depth=16)
    out = {}
    for name, (m, mask) in (
        ("disc", _disc(wavelengths=LAM)),
        ("dent", _indentation(wavelengths=LAM)),
    ):
        img = normalise(white_light_image(np.nan_to_num(m.q), spec, cam)).data
        out[name] = (m, mask, img)
    o, c = colour_chart(LAW, spec, cam, max_order=5.0, n=2000)
    out["table"] = CalibrationTable.from_chart(o, normalise(cam.encode(c, None)).data)
    return out


def test_rgb_refined_search_recovers_order_up_to_3(white):
    table = white["table"]
    for name in ("disc", "dent"):
        m, mask, img = white[name]
        truth = m.simple_order
        if name == "disc":
            seeds = [((80, 3), float(truth[80, 3]))]
        else:
            seeds = [((2, 2), float(truth[2, 2]))]
        res = search_refined(img, table, seeds, mask=mask)
        sel = mask & (truth <= 3.0)
        assert sel.sum() > 1000
        assert _rms((res.order - truth)[sel]) < 0.05, name
        assert np.nanmedian(res.error[sel]) < 0.01


def test_rgb_plain_search_and_its_limit(white):
    """Plain search is exact at low orders; beyond ~3 repeated colours make it jump."""
    m, mask, img = white["disc"]
    truth = m.simple_order
    res = search(img, white["table"], mask=mask)
    low = mask & (truth <= 1.0)
    assert _rms((res.order - truth)[low]) < 0.01
    high = mask & (truth > 3.0)
    assert np.mean(np.abs(res.order - truth)[high] > 0.3) > 0.01


def test_calibration_table_from_disc_line_and_csv(white, tmp_path):
    """A table read off a disc image along the horizontal radius (centre outwards, known
    orders) calibrates another specimen, and survives a CSV round trip."""
    m, mask, img = white["disc"]
    truth = m.simple_order
    n = img.shape[0]
    tab = CalibrationTable.from_line(
        img, (n // 2, n // 2), (n // 2, n - 4), truth[n // 2, n // 2 : n - 3], n_rows=800
    )
    assert tab.orders[-1] == pytest.approx(3.0, abs=0.02)
    tab.to_csv(tmp_path / "t.csv")
    back = CalibrationTable.from_csv(tmp_path / "t.csv")
    np.testing.assert_allclose(back.rgb, tab.rgb, atol=1e-6)
    dm, dmask, dimg = white["dent"]
    dtruth = dm.simple_order
    res = search_refined(dimg, back, [((2, 2), float(dtruth[2, 2]))], mask=dmask)
    sel = dmask & (dtruth <= 2.5)
    assert _rms((res.order - dtruth)[sel]) < 0.05


def test_rgb_bad_input(white, tmp_path):
    table = white["table"]
    m, mask, img = white["disc"]
    with pytest.raises(ValueError, match="strictly increasing"):
        CalibrationTable(np.array([0.0, 0.0]), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="needs colour"):
        search(img[..., 0], table)
    with pytest.raises(ValueError, match="outside the image or the mask"):
        search_refined(img, table, [((0, 0), 0.0)], mask=mask)
    with pytest.raises(ValueError, match="window = 0"):
        search_refined(img, table, [((80, 3), 0.0)], window=0)
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="order,R,G,B"):
        CalibrationTable.from_csv(tmp_path / "bad.csv")


# -- files, masks, profiles, comparison --------------------------------------------------------


def test_image_files_8_16_bit_and_six_step_stack(tmp_path, dent):
    import tifffile

    m, mask = dent
    imgs = _six(m)
    paths = []
    for k, i in enumerate(imgs):
        p = tmp_path / f"s{k + 1}.png"
        write_image(p, (i * 65535).round().astype(np.uint16))
        paths.append(p)
    frames = load_six_step(paths)
    assert frames[0].bit_depth == 16
    np.testing.assert_allclose(frames[3].data, imgs[3], atol=1 / 65535)
    stack = np.stack([(i * 255).round().astype(np.uint8) for i in imgs])
    tifffile.imwrite(tmp_path / "stack.tif", stack)
    frames8 = load_six_step(tmp_path / "stack.tif")
    assert frames8[5].bit_depth == 8 and frames8[5].shape == imgs[5].shape
    res = six_step(frames8, mask=mask)
    fo = unwrap_fringe_order(res)
    assert _rms((fo.order - m.fringe_order())[fo.reliable]) < 0.05
    # JPEG (lossy) colour reads too
    import imageio.v3 as iio

    rgb = (np.stack([imgs[0]] * 3, axis=-1) * 255).astype(np.uint8)
    iio.imwrite(tmp_path / "c.jpg", rgb)
    assert load_image(tmp_path / "c.jpg").data.shape == rgb.shape


def test_image_bad_input(tmp_path):
    flat = np.full((8, 8), 7, np.uint8)
    write_image(tmp_path / "flat.png", flat)
    with pytest.raises(ValueError, match="empty"):
        load_image(tmp_path / "flat.png")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_image(tmp_path / "nope.png")
    with pytest.raises(ValueError, match="exactly 6 images"):
        load_six_step([np.eye(4)] * 5)
    with pytest.raises(ValueError, match="differ in size"):
        load_six_step([np.eye(4)] * 5 + [np.eye(5)])
    with pytest.raises(ValueError, match="dark frame shape"):
        load_image(tmp_path / "flat.png", dark=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="float images must lie in"):
        normalise(np.full((4, 4), 3.0))
    with pytest.raises(ValueError, match="min_modulation"):
        six_step([np.eye(4)] * 6, min_modulation=1.5)
    with pytest.raises(ValueError, match="mask shape"):
        six_step([np.eye(4)] * 6, mask=np.ones((3, 3), bool))


def test_masks_and_profiles():
    m = circle_mask((21, 21), (10, 10), 5)
    assert m.sum() == pytest.approx(np.pi * 25, rel=0.1)
    tri = polygon_mask((10, 10), [(0, 0), (0, 9), (9, 0)])
    assert tri[1, 1] and not tri[9, 9]
    ramp = np.tile(np.arange(50.0), (20, 1))
    ramp[:, 30:33] = np.nan
    p = line_profile(ramp, (10, 0), (10, 49), pixel_size=1e-4)
    assert p.distance[-1] == pytest.approx(49e-4)
    finite = np.isfinite(p.values)
    np.testing.assert_allclose(p.values[finite], (p.distance / 1e-4)[finite], atol=1e-9)
    assert not finite[30:33].any()
    with pytest.raises(ValueError, match="outside the image"):
        line_profile(ramp, (10, 0), (10, 60))


def test_circle_profile_reads_the_map_at_its_angles():
    """A plane in (row, col) is read exactly by the bilinear reading, so on a circle of
    radius R about (r0, c0) the values are the plane at (r0 - R sin, c0 + R cos): angles
    counter-clockwise from +col with rows running down (90 deg is up, row r0 - R).
    Masked pixels give NaN, and a circle leaving the image, a zero radius or two angles
    fail."""
    rows, cols = np.mgrid[:41, :61].astype(float)
    plane = 3.0 * cols - 2.0 * rows  # exact under bilinear interpolation
    theta, v = circle_profile(plane, (20.5, 30.0), 1.2, pixel_size=0.1, n=36)
    assert theta[9] == pytest.approx(np.pi / 2)
    r, c = 20.5 - 12.0 * np.sin(theta), 30.0 + 12.0 * np.cos(theta)
    np.testing.assert_allclose(v, 3.0 * c - 2.0 * r, atol=1e-9)
    assert v[9] == pytest.approx(3.0 * 30.0 - 2.0 * 8.5)  # up: row 8.5
    holed = plane.copy()
    holed[8, 29:32] = np.nan  # under the circle's top
    _, vh = circle_profile(holed, (20.5, 30.0), 12.0, n=36)
    assert np.isnan(vh[9]) and np.isfinite(vh[0]) and np.isfinite(vh[27])
    for args, kw, words in [
        ((plane, (20.5, 30.0), 25.0), {}, "leaves the image"),
        ((plane, (20.5, 30.0), 0.0), {}, "radius = 0.0"),
        ((plane, (20.5, 30.0), 5.0), {"n": 2}, "n = 2"),
    ]:
        with pytest.raises(ValueError, match=words):
            circle_profile(*args, **kw)


def test_compare_registers_shift_and_scale(dent, tmp_path):
    """A prediction at twice the measured resolution and off-centre by (3.4, -2.2) px
    registers back to sub-pixel and leaves a residual far below the fringe order."""
    m, mask = dent
    pred = m.fringe_order()  # 160 px over 10 mm
    coarse, _ = _indentation(n=80)
    meas = np.roll(coarse.fringe_order(), (3, -2), axis=(0, 1))
    comp = compare_maps(
        pred,
        meas,
        predicted_pixel_size=10e-3 / 160,
        measured_pixel_size=10e-3 / 80,
        centre_predicted=(79.5, 79.5),
    )
    assert comp.centre_measured[0] == pytest.approx(39.5 + 3, abs=0.15)
    assert comp.centre_measured[1] == pytest.approx(39.5 - 2, abs=0.15)
    assert comp.rms < 0.03 and comp.p95 < 0.06
    comparison_figure(comp, tmp_path / "cmp.png")
    assert (tmp_path / "cmp.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="measured_pixel_size = 0"):
        compare_maps(pred, meas, predicted_pixel_size=1e-4, measured_pixel_size=0)


def test_compare_registers_maps_whose_holes_differ(dent):
    """The measurement leaves out a larger disc about the contact than the prediction
    (as a user's --exclude-circle does) and is shifted by (2.3, -1.6) px: the registered
    centre comes back within 0.15 px (filling the holes with the mean put a one-photo
    map 3.5 px off and tripled its residual)."""
    from scipy.ndimage import shift as nd_shift

    m, _ = dent
    pred = m.fringe_order()
    r, c = np.mgrid[:160, :160]
    meas = nd_shift(np.nan_to_num(pred), (2.3, -1.6), order=3)
    meas[np.hypot(r - 79.5 - 2.3, c - 79.5 + 1.6) < 35] = np.nan
    comp = compare_maps(pred, meas, predicted_pixel_size=1e-4, measured_pixel_size=1e-4)
    assert comp.centre_measured[0] == pytest.approx(79.5 + 2.3, abs=0.15)
    assert comp.centre_measured[1] == pytest.approx(79.5 - 1.6, abs=0.15)
    assert comp.rms < 0.02


def test_a_uniform_dark_frame_is_a_valid_dark_frame(tmp_path):
    """A camera's dark frame (lens cap on) is often perfectly uniform: it is subtracted,
    not refused as an empty image (it was: "the image is empty")."""
    img = (np.arange(64).reshape(8, 8) + 20).astype(np.uint8)
    write_image(tmp_path / "img.png", img)
    write_image(tmp_path / "dark.png", np.full((8, 8), 5, np.uint8))
    got = load_image(tmp_path / "img.png", dark=tmp_path / "dark.png")
    np.testing.assert_allclose(got.data, (img.astype(float) - 5) / 255)
    frames = load_six_step(
        [tmp_path / "img.png"] * 5 + [tmp_path / "img.png"], dark=str(tmp_path / "dark.png")
    )
    assert len(frames) == 6


def test_colour_spread_tells_white_light_from_single_colour_light():
    """Grey (or one-colour) fringes have their colours on a line: spread ~0, below the
    threshold; white-light fringes from the optics chart turn through all three
    colour dimensions."""
    from fringekit.analysis import MIN_COLOUR_SPREAD, colour_spread
    from fringekit.optics import PSM4_ASSUMED, Camera, colour_chart, light_source

    lam = PSM4_ASSUMED.wavenumber_grid(31)
    _, rgb = colour_chart(PSM4_ASSUMED, light_source("LED", lam), Camera(), max_order=3.0, n=400)
    white = rgb.reshape(20, 20, 3)
    assert colour_spread(white) > 5 * MIN_COLOUR_SPREAD
    grey = np.repeat(np.linspace(0, 1, 400).reshape(20, 20, 1), 3, axis=-1)
    green = grey * np.array([0.1, 0.9, 0.2]) + 0.002 * np.random.default_rng(0).random((20, 20, 3))
    assert colour_spread(grey) < 1e-12 and colour_spread(green) < MIN_COLOUR_SPREAD


@pytest.mark.parametrize("suffix", [".jpg", ".png"])
def test_a_photograph_is_read_as_its_exif_orientation_shows_it(tmp_path, suffix):
    """A camera stores a portrait photograph landscape with an EXIF orientation tag
    (6: turn 90 deg clockwise to view); rows and columns are those a viewer shows."""
    from PIL import Image

    a = np.zeros((20, 40), np.uint8)
    a[:5, :10] = 255  # top left as stored
    a[10:, 30:] = 128  # bottom right as stored
    img = Image.fromarray(a)
    exif = img.getexif()
    exif[0x0112] = 6
    path = tmp_path / f"portrait{suffix}"
    img.save(path, exif=exif, **({"quality": 95} if suffix == ".jpg" else {}))
    frame = load_image(path)
    assert frame.data.shape == (40, 20)
    assert frame.data[0, -1] == pytest.approx(1.0, abs=0.02)  # now top right
    assert frame.data[-1, 0] == pytest.approx(128 / 255, abs=0.02)  # now bottom left


def test_an_image_without_a_finite_value_is_refused(tmp_path):
    import tifffile

    nan = np.full((8, 8), np.nan, np.float32)
    tifffile.imwrite(tmp_path / "nan.tif", nan)
    with pytest.raises(ValueError, match="nan.tif: the image holds no finite value"):
        load_image(tmp_path / "nan.tif")
    nan[2, 2] = 0.5  # NaN is no data; one value alone is an empty image
    tifffile.imwrite(tmp_path / "one.tif", nan)
    with pytest.raises(ValueError, match="every pixel equals 0.5"):
        load_image(tmp_path / "one.tif")


@pytest.mark.parametrize("planes", [1, 2, 3, 4])
def test_a_16_bit_png_is_read_at_its_full_depth(tmp_path, planes):
    """16-bit grey, colour and colour + alpha PNGs keep every bit (Pillow cuts 16-bit
    colour to 8 bits); the values are the file's over 65535."""
    import png

    rng = np.random.default_rng(3)
    a = rng.integers(0, 65535, size=(6, 5, planes), dtype=np.uint16)
    a[0, 0] = 257  # not a multiple of 256: lost at 8 bits
    writer = png.Writer(5, 6, greyscale=planes <= 2, alpha=planes in (2, 4), bitdepth=16)
    with open(tmp_path / "deep.png", "wb") as fh:
        writer.write(fh, a.reshape(6, 5 * planes).tolist())
    frame = load_image(tmp_path / "deep.png")
    want = a[..., 0] if planes <= 2 else a[..., :3]  # alpha dropped
    assert frame.bit_depth == 16
    np.testing.assert_array_equal(frame.data, want / 65535.0)


def test_a_grey_png_with_alpha_is_a_grey_image(tmp_path):
    """An 8-bit grey + alpha PNG (photo editors write them) is one grey image, not "a
    stack of 64 pages"."""
    import imageio.v3 as iio

    a = np.stack(
        [np.arange(64, dtype=np.uint8).reshape(8, 8) * 4, np.full((8, 8), 255, np.uint8)], -1
    )
    iio.imwrite(tmp_path / "grey_alpha.png", a)
    frame = load_image(tmp_path / "grey_alpha.png")
    assert frame.data.shape == (8, 8) and frame.bit_depth == 8
    np.testing.assert_array_equal(frame.data, a[..., 0] / 255.0)
