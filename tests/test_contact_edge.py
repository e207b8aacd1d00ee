"""The contact radius fitted to the open gap beyond the edge (fringekit.fea.contact_edge)."""

from __future__ import annotations

import numpy as np
import pytest

from fringekit.fea.contact_edge import edge_radius

R_SPHERE = 1.75e-3


def hertz_gap(r: np.ndarray, a: float) -> np.ndarray:
    """The separation (m) between a sphere and the surface of a half-space outside a Hertz
    contact of radius ``a`` (Johnson 1985, §3.4: r^2 / 2R - a^2 / R + the displacement of
    the Hertz pressure, eq. 3.42b); 0 inside."""
    ra = np.maximum(r, a)
    u = ((2 * a * a - ra**2) * np.arcsin(a / ra) + a * np.sqrt(ra**2 - a * a)) / (np.pi * R_SPHERE)
    return np.where(r <= a, 0.0, ra**2 / (2 * R_SPHERE) - a * a / R_SPHERE + u)


def scattered_points(n: int, r_max: float, seed: int, quarter: bool = False) -> np.ndarray:
    """``n`` points spread uniformly over a disc (or its first quadrant) of radius r_max."""
    rng = np.random.default_rng(seed)
    r = r_max * np.sqrt(rng.random(n))
    t = rng.random(n) * (0.5 * np.pi if quarter else 2 * np.pi)
    return np.c_[r * np.cos(t), r * np.sin(t), np.zeros(n)]


@pytest.mark.parametrize("a", [0.4e-3, 1.17e-3])
def test_the_hertz_edge_is_found_between_scattered_points(a):
    """Scattered points, not rings: the outermost one in contact sits up to a point spacing
    inside the edge, and the fit still finds the edge within 1e-3 of the radius
    (measured 7.5e-4 inside: the quadratic through Hertz's g^(2/3) over the band)."""
    pts = scattered_points(3000, 2 * a, seed=1)
    r = np.hypot(pts[:, 0], pts[:, 1])
    g = hertz_gap(r, a)
    a_fit, sd = edge_radius(pts, g, r <= a, np.zeros(2))
    assert a_fit == pytest.approx(a, rel=1e-3)
    assert sd < 2e-4 * a


def test_a_gap_normal_to_the_sphere_at_a_large_contact_is_read_within_one_percent():
    """The solver's gap is the distance normal to the sphere, and the reference sensor's
    contact reaches 0.67 of the sphere's radius, where the normal turns by 42 degrees at
    the edge. A surface lying Hertz's separation below the sphere, its gap measured
    along the sphere's normal: the edge within 1 % (measured 0.85 % outside; a straight
    line through g^(2/3) over half a radius read the FE edge 0.7 % inside the outermost
    point in contact)."""
    a = 1.17e-3
    pts = scattered_points(4000, 2 * a, seed=6)
    r = np.hypot(pts[:, 0], pts[:, 1])
    pts, r = pts[r < 0.98 * R_SPHERE], r[r < 0.98 * R_SPHERE]
    z = -np.sqrt(R_SPHERE**2 - r**2) - hertz_gap(r, a)  # the sphere's centre at z = 0
    pts[:, 2] = z
    normal_gap = np.hypot(r, z) - R_SPHERE
    a_fit, _ = edge_radius(pts, normal_gap, r <= a, np.zeros(2))
    assert a_fit == pytest.approx(a, rel=1e-2)


def test_a_shifted_edge_is_read_as_its_radius():
    """The contact's centre 0.05 mm off the indenter's axis (a tangential load shifts it):
    the radius comes back to 1e-3, and without the shift terms (a symmetry plane claimed
    through the axis) the misfit shows in a stated sd five times larger."""
    a, shift = 1.0e-3, np.array([50e-6, -20e-6])
    pts = scattered_points(3000, 2 * a, seed=2)
    rc = np.hypot(pts[:, 0] - shift[0], pts[:, 1] - shift[1])
    g, act = hertz_gap(rc, a), rc <= a
    a_fit, sd = edge_radius(pts, g, act, np.zeros(2))
    assert a_fit == pytest.approx(a, rel=1e-3)
    wrong = edge_radius(pts, g, act, np.zeros(2), fixed_axes=(0, 1))
    assert wrong is not None and wrong[1] > 5 * sd
    half, _ = edge_radius(pts, g, act, np.zeros(2), fixed_axes=(1,))  # x shift free only
    assert abs(half / a - 1) > abs(a_fit / a - 1)


def test_a_quarter_model_fits_without_the_shift_terms():
    """A quarter model's points cover one quadrant; the symmetry planes fix the centre."""
    a = 0.8e-3
    pts = scattered_points(1000, 2 * a, seed=3, quarter=True)
    r = np.hypot(pts[:, 0], pts[:, 1])
    a_fit, _ = edge_radius(pts, hertz_gap(r, a), r <= a, np.zeros(2), fixed_axes=(0, 1))
    assert a_fit == pytest.approx(a, rel=1e-3)


def test_noise_on_the_gap_is_covered_by_the_stated_sd():
    """Gaps with 0.1 um of noise (a penalty contact's scatter at the quadrature points):
    over 200 draws the fit moves from its noise-free answer by less than two stated sd
    in at least 90 % of them. The sd is the fit's statistical error; the quadratic's own
    bias on Hertz's gap (8e-4 of the radius with these 600 points) is not in it."""
    a = 1.0e-3
    pts = scattered_points(600, 2 * a, seed=4)
    r = np.hypot(pts[:, 0], pts[:, 1])
    clean, act = hertz_gap(r, a), r <= a
    a_clean, _ = edge_radius(pts, clean, act, np.zeros(2))
    assert a_clean == pytest.approx(a, rel=1e-3)
    rng = np.random.default_rng(5)
    z = []
    for _ in range(200):
        g = clean + np.where(act, 0.0, 1e-7 * rng.standard_normal(len(r)))
        a_fit, sd = edge_radius(pts, g, act, np.zeros(2))
        z.append((a_fit - a_clean) / sd)
    assert np.mean(np.abs(z) < 2) >= 0.9


def test_too_few_open_points_near_the_edge_give_no_answer():
    """Fewer than eight open points in the band, or no point in contact: None, and the
    caller falls back to the area's circle."""
    a = 1.0e-3
    r = np.array([0.2, 0.5, 0.9, 1.1, 1.2, 1.3, 1.4]) * 1e-3
    pts = np.c_[r, np.zeros_like(r), np.zeros_like(r)]
    assert edge_radius(pts, hertz_gap(r, a), r <= a, np.zeros(2)) is None
    assert edge_radius(pts, hertz_gap(r, a), np.zeros(len(r), bool), np.zeros(2)) is None
