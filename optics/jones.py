r"""Jones calculus for the photoelastic path, in SU(2) (unit quaternion) form.

Slab k (``docs/theory.md``, "Jones integration"):
J_k = R(-theta) diag(e^{-i d/2}, e^{+i d/2}) R(theta)
with R(a) = [[cos a, sin a], [-sin a, cos a]]. With the Pauli matrices s1, s2, s3,

    J_k = cos(d/2) I - i sin(d/2) (sin 2theta s1 + cos 2theta s3),

so every path matrix is U = w I - i (x s1 + y s2 + z s3), stored as q = (w, x, y, z)
on the last axis. Products are quaternion products (4 reals instead of 2x2 complex).
A rotator R(g) is (cos g, 0, -sin g, 0). The reflection double pass in the unfolded
frame is U_refl = U^T U (U^T flips the sign of y).

Characteristic parameters (Aben, Integrated Photoelasticity, 1979): any U equals a
retarder (Delta*, theta*) followed by a rotator gamma*; with
Delta* in [0, pi]:  cos(D/2) = sqrt(w^2 + y^2), gamma = atan2(-y, w),
theta = (atan2(x, z) + gamma) / 2.
"""

from __future__ import annotations

import numpy as np

from fringekit._threads import thread_pool, usable_cores

__all__ = [
    "secondary_principal",
    "principal_from_components",
    "retarder",
    "retarder_spectrum",
    "rotator",
    "qmul",
    "qtranspose",
    "to_matrix",
    "from_matrix",
    "integrate_path",
    "characteristic",
]


def secondary_principal(sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Secondary principal stress difference and angle for rays along z.

    ds = sqrt((sxx - syy)^2 + 4 sxy^2),  tan 2 theta = 2 sxy / (sxx - syy)
    (``docs/theory.md``).

    Parameters
    ----------
    sigma : (..., 3, 3) float array
        Cauchy stress (Pa).

    Returns
    -------
    ds : (...) float array
        Secondary principal stress difference (Pa).
    theta : (...) float array
        Its angle from the x axis (rad), in (-pi/2, pi/2].

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import secondary_principal
    >>> ds, theta = secondary_principal(np.array([[1e5, 5e4, 0], [5e4, 0, 0], [0, 0, -2e5]]))
    >>> round(float(ds)), round(float(np.degrees(theta)), 1)  # Pa, degrees
    (141421, 22.5)
    """
    return principal_from_components(sigma[..., 0, 0] - sigma[..., 1, 1], 2.0 * sigma[..., 0, 1])


def principal_from_components(a, b) -> tuple[np.ndarray, np.ndarray]:
    """ds = hypot(a, b) (Pa) and theta = atan2(b, a) / 2 (rad) from a = sigma_xx - sigma_yy
    and b = 2 sigma_xy, the two stress combinations the secondary principal values are
    linear in (so they can be interpolated before this step)."""
    return np.hypot(a, b), 0.5 * np.arctan2(b, a)


def retarder(delta, theta) -> np.ndarray:
    """Quaternion (..., 4) of a linear retarder.

    Parameters
    ----------
    delta : float or array
        Retardation (rad).
    theta : float or array
        Fast-axis angle (rad), broadcast against ``delta``. Each angle's trigonometry is
        evaluated on its own shape (an axis per ray shared by W wavelengths costs P, not
        P * W).

    Returns
    -------
    (..., 4) float array
        Unit quaternions (w, x, y, z) of J = cos(d/2) I - i sin(d/2) (sin 2t s1 + cos 2t s3).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import retarder
    >>> retarder(np.pi, np.pi / 8).round(4).tolist()  # a half-wave plate at 22.5 degrees
    [0.0, 0.7071, 0.0, 0.7071]
    >>> retarder(np.zeros((2, 3)), 0.0).shape
    (2, 3, 4)
    """
    delta, theta = np.asarray(delta, float), np.asarray(theta, float)
    half = 0.5 * delta
    s = np.sin(half)
    out = np.empty(np.broadcast_shapes(delta.shape, theta.shape) + (4,))
    out[..., 0] = np.cos(half)
    out[..., 1] = s * np.sin(2 * theta)
    out[..., 2] = 0.0
    out[..., 3] = s * np.cos(2 * theta)
    return out


def rotator(gamma) -> np.ndarray:
    """Quaternion of the rotator R(gamma) = [[cos g, sin g], [-sin g, cos g]].

    Parameters
    ----------
    gamma : float or array
        Rotation (rad).

    Returns
    -------
    (..., 4) float array
        Unit quaternions (cos g, 0, -sin g, 0).

    Examples
    --------
    >>> from fringekit.optics import rotator
    >>> rotator(0.3).round(4).tolist()
    [0.9553, 0.0, -0.2955, 0.0]
    """
    g = np.asarray(gamma, float)
    return np.stack([np.cos(g), np.zeros_like(g), -np.sin(g), np.zeros_like(g)], -1)


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product a * b (apply b first, then a) of quaternions (..., 4)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + bw * ax + ay * bz - az * by,
            aw * by + bw * ay + az * bx - ax * bz,
            aw * bz + bw * az + ax * by - ay * bx,
        ],
        axis=-1,
    )


def qtranspose(q: np.ndarray) -> np.ndarray:
    """Quaternion of the matrix transpose U^T."""
    out = np.array(q, copy=True)
    out[..., 2] *= -1
    return out


def to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 2, 2) complex Jones matrix of quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(np.asarray(q), -1, 0)
    m = np.empty(np.shape(w) + (2, 2), dtype=np.complex128)
    m[..., 0, 0] = w - 1j * z
    m[..., 0, 1] = -y - 1j * x
    m[..., 1, 0] = y - 1j * x
    m[..., 1, 1] = w + 1j * z
    return m


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Quaternion (..., 4) of an SU(2) Jones matrix (..., 2, 2) (inverse of to_matrix)."""
    w = 0.5 * (m[..., 0, 0] + m[..., 1, 1]).real
    z = 0.5 * (m[..., 1, 1] - m[..., 0, 0]).imag
    x = -0.5 * (m[..., 0, 1] + m[..., 1, 0]).imag
    y = 0.5 * (m[..., 1, 0] - m[..., 0, 1]).real
    return np.stack([w, x, y, z], axis=-1)


def _arithmetic(rows: np.ndarray):
    """(first (n,), step (n,)) when every row of ``rows`` (n, W) is an arithmetic
    sequence (W >= 4; to 1e-9 of its largest value, a phase error below 1e-9 of a ray's
    retardation), else None."""
    W = rows.shape[1]
    if W < 4:
        return None
    step = (rows[:, -1] - rows[:, 0]) / (W - 1)
    dev = np.abs(rows - rows[:, :1] - step[:, None] * np.arange(W)).max(axis=1)
    if np.all(dev <= 1e-9 * np.abs(rows).max(axis=1)):
        return rows[:, 0], step
    return None


def retarder_spectrum(a: np.ndarray, b: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Quaternions (P, W, 4) of linear retarders of retardation hypot(a, b) k (rad) at
    each wavelength and fast axis atan2(b, a) / 2: :func:`retarder` of a summed slab
    vector through W wavelengths.

    Parameters
    ----------
    a, b : (P,) float arrays
        The vector's components (Pa m; (sigma_xx - sigma_yy) dz and 2 sigma_xy dz).
    k : (W,) float array
        2 pi C(lam) / lam (rad/(Pa m)) per wavelength. On a wavenumber grid (an
        arithmetic sequence, W >= 4) the W half-angles' cos and sin come from one complex
        exponential and a running product (as :func:`integrate_path`), not 2 W trig calls
        per ray; the axis' from the components, without an angle.

    Returns
    -------
    (P, W, 4) float array

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics.jones import retarder, retarder_spectrum
    >>> k = np.linspace(1.0, 2.0, 5)
    >>> q = retarder_spectrum(np.array([0.3]), np.array([0.4]), k)
    >>> bool(np.allclose(q, retarder(0.5 * k, 0.5 * np.arctan2(0.4, 0.3))))
    True
    """
    a, b, k = np.asarray(a, float), np.asarray(b, float), np.asarray(k, float)
    mag = np.hypot(a, b)
    arith = _arithmetic(k.reshape(1, -1))
    if arith is None:  # a few wavelengths: retarder() itself
        return retarder(mag[:, None] * k[None, :], 0.5 * np.arctan2(b, a)[:, None])
    e = np.empty((len(mag), len(k)), np.complex128)
    e[:, 0] = np.exp(0.5j * arith[0][0] * mag)
    e[:, 1:] = np.exp(0.5j * arith[1][0] * mag)[:, None]
    np.cumprod(e, axis=1, out=e)
    cw, sw = e.real, e.imag
    inv = np.divide(1.0, mag, out=np.zeros_like(mag), where=mag > 0)
    s2t = (b * inv)[:, None]  # sin and cos of twice the axis (axis 0 where mag = 0)
    c2t = np.where(mag > 0, a * inv, 1.0)[:, None]
    out = np.empty((len(mag), len(k), 4))
    out[..., 0] = cw
    out[..., 1] = sw * s2t
    out[..., 2] = 0.0
    out[..., 3] = sw * c2t
    return out


def integrate_path(
    ds: np.ndarray, theta: np.ndarray, dz: np.ndarray, k: np.ndarray, *, chunk: int = 4096
) -> np.ndarray:
    """Path matrix U = J_S ... J_1 for every ray and wavelength.

    Parameters
    ----------
    ds, theta, dz : (P, S) float arrays
        Secondary principal stress difference (Pa), angle (rad) and slab thickness (m),
        slab 1 first (where the light enters).
    k : (W,), (S, W) or (P, S, W) float array
        2 pi C(lam) / lam (rad/(Pa m)) per wavelength, optionally per slab (layers of
        different materials along every ray) or per ray and slab.
    chunk : int
        Rays per block (bounds memory at ~ chunk * W * 40 bytes).

    Returns
    -------
    (P, W, 4) float array
        Path quaternions.

    Examples
    --------
    Three 1 mm slabs under 0.1 MPa with fixed axes: one retarder of 0.777 fringe,
    whose characteristic retardation is folded to [0, pi]:

    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, characteristic, integrate_path
    >>> k = PSM4_ASSUMED.retardation_per_stress_length([575e-9])
    >>> q = integrate_path(np.full((1, 3), 1e5), np.zeros((1, 3)), np.full((1, 3), 1e-3), k)
    >>> q.shape, round(float(characteristic(q)[0][0, 0] / (2 * np.pi)), 4)  # 1 - 0.777
    ((1, 1, 4), 0.2226)
    """
    ds, theta, dz = (np.asarray(a, float) for a in (ds, theta, dz))
    P, S = ds.shape
    k = np.asarray(k, float)
    if k.ndim == 2 and k.shape[0] != S:
        raise ValueError(
            f"k shape {k.shape} does not match {S} slabs; give (W,), (S, W) or (P, S, W)"
        )
    per_ray_slab = k.ndim == 3
    per_slab = k.ndim == 2
    W = k.shape[-1]
    # Slabs whose k is an arithmetic sequence over the wavelengths (a wavenumber grid,
    # optics.stressoptic.wavenumber_grid) get cos/sin of the W half-angles from one
    # complex exponential and a running product instead of 2 W trig calls per ray.
    rows = k.reshape(S, W) if per_slab else k.reshape(1, W) if k.ndim == 1 else None
    arith = _arithmetic(rows) if rows is not None else None
    if arith is not None:
        arith = tuple(np.broadcast_to(a, (S,)) for a in arith)
    out = np.empty((P, W, 4))

    def block(start: int) -> None:
        sl = slice(start, min(P, start + chunk))
        n = sl.stop - sl.start
        w = np.ones((n, W))
        x = np.zeros((n, W))
        y = np.zeros((n, W))
        z = np.zeros((n, W))
        c2 = np.cos(2 * theta[sl])
        s2 = np.sin(2 * theta[sl])
        phase = ds[sl] * dz[sl]
        for s in range(S):  # loop over ray samples; vectorised over rays and wavelengths
            if arith is not None:
                e = np.empty((n, W), np.complex128)
                e[:, 0] = np.exp(0.5j * arith[0][s] * phase[:, s])
                e[:, 1:] = np.exp(0.5j * arith[1][s] * phase[:, s])[:, None]
                np.cumprod(e, axis=1, out=e)  # e^{i h (k0 + j dk)} = e^{i h k0} (e^{i h dk})^j
                sw, sn = e.real, e.imag
            else:
                kk = k[sl, s, :] if per_ray_slab else k[None, s, :] if per_slab else k[None, :]
                half = 0.5 * phase[:, s, None] * kk
                sw, sn = np.cos(half), np.sin(half)
            sx, sz = sn * s2[:, s, None], sn * c2[:, s, None]
            # q <- J_s * q with J_s = (sw, sx, 0, sz)
            w, x, y, z = (
                sw * w - sx * x - sz * z,
                sw * x + w * sx - sz * y,
                sw * y + sz * x - sx * z,
                sw * z + w * sz + sx * y,
            )
        out[sl, :, 0], out[sl, :, 1], out[sl, :, 2], out[sl, :, 3] = w, x, y, z

    # numpy's elementwise loops release the GIL: blocks run on the cores in threads
    starts = range(0, P, chunk)
    pool = None
    if len(starts) > 1:
        pool = thread_pool() if usable_cores() > 1 else None
    if pool is not None:
        list(pool.map(block, starts))
    else:
        for start in starts:
            block(start)
    return out


def characteristic(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Aben's characteristic parameters of U = R(gamma) . Retarder(Delta, theta).

    Jones matrices are taken up to a global phase, so -U and U give the same parameters.

    Parameters
    ----------
    q : (..., 4) float array
        Path quaternions.

    Returns
    -------
    delta : (...) float array
        Characteristic retardation Delta* in [0, pi] (rad).
    theta : (...) float array
        Characteristic angle theta* in [-pi/2, pi/2) (rad).
    gamma : (...) float array
        Characteristic rotation gamma* in [-pi/2, pi/2] (rad; sign per :func:`rotator`).

    Examples
    --------
    >>> from fringekit.optics import characteristic, retarder, rotator
    >>> from fringekit.optics.jones import qmul
    >>> u = qmul(rotator(0.3), retarder(1.0, 0.2))  # retarder first, then the rotator
    >>> [round(float(v), 4) for v in characteristic(u)]
    [1.0, 0.2, 0.3]
    """
    q = np.asarray(q)
    q = np.where(q[..., :1] < 0, -q, q)  # -U is U up to a global phase: keep |gamma| <= pi/2
    w, x, y, z = np.moveaxis(q, -1, 0)
    delta = 2 * np.arctan2(np.hypot(x, z), np.hypot(w, y))
    gamma = np.arctan2(-y, w)
    theta = 0.5 * np.arctan2(x, z) + 0.5 * gamma
    theta = (theta + np.pi / 2) % np.pi - np.pi / 2
    return delta, theta, gamma
