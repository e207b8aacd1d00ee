"""The polar ray lattice a response library stores one indenter's field on.

One indenter at the origin, tangential load along +x. Its field is mirror-symmetric about
y = 0 (the sheet is isotropic and laterally large), so rays are stored on a polar lattice
over the half plane: radii ``r`` (graded, finest near the contact) and angles
``phi`` in [0, pi]. Along each ray the stress is kept slab by slab (``S`` slabs of equal
thickness through the deformed sheet, as :func:`optics.sample_rays` takes them) as the two
combinations the optics needs, in POLAR components and multiplied by the slab thickness:

    A = (sigma_rr - sigma_pp) dz,   B = 2 sigma_rp dz     (Pa m)

Polar components make the normal-load field independent of phi (exact interpolation in
phi), and the products with dz make fields of several indenters add slab by slab on one
ray (the superposition of :mod:`fringekit.library.synth`). A Cartesian pair (a, b) =
(sigma_xx - sigma_yy, 2 sigma_xy) at polar angle alpha is the polar pair turned by 2 alpha
(the transformation of a plane stress tensor, e.g. Timoshenko and Goodier, Theory of
Elasticity, section 9):

    a = A cos 2alpha - B sin 2alpha,   b = A sin 2alpha + B cos 2alpha

Under the mirror y -> -y, sigma_rp changes sign: a point at -phi sees (A, -B) of +phi.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fringekit.optics import sample_points

__all__ = [
    "PolarLattice",
    "default_lattice",
    "interpolate_turned",
    "polar_to_cartesian",
    "sample_lattice",
]


@dataclass(frozen=True)
class PolarLattice:
    """Ray positions of a library field.

    Attributes
    ----------
    r : (R,) radii (m), increasing, r[0] = 0.
    phi : (F,) angles (rad), uniform over [0, pi].
    n_slabs : int — slabs per ray.
    """

    r: np.ndarray
    phi: np.ndarray
    n_slabs: int

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.r), len(self.phi)

    @property
    def r_max(self) -> float:
        return float(self.r[-1])

    def xy(self) -> np.ndarray:
        """(R * F, 2) node positions (m), r-major."""
        rr, pp = np.meshgrid(self.r, self.phi, indexing="ij")
        return np.column_stack([(rr * np.cos(pp)).ravel(), (rr * np.sin(pp)).ravel()])


def default_lattice(
    r_max: float,
    *,
    fine_step: float,
    fine_radius: float,
    growth: float = 1.08,
    phi_step_deg: float = 5.0,
    n_slabs: int = 16,
) -> PolarLattice:
    """Radii at ``fine_step`` (m) out to ``fine_radius`` (m), then growing by ``growth``
    per node out to ``r_max`` (m); angles every ``phi_step_deg`` over [0, 180] deg."""
    if not (0 < fine_step < fine_radius < r_max):
        raise ValueError(
            f"lattice radii: need 0 < fine_step ({fine_step}) < fine_radius ({fine_radius}) "
            f"< r_max ({r_max}) (m)"
        )
    r = list(np.arange(0.0, fine_radius + 0.5 * fine_step, fine_step))
    step = fine_step
    while r[-1] < r_max:
        step *= growth
        r.append(min(r[-1] + step, r_max))
    n_phi = int(round(180.0 / phi_step_deg)) + 1
    return PolarLattice(r=np.array(r), phi=np.linspace(0.0, np.pi, n_phi), n_slabs=int(n_slabs))


def polar_to_cartesian(A, B, alpha, out=None) -> np.ndarray:
    """Cartesian pairs (..., 2) (a, b) of polar pairs (A, B) at polar angle ``alpha``
    (rad, broadcast against the last-but-slab axes): the 2 alpha rotation of the module
    docstring, in A's precision, written into ``out`` (..., 2) when given."""
    return _turn(A, B, np.cos(2 * alpha), np.sin(2 * alpha), out)


def _turn(A, B, c, s, out=None, sign=1.0) -> np.ndarray:
    """:func:`polar_to_cartesian` with c = cos 2 alpha and s = sin 2 alpha given, of the
    pairs (A, ``sign`` B)."""
    c, s = c.astype(A.dtype), s.astype(A.dtype)
    sb, cb = (sign * s).astype(A.dtype), (sign * c).astype(A.dtype)
    out = np.empty((*np.broadcast_shapes(A.shape, B.shape), 2), A.dtype) if out is None else out
    np.multiply(A, c, out=out[..., 0])
    out[..., 0] -= B * sb
    np.multiply(A, s, out=out[..., 1])
    out[..., 1] += B * cb
    return out


def _fill_inward(v: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Nodes without a ray (inside the contact) take the first valid value outward at the
    same angle (holes further out, none expected, the last valid one inward), so that
    interpolation across the contact edge and between loads stays continuous; those
    nodes are masked when images are made. v: (R, F, ...), valid: (R, F)."""
    R, F = valid.shape
    first = np.argmax(valid, axis=0)  # (F,); 0 for an angle without any valid node
    idx = np.maximum.accumulate(np.where(valid, np.arange(R)[:, None], -1), axis=0)
    idx = np.where(idx < 0, first[None, :], idx)
    return v[idx, np.arange(F)[None, :]]


def sample_lattice(field, lattice: PolarLattice) -> tuple[np.ndarray, np.ndarray]:
    """One field on the lattice.

    Parameters
    ----------
    field : optics.FEMStressField (or any field with ``z_range`` and ``stress``), in the
        frame of the library: indenter axis at the origin, tangential load along +x.
    lattice : PolarLattice

    Returns
    -------
    AB : (R, F, S, 2) float32 — A and B per slab (Pa m), filled inward of the contact.
    valid : (R, F) bool — nodes whose ray crosses the sheet outside the contact.
    """
    R, F = lattice.shape
    xy = lattice.xy()
    a, b, dz, ok = sample_points(field, xy, lattice.n_slabs)
    alpha = np.arctan2(xy[:, 1], xy[:, 0])[:, None]
    c, s = np.cos(2 * alpha), np.sin(2 * alpha)
    A = (a * c + b * s) * dz[:, None]  # the inverse of polar_to_cartesian
    B = (-a * s + b * c) * dz[:, None]
    AB = np.stack([A, B], axis=-1).reshape(R, F, lattice.n_slabs, 2)
    valid = ok.reshape(R, F)
    return _fill_inward(AB, valid).astype(np.float32), valid


def interpolate_turned(AB: np.ndarray, lattice: PolarLattice, dx, dy, psi) -> np.ndarray:
    """Cartesian slab pairs of a lattice field turned to the tangential direction ``psi``.

    Parameters
    ----------
    AB : (R, F, S, 2) polar slab pairs on ``lattice`` (any S: a slab-summed field, S = 1,
        interpolates 16 times cheaper).
    lattice : PolarLattice
    dx, dy : (...) float arrays, positions relative to the indenter axis (m)
    psi : float or array broadcast against ``dx``, direction of the tangential load (rad
        from +x)

    Returns
    -------
    (..., S, 2) float32 (a, b) = ((sigma_xx - sigma_yy) dz, 2 sigma_xy dz) in the sensor
    frame, bilinear in (r, phi), zero at and beyond ``lattice.r_max``.
    """
    dx, dy, psi = (np.asarray(a, float) for a in (dx, dy, psi))
    shape = np.broadcast_shapes(dx.shape, dy.shape, psi.shape)
    cp, sp = np.cos(psi), np.sin(psi)  # one per direction, broadcast below
    dx, dy = np.broadcast_to(dx, shape), np.broadcast_to(dy, shape)
    cp, sp = np.broadcast_to(cp, shape), np.broadcast_to(sp, shape)
    r2 = dx * dx + dy * dy
    S = AB.shape[2]
    out = np.zeros((*shape, S, 2), np.float32)
    near = r2 < lattice.r_max**2
    everywhere = bool(near.all())
    if everywhere:  # the usual case: every point near, no gather
        dx, dy, cp, sp, r2 = (a.reshape(-1) for a in (dx, dy, cp, sp, r2))
    else:
        dx, dy, cp, sp, r2 = (a[near] for a in (dx, dy, cp, sp, r2))
    if not r2.size:
        return out
    u = cp * dx + sp * dy  # the point in the frame of the turned field
    v = cp * dy - sp * dx
    rn = np.sqrt(r2)
    pn = np.arctan2(np.abs(v), u)  # [0, pi]; v < 0 is the mirror image
    ir = np.clip(np.searchsorted(lattice.r, rn) - 1, 0, len(lattice.r) - 2)
    tr = ((rn - lattice.r[ir]) / (lattice.r[ir + 1] - lattice.r[ir])).astype(np.float32)
    dphi = lattice.phi[1] - lattice.phi[0]
    ip = np.clip((pn / dphi).astype(int), 0, len(lattice.phi) - 2)
    tp = (pn / dphi - ip).astype(np.float32)
    # the four corners of each point's cell as rows of the flattened (R * F, S * 2) field
    # (np.take, 3-4 times faster than fancy indexing here), weighted in float32 (the
    # field's precision) with in-place products and sums
    F = AB.shape[1]
    flat = AB.reshape(-1, S * 2)
    k = ir * F + ip
    weights = ((1 - tr) * (1 - tp), tr * (1 - tp), (1 - tr) * tp, tr * tp)
    val = np.take(flat, k, axis=0)
    val *= weights[0][:, None]
    tmp = np.empty_like(val)
    for corner, w in zip((k + F, k + 1, k + F + 1), weights[1:], strict=True):  # 3 corners
        np.take(flat, corner, axis=0, out=tmp)
        tmp *= w[:, None]
        val += tmp
    val = val.reshape(-1, S, 2)
    # cos and sin of twice the polar angle of (dx, dy), without the angle: (dx^2 - dy^2,
    # 2 dx dy) / r^2 (the axis itself, r = 0, as angle 0)
    inv = np.divide(1.0, r2, out=np.zeros_like(r2), where=r2 > 0)
    c2 = np.where(r2 > 0, (dx * dx - dy * dy) * inv, 1.0)[:, None]
    s2 = (2.0 * dx * dy * inv)[:, None]
    mirror = np.where(v < 0, -1.0, 1.0)[:, None]  # B changes sign below the axis
    turned = out.reshape(-1, S, 2) if everywhere else None
    turned = _turn(val[..., 0], val[..., 1], c2, s2, turned, mirror)
    if not everywhere:
        out[near] = turned
    return out
