"""Optics: stress-optic law, Jones round trips, polariscopes, disc, white light, camera."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from fringekit.optics import (
    PSM4_ASSUMED,
    SIX_STEPS,
    Boussinesq,
    Camera,
    DiametralDisc,
    PixelGrid,
    StressOpticLaw,
    TwistedStress,
    UniformStress,
    bright_field_circular,
    characteristic,
    colour_chart,
    dark_field_circular,
    intensity,
    light_source,
    optical_map,
    plane_polariscope,
    retarder,
    rotator,
    six_step_arrangements,
    white_light_image,
    write_image,
)
from fringekit.optics.jones import from_matrix, integrate_path, qmul, qtranspose, to_matrix

LAW = PSM4_ASSUMED
RNG = np.random.default_rng(1234)


def _sigma(sxx, syy, sxy):
    s = np.zeros((3, 3))
    s[0, 0], s[1, 1], s[0, 1], s[1, 0] = sxx, syy, sxy, sxy
    s[2, 2] = -3e4  # the stress along the ray must not matter
    return s


def test_strain_optic_relation():
    law = StressOpticLaw.from_strain_optic(K=0.004, E=4e6, nu=0.49, wavelength_ref=575e-9)
    assert law.f_sigma == pytest.approx(575e-9 * 4e6 / (0.004 * 1.49), rel=1e-15)
    assert law.C(575e-9)[0] == pytest.approx(575e-9 / law.f_sigma)
    p = StressOpticLaw(400.0, dispersion="power", coefficient=0.2)
    assert p.C(500e-9)[0] == pytest.approx(p.C_ref * (575 / 500) ** 0.2)
    # same stress and path at 500 nm: retardation scales by C(lam)/C_ref * lam_ref/lam
    assert p.relative_retardation(500e-9)[0] == pytest.approx((575 / 500) ** 1.2, rel=1e-14)
    assert law.relative_retardation(575e-9)[0] == pytest.approx(1.0, rel=1e-15)
    c = StressOpticLaw(400.0, dispersion="cauchy", coefficient=1e-14)
    assert c.C(575e-9)[0] == pytest.approx(c.C_ref)
    assert c.C(450e-9)[0] > c.C_ref


def test_quaternion_algebra_matches_matrices():
    a = retarder(RNG.uniform(0, 7, 5), RNG.uniform(-2, 2, 5))
    b = qmul(rotator(RNG.uniform(-3, 3, 5)), retarder(RNG.uniform(0, 7, 5), RNG.uniform(-2, 2, 5)))
    np.testing.assert_allclose(to_matrix(qmul(a, b)), to_matrix(a) @ to_matrix(b), atol=1e-14)
    np.testing.assert_allclose(
        to_matrix(qtranspose(b)), np.swapaxes(to_matrix(b), -1, -2), atol=1e-14
    )
    np.testing.assert_allclose(from_matrix(to_matrix(b)), b, atol=1e-14)
    # the retarder is R(-t) diag(e^{-id/2}, e^{id/2}) R(t) (docs/theory.md)
    d, t = 1.3, 0.4
    R = np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
    m = R.T @ np.diag([np.exp(-0.5j * d), np.exp(0.5j * d)]) @ R
    np.testing.assert_allclose(to_matrix(retarder(d, t)), m, atol=1e-15)
    # an axis per ray broadcast over wavelengths, as the ray synthesis passes it
    dd, tt = RNG.uniform(0, 9, (6, 5)), RNG.uniform(-2, 2, (6, 1))
    one = [retarder(dd[i, w], tt[i, 0]) for i in range(6) for w in range(5)]
    np.testing.assert_allclose(retarder(dd, tt), np.reshape(one, (6, 5, 4)), atol=1e-15)


def test_characteristic_parameters_round_trip():
    d = RNG.uniform(0.05, np.pi - 0.05, 50)
    t = RNG.uniform(-np.pi / 2 + 0.01, np.pi / 2 - 0.01, 50)
    g = RNG.uniform(-1.0, 1.0, 50)
    q = qmul(rotator(g), retarder(d, t))
    d2, t2, g2 = characteristic(q)
    np.testing.assert_allclose(d2, d, atol=1e-12)
    np.testing.assert_allclose(g2, g, atol=1e-12)
    np.testing.assert_allclose(np.cos(2 * (t2 - t)), 1.0, atol=1e-12)


def test_uniform_slab_in_reflection():
    t = 3e-3
    sig = _sigma(2.0e4, -1.0e4, 6.0e3)
    field = UniformStress(sig, 0.0, t)
    m = optical_map(field, PixelGrid((3, 4), 1e-3), LAW, n_samples=5)
    ds = np.hypot(3.0e4, 1.2e4)
    n_exact = 2 * t * ds / LAW.f_sigma
    np.testing.assert_allclose(m.simple_order, n_exact, rtol=1e-13)
    np.testing.assert_allclose(m.fringe_order(), n_exact, rtol=1e-12)
    theta = 0.5 * np.arctan2(1.2e4, 3.0e4)
    np.testing.assert_allclose(m.principal_angle(), theta, atol=1e-12)
    np.testing.assert_allclose(m.rotation[..., 0], 0.0, atol=1e-12)


def test_reflection_is_retarder_of_twice_the_retardation():
    for d in (0.3, 1.1, 2.5):
        q = retarder(d, 0.37)
        refl = qmul(qtranspose(q), q)
        np.testing.assert_allclose(refl, retarder(2 * d, 0.37), atol=1e-14)


def test_twisted_retarder_closed_form():
    """Linearly twisting axes vs the exact solution of dJ/dz = -i (k/2)(... ) J."""
    t, ds, th0, rate = 3e-3, 2.0e4, 0.2, 400.0  # 1.2 rad of twist through the sheet
    field = TwistedStress(ds=ds, theta0=th0, rate=rate, z0=0.0, z1=t)
    lam = np.array([575e-9, 480e-9])
    k = LAW.retardation_per_stress_length(lam)
    m_fine = optical_map(field, PixelGrid((1, 1), 1e-3), LAW, lam, n_samples=4000, reflection=False)
    # closed form: in the frame rotating with the axes the generator is constant
    s3 = np.array([[1, 0], [0, -1]], complex)
    for w, kw in enumerate(k):
        beta = 0.5 * kw * ds  # retardation rate / 2 (rad/m)

        def rot(a):
            return np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])

        # J(z) = R(-th(z)) exp(-i (beta s3 + rate * i s2) z) R(th0); i s2 = [[0,1],[-1,0]]
        gen = -1j * beta * s3 + rate * np.array([[0, 1], [-1, 0]])
        J = rot(-(th0 + rate * t)) @ expm(gen * t) @ rot(th0)
        assert np.abs(J - to_matrix(m_fine.q[0, 0, w])).max() < 1e-6


def test_dark_plus_bright_field_is_unpolarised_intensity():
    q = retarder(RNG.uniform(0, 20, 100), RNG.uniform(-2, 2, 100))
    q = qmul(rotator(RNG.uniform(-1, 1, 100)), q)
    for dark, bright in (
        (dark_field_circular(), bright_field_circular()),
        (plane_polariscope(0.3), plane_polariscope(0.3, dark=False)),
    ):
        np.testing.assert_allclose(intensity(q, dark) + intensity(q, bright), 1.0, atol=1e-13)


def test_intensity_quadratic_form_equals_jones_products():
    """I = q^T M q against |A U e_in|^2 with explicit 2 x 2 complex products, for
    perfect arrangements (whose forms have zero terms, skipped), misaligned ones and
    non-trivial (rotating) paths, on a (P, W, 4) batch as the ray synthesis makes."""
    q = qmul(
        rotator(RNG.uniform(-1, 1, 50)), retarder(RNG.uniform(0, 20, 50), RNG.uniform(-2, 2, 50))
    )
    for arr in (
        *six_step_arrangements(analyser=0.03, qwp_in=0.02, qwp_error=0.05),
        *six_step_arrangements(),
        dark_field_circular(),
        plane_polariscope(0.4),
    ):
        e = np.einsum("ij,pjk,k->pi", arr.output_matrix(), to_matrix(q), arr.input_state())
        expected = np.sum(np.abs(e) ** 2, -1)
        np.testing.assert_allclose(intensity(q, arr), expected, atol=1e-14)
        batch = intensity(q.reshape(10, 5, 4), arr, source=2.0)
        np.testing.assert_allclose(batch, 2.0 * expected.reshape(10, 5), atol=1e-14)


def test_wavenumber_grid_and_recurrence_match_direct_trig():
    """On the wavenumber grid k is evenly spaced (for each dispersion model), and the
    recurrence path of integrate_path equals the per-wavelength trig path to 1e-12."""
    for law in (
        LAW,
        StressOpticLaw(386.0, dispersion="power", coefficient=0.3),
        StressOpticLaw(386.0, dispersion="cauchy", coefficient=2e-14),
    ):
        lam = law.wavenumber_grid(31)
        assert lam[0] == pytest.approx(400e-9, rel=1e-12) and lam[-1] == pytest.approx(700e-9)
        assert np.all(np.diff(lam) > 0)
        k = law.retardation_per_stress_length(lam)
        assert np.abs(np.diff(k, 2)).max() < 1e-12 * k.max()
    P, S = 40, 12
    ds, th = RNG.uniform(0, 2e5, (P, S)), RNG.uniform(-2, 2, (P, S))
    dz = np.full((P, S), 3e-3 / S)
    k = LAW.retardation_per_stress_length(LAW.wavenumber_grid(9))
    fast = integrate_path(ds, th, dz, k)
    slow = integrate_path(ds, th, dz, np.broadcast_to(k, (P, S, 9)))  # per-ray k: trig path
    np.testing.assert_allclose(fast, slow, atol=1e-12)
    with pytest.raises(ValueError, match="n = 0"):
        LAW.wavenumber_grid(0)


def test_six_step_table_and_seed_equations():
    th = RNG.uniform(-np.pi / 4 + 0.05, np.pi / 4 - 0.05, 400)
    d = RNG.uniform(0.05, np.pi - 0.05, 400)  # sin d > 0: away from the ambiguity
    q = retarder(d, th)
    i = np.stack([intensity(q, a, source=2.0) for a in SIX_STEPS])  # I_a/2 = 1
    expect = np.stack(
        [
            1 + np.cos(d),
            1 - np.cos(d),
            1 - np.sin(2 * th) * np.sin(d),
            1 + np.cos(2 * th) * np.sin(d),
            1 + np.sin(2 * th) * np.sin(d),
            1 - np.cos(2 * th) * np.sin(d),
        ]
    )
    np.testing.assert_allclose(i, expect, atol=1e-13)
    i1, i2, i3, i4, i5, i6 = i
    theta = 0.5 * np.arctan2(i5 - i3, i4 - i6)  # seed eq. 2, atan2 form
    np.testing.assert_allclose(theta, th, atol=1e-10)
    delta = np.arctan2((i4 - i6) / np.cos(2 * theta), i1 - i2)  # seed eq. 3, atan2 form
    np.testing.assert_allclose(delta, d, atol=1e-10)


def test_quarter_wave_error_breaks_the_table():
    q = retarder(np.array([1.0]), np.array([0.3]))
    good = np.array([intensity(q, a) for a in SIX_STEPS])
    bad = np.array([intensity(q, a) for a in six_step_arrangements(qwp_error=0.1, qwp_in=0.05)])
    assert np.abs(good - bad).max() > 1e-3


def test_diametral_disc_whole_field():
    P, D, t = 60.0, 40e-3, 6e-3
    disc = DiametralDisc(P=P, D=D, t=t)
    grid = PixelGrid((81, 81), D / 80)
    m = optical_map(disc, grid, LAW, n_samples=3, reflection=False)
    centre = m.fringe_order()[40, 40]
    assert centre == pytest.approx(8 * P / (np.pi * D * LAW.f_sigma), rel=1e-12)
    xy = grid.xy().reshape(81, 81, 2)
    exact = t * disc.stress_difference(xy) / LAW.f_sigma
    inner = m.mask & (np.hypot(xy[..., 0], xy[..., 1]) < 0.45 * D)
    err = np.abs(m.fringe_order() - exact)[inner]
    assert err.max() < 1e-3
    assert not m.mask[0, 0] and m.mask[40, 40]


def test_white_light_dark_field_zero_is_black_and_first_order_colours():
    lam = np.linspace(400e-9, 700e-9, 31)
    spec = light_source("LED", lam)
    cam = Camera()
    orders, rgb = colour_chart(LAW, spec, cam, max_order=2.0, n=201)
    np.testing.assert_allclose(rgb[0], 0.0, atol=1e-12)  # zero order is black

    def at(n):
        return rgb[np.argmin(np.abs(orders - n))]

    # Michel-Levy order (retardation at 575 nm): lavender grey, white, straw yellow,
    # red, violet (tint of passage at N = 1), blue, green.
    r, g, b = at(0.15)
    assert b > g > r and b < 0.4  # lavender/bluish grey, dim
    assert at(0.45).min() > 0.9 and np.ptp(at(0.45)) < 0.1  # first-order white
    r, g, b = at(0.6)
    assert r > 0.8 and g > 0.8 and b < 0.5  # straw yellow
    r, g, b = at(0.8)
    assert r > g + 0.3 and r > b + 0.3  # first-order red
    r, g, b = at(0.95)
    assert b > r > g  # violet, the tint of passage
    r, g, b = at(1.15)
    assert b > 0.9 and r < 0.1  # second-order blue
    r, g, b = at(1.4)
    assert g > r and g > b  # second-order green


def test_camera_quantisation_noise_and_files(tmp_path):
    lam = np.linspace(400e-9, 700e-9, 16)
    q = retarder(np.full((8, 9, 16), 2.0), np.full((8, 9, 16), 0.1))
    img8 = white_light_image(q, light_source("A", lam), Camera(bit_depth=8))
    img16 = white_light_image(
        q, light_source("A", lam), Camera(bit_depth=16, full_well=2e4, read_noise=5)
    )
    assert img8.dtype == np.uint8 and img8.shape == (8, 9, 3)
    assert img16.dtype == np.uint16 and np.ptp(img16[..., 1]) > 0  # noise present
    again = white_light_image(
        q, light_source("A", lam), Camera(bit_depth=16, full_well=2e4, read_noise=5)
    )
    np.testing.assert_array_equal(img16, again)  # seeded
    cam = Camera(sensitivities="Nikon 5100 (NPL)")
    assert white_light_image(q, light_source("D65", lam), cam).shape == (8, 9, 3)
    import imageio.v3 as iio

    for name, img in (("a.png", img8), ("b.tif", img16), ("c.png", img16[..., 1])):
        write_image(tmp_path / name, img)
        np.testing.assert_array_equal(iio.imread(tmp_path / name), img)
    with pytest.raises(ValueError, match="16-bit RGB PNG"):
        write_image(tmp_path / "d.png", img16)


def test_ray_sampling_converges_on_boussinesq():
    field = Boussinesq(F=8.0, nu=0.49, core=1.2e-3)
    grid = PixelGrid((24, 24), 0.4e-3, center=(4.6e-3, 4.6e-3))
    a = optical_map(field, grid, LAW, n_samples=64).fringe_order()
    b = optical_map(field, grid, LAW, n_samples=128).fringe_order()
    assert np.nanmax(np.abs(a - b)) < 0.01
    assert np.nanmax(a) > 1.0  # several fringes: a real test


def test_integrate_path_batch_consistency():
    ds = RNG.uniform(0, 3e4, (10, 7))
    th = RNG.uniform(-1, 1, (10, 7))
    dz = np.full((10, 7), 1e-4)
    k = LAW.retardation_per_stress_length(np.array([500e-9, 600e-9]))
    whole = integrate_path(ds, th, dz, k)
    parts = integrate_path(ds, th, dz, k, chunk=3)
    np.testing.assert_allclose(whole, parts, atol=0)
    np.testing.assert_allclose(np.linalg.norm(whole, axis=-1), 1.0, atol=1e-13)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: StressOpticLaw(400.0, wavelength_ref=1000e-9), "visible"),
        (lambda: StressOpticLaw(-1.0), "f_sigma"),
        (lambda: LAW.C(200e-9), "wavelength"),
        (lambda: PixelGrid((0, 10), 1e-4), "shape"),
        (lambda: PixelGrid((10, 10), 0.0), "pixel_size"),
        (lambda: light_source("sodium"), "light source"),
        (lambda: Camera(bit_depth=12), "bit_depth"),
        (lambda: Camera(read_noise=5.0), "full_well"),
        (lambda: Camera(sensitivities="nope").responses(np.array([5e-7])), "sensitivities"),
        (
            lambda: optical_map(
                UniformStress(np.eye(3)), PixelGrid((2, 2), 1e-3), LAW, n_samples=0
            ),
            "n_samples",
        ),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_grid_pixel_mapping_round_trip():
    g = PixelGrid((5, 7), 0.1e-3, center=(1e-3, -2e-3))
    x, y = g.pixel_to_xy(0, 0)
    assert x < 1e-3 and y > -2e-3  # row 0 is the top (largest y), col 0 the left
    r, c = g.xy_to_pixel(*g.pixel_to_xy(np.array([3.0]), np.array([5.0])))
    np.testing.assert_allclose([r[0], c[0]], [3.0, 5.0])
    np.testing.assert_allclose(g.pixel_to_xy(2, 3), (1e-3, -2e-3))


def test_layers_of_two_materials_compose_in_light_order():
    """PC then sheet: each layer with its own law; the reflected path is U^T U of the
    product J_sheet J_pc, which for non-commuting axes depends on the order."""
    from fringekit.optics import POLYCARBONATE_ASSUMED, integrate_layers, sample_rays

    grid = PixelGrid((2, 3), 1e-3)
    pc = UniformStress(_sigma(3e5, 0.0, 0.0), -4e-3, 0.0)  # axes at 0
    sheet = UniformStress(_sigma(0.0, 0.0, 1.5e4), 0.0, 3e-3)  # axes at 45 deg
    laws = [POLYCARBONATE_ASSUMED, LAW]
    s_pc, s_sh = sample_rays(pc, grid, 3), sample_rays(sheet, grid, 5)
    lam = np.array([575e-9, 480e-9])
    q, simple, valid = integrate_layers([s_pc, s_sh], laws, lam)
    assert valid.all() and q.shape == (6, 2, 4)
    for w in range(2):
        d_pc = POLYCARBONATE_ASSUMED.retardation_per_stress_length(lam[w : w + 1])[0] * 3e5 * 4e-3
        d_sh = LAW.retardation_per_stress_length(lam[w : w + 1])[0] * 3e4 * 3e-3
        u = qmul(retarder(d_sh, np.pi / 4), retarder(d_pc, 0.0))
        np.testing.assert_allclose(q[0, w], qmul(qtranspose(u), u), atol=1e-12)
        wrong = qmul(retarder(d_pc, 0.0), retarder(d_sh, np.pi / 4))
        assert np.abs(q[0, w] - qmul(qtranspose(wrong), wrong)).max() > 1e-3
    n_exact = 2 * (4e-3 * 3e5 / POLYCARBONATE_ASSUMED.f_sigma + 3e-3 * 3e4 / LAW.f_sigma)
    np.testing.assert_allclose(simple, n_exact, rtol=1e-12)
    with pytest.raises(ValueError, match="one StressOpticLaw per layer"):
        integrate_layers([s_pc], laws, lam)


def _retarder_map(order, theta, mask, guide):
    from fringekit.optics import PSM4_ASSUMED, OpticalMap, PixelGrid
    from fringekit.optics.jones import retarder

    n = order.shape[0]
    q = retarder(2 * np.pi * order, theta)[:, :, None, :]
    return OpticalMap(
        PixelGrid((n, n), 1e-4),
        np.array([PSM4_ASSUMED.wavelength_ref]),
        q,
        np.where(mask, guide, np.nan),
        mask,
        True,
        PSM4_ASSUMED,
    )


def test_branch_ambiguity_marks_every_terrace_and_nothing_under_an_exact_guide():
    """A smooth retarder field (order 0.3-2.9, radial axes) with the simple-order guide
    pushed off by up to 0.45 fringe over a patch, as turning axes do under shear: the
    per-pixel branch draws terraces there; 70 % of the wrong pixels are flagged (a wrong
    value the guide lands right on cannot be told locally), none outside the patch, and
    none at all with the exact guide."""
    n = 64
    r, c = np.mgrid[:n, :n].astype(float)
    x, y = (c - n / 2 + 0.5) / n, (n / 2 - 0.5 - r) / n
    rad = np.hypot(x, y)
    order = 0.3 + 2.6 * np.exp(-((rad / 0.3) ** 2))
    theta, mask = np.arctan2(y, x), rad > 0.06
    exact = _retarder_map(order, theta, mask, order)
    np.testing.assert_allclose(exact.fringe_order()[mask], order[mask], atol=1e-9)
    assert not exact.branch_ambiguous().any()
    patch = np.exp(-(((x + 0.15) / 0.08) ** 2 + ((y - 0.1) / 0.12) ** 2))
    off = _retarder_map(order, theta, mask, order + 0.45 * patch)
    wrong = mask & (np.abs(off.fringe_order() - order) > 0.05)
    flagged = off.branch_ambiguous()
    assert wrong.sum() > 20 and flagged[wrong].mean() > 0.65
    assert flagged.sum() < 4 * wrong.sum() and not flagged[patch < 0.05].any()


def test_frozen_stress_and_turned_axes_add_as_stress_tensors():
    """RaySamples.frozen: a stress frozen evenly through the layer adds to the sampled
    one as a tensor would (a uniform slab of the two stresses summed gives the same ds and
    angle), and turning the samples by t reads a stress in axes turned by -t (the same
    tensor rotated by t); zero and no turn change nothing."""
    from fringekit.optics import sample_rays

    t_mm, n = 2e-3, 5
    load = np.array([[1.2e5, 3.0e4, 0.0], [3.0e4, -2.0e4, 0.0], [0.0, 0.0, -1e5]])
    grid = PixelGrid((2, 3), 1e-3)
    rays = sample_rays(UniformStress(load, z0=0.0, z1=t_mm), grid, n_samples=n)
    rng = np.random.default_rng(3)
    ab = rng.normal(0.0, 80.0, (grid.n_pixels, 2))  # Pa m: up to ~0.1 MPa through 2 mm
    turn = 0.4
    got = rays.frozen(ab, turn)
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    for p in range(grid.n_pixels):
        a, b = ab[p] / t_mm
        frozen = np.array([[a / 2, b / 2, 0.0], [b / 2, -a / 2, 0.0], [0.0, 0.0, 0.0]])
        want = sample_rays(
            UniformStress(rot @ load @ rot.T + frozen, z0=0.0, z1=t_mm), grid, n_samples=n
        ).per_pixel()
        assert np.allclose(got.ds[p], want.ds[p], rtol=1e-12, atol=1e-6)
        assert np.allclose(got.theta[p], want.theta[p], atol=1e-12)
    same = rays.frozen()
    plain = rays.per_pixel()
    assert np.allclose(same.ds, plain.ds) and np.allclose(same.theta, plain.theta)
