"""Pixel grid over the sheet and vertical ray sampling.

Pixel (row, col) has its centre at

    x = x0 + (col - (cols - 1) / 2) * pixel_size
    y = y0 - (row - (rows - 1) / 2) * pixel_size

so row 0 is the top of the image (largest y), as a camera looking down the z axis
from the contact side would show it; :meth:`PixelGrid.pixel_to_xy` is the one place
this mapping lives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import binary_dilation
from tqdm.auto import tqdm

from .jones import principal_from_components

__all__ = ["PixelGrid", "RaySamples", "sample_points", "sample_rays"]


@dataclass(frozen=True)
class PixelGrid:
    """A rectangular camera grid over the sheet.

    Pixel (row, col) has its centre at x = x0 + (col - (cols - 1) / 2) pixel_size,
    y = y0 - (row - (rows - 1) / 2) pixel_size: row 0 is the top of the image (largest
    y), as a camera looking down the z axis from the contact side shows it.

    Parameters
    ----------
    shape : (rows, cols)
        Image shape in pixels (>= 1 each).
    pixel_size : float
        Pixel pitch on the sheet (m).
    center : (x0, y0)
        Sheet coordinates of the image centre (m).

    Raises
    ------
    ValueError
        A shape below 1 x 1 or a pitch that is not > 0.

    Examples
    --------
    >>> from fringekit.optics import PixelGrid
    >>> grid = PixelGrid((3, 4), pixel_size=1e-3)
    >>> grid.n_pixels, grid.xy().shape
    (12, (12, 2))
    >>> [float(v) for v in grid.pixel_to_xy(0, 0)]  # top left pixel centre, m
    [-0.0015, 0.001]
    >>> [float(v) for v in grid.xy_to_pixel(-0.0015, 0.001)]
    [0.0, 0.0]
    >>> PixelGrid.from_field_of_view(20e-3, (96, 96)).pixel_size  # m
    0.00020833333333333335
    """

    shape: tuple[int, int]
    pixel_size: float
    center: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        rows, cols = self.shape
        if int(rows) < 1 or int(cols) < 1:
            raise ValueError(f"shape = {self.shape!r} is not allowed; need at least 1 x 1 pixels")
        if not (math.isfinite(self.pixel_size) and self.pixel_size > 0):
            raise ValueError(f"pixel_size = {self.pixel_size!r} is not allowed; it must be > 0 (m)")
        object.__setattr__(self, "shape", (int(rows), int(cols)))

    @classmethod
    def from_field_of_view(cls, width: float, shape: tuple[int, int], center=(0.0, 0.0)):
        """Grid of ``shape`` whose columns span ``width`` (m) centre to centre plus one pitch."""
        if not width > 0:
            raise ValueError(f"width = {width!r} is not allowed; it must be > 0 (m)")
        return cls(shape=shape, pixel_size=width / shape[1], center=center)

    @classmethod
    def about_origin(cls, shape: tuple[int, int], pixel_size: float, origin_rc):
        """Grid of ``shape`` whose pixel ``origin_rc`` (row, col; fractional) lies at the
        sheet's origin, x = y = 0."""
        rows, cols = shape
        r0, c0 = origin_rc
        p = pixel_size
        return cls(shape, p, (-(c0 - (cols - 1) / 2) * p, (r0 - (rows - 1) / 2) * p))

    @property
    def n_pixels(self) -> int:
        return self.shape[0] * self.shape[1]

    def pixel_to_xy(self, rows, cols) -> tuple[np.ndarray, np.ndarray]:
        """Sheet coordinates (m) of pixel centres (any broadcastable row/col arrays)."""
        r, c = np.asarray(rows, float), np.asarray(cols, float)
        x = self.center[0] + (c - (self.shape[1] - 1) / 2) * self.pixel_size
        y = self.center[1] - (r - (self.shape[0] - 1) / 2) * self.pixel_size
        return x, y

    def xy_to_pixel(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of :meth:`pixel_to_xy` (fractional row, col)."""
        c = (np.asarray(x) - self.center[0]) / self.pixel_size + (self.shape[1] - 1) / 2
        r = -(np.asarray(y) - self.center[1]) / self.pixel_size + (self.shape[0] - 1) / 2
        return r, c

    def xy(self) -> np.ndarray:
        """(rows * cols, 2) pixel-centre coordinates in row-major order (m)."""
        rr, cc = np.meshgrid(np.arange(self.shape[0]), np.arange(self.shape[1]), indexing="ij")
        x, y = self.pixel_to_xy(rr.ravel(), cc.ravel())
        return np.stack([x, y], axis=1)


@dataclass(frozen=True)
class RaySamples:
    """Stress sampled along vertical rays (made by :func:`sample_rays`).

    Only what the optics needs is kept: the secondary principal stress difference and
    angle at each slab midpoint (optics.jones.secondary_principal), not the full tensor.
    Pixels whose rays are mirror images of each other under the field's symmetry planes
    (``field.fold_xy``) share one row; the mirror flips the shear stresses that set the
    angle, so such a pixel sees its row with theta -> -theta.

    Parameters
    ----------
    ds : (R, S) float array
        Secondary principal stress difference (Pa), one row per distinct ray.
    theta : (R, S) float array
        Secondary principal angle (rad).
    dz : (R, S) float array
        Slab thickness along the ray (m).
    valid : (P,) bool array
        Pixels whose ray crosses the photoelastic layer.
    index : (P,) int array
        The row of each pixel's ray.
    mirror : (P,) bool array
        The pixel sees its row mirrored (theta -> -theta).

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import sample_rays
    >>> rays = sample_rays(field, PixelGrid((2, 2), 1e-3), n_samples=4)
    >>> rays.ds.shape, rays.n_pixels, float(rays.dz[0, 0])  # rows, slabs; m
    ((4, 4), 4, 0.00075)
    >>> rays.per_pixel().index.tolist()
    [0, 1, 2, 3]
    """

    ds: np.ndarray
    theta: np.ndarray
    dz: np.ndarray
    valid: np.ndarray
    index: np.ndarray
    mirror: np.ndarray

    @property
    def n_pixels(self) -> int:
        return len(self.valid)

    def per_pixel(self) -> RaySamples:
        """The same samples with one row per pixel (mirrors applied, invalid rays zero)."""
        sign = np.where(self.mirror, -1.0, 1.0)[:, None]
        keep = self.valid[:, None]
        return RaySamples(
            ds=np.where(keep, self.ds[self.index], 0.0),
            theta=np.where(keep, sign * self.theta[self.index], 0.0),
            dz=np.where(keep, self.dz[self.index], 0.0),
            valid=self.valid,
            index=np.arange(self.n_pixels),
            mirror=np.zeros(self.n_pixels, bool),
        )

    def frozen(self, ab: np.ndarray | None = None, turn: float = 0.0) -> RaySamples:
        """The samples per pixel (:meth:`per_pixel`) with every slab's angle turned by
        ``turn`` (rad; into axes turned by -turn) and a stress frozen evenly through the
        layer added: ``ab`` (P, 2) its slab pair summed through the thickness,
        ((sigma_xx - sigma_yy) dz, 2 sigma_xy dz) in the turned axes (Pa m), None for
        none. The stress components add slab by slab (a = ds cos 2 theta, b = ds sin 2
        theta), as a residual birefringence frozen into the sheet composes with a load's
        (``fringekit.inversion.model.ImageModel.residual_ab``).

        Examples
        --------
        >>> import numpy as np
        >>> from fringekit.optics import PixelGrid, UniformStress, sample_rays
        >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=2e-3)
        >>> rays = sample_rays(field, PixelGrid((1, 2), 1e-3), n_samples=4)
        >>> more = rays.frozen(np.array([[0.0, 200.0], [-200.0, 0.0]]), turn=np.pi / 4)
        >>> np.round(more.ds[:, 0]).tolist()  # Pa: 1e5 at 45 deg, plus 1e5 at 45 or at 90 deg
        [200000.0, 141421.0]
        """
        pp = self.per_pixel()
        two = 2.0 * (pp.theta + turn)
        a, b = pp.ds * np.cos(two), pp.ds * np.sin(two)
        if ab is not None:
            t = pp.dz.sum(axis=1)
            per = np.asarray(ab, float) / np.where(t > 0, t, np.inf)[:, None]  # Pa; 0 off
            a, b = a + per[:, :1], b + per[:, 1:]
        ds, theta = principal_from_components(a, b)
        return replace(pp, ds=ds, theta=theta)


def _fold(field, xy: np.ndarray, pixel_size: float):
    """Distinct rays of the pixels under the field's symmetry: (xy_rows, index, mirror)."""
    fold = getattr(field, "fold_xy", None)
    if fold is None:
        return xy, np.arange(len(xy)), np.zeros(len(xy), bool)
    folded, mirror = fold(xy)
    key = np.round(folded / (1e-6 * pixel_size)).astype(np.int64)
    _, first, index = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return folded[first], index.reshape(-1), np.asarray(mirror, bool)


def _sample_ab(field, xy, z0, z1, s, chunk, progress, desc):
    """sigma_xx - sigma_yy and 2 sigma_xy (Pa), (n, S), at heights z0 + (z1 - z0) s."""
    n, S = len(xy), len(s)
    a = np.zeros((n, S))
    b = np.zeros((n, S))
    per = max(1, chunk // S)
    starts = range(0, n, per)
    for start in tqdm(starts, desc=desc, unit="block", disable=not progress, leave=False):
        sl = slice(start, min(n, start + per))
        m = sl.stop - sl.start
        pts = np.empty((m, S, 3))
        pts[..., 0] = xy[sl, 0, None]
        pts[..., 1] = xy[sl, 1, None]
        pts[..., 2] = z0[sl, None] + (z1 - z0)[sl, None] * s[None, :]
        sig = field.stress(pts)
        a[sl] = sig[..., 0, 0] - sig[..., 1, 1]
        b[sl] = 2.0 * sig[..., 0, 1]
    return a, b


def _lattice_level(field, xy, want, step, s, chunk, progress, rtol, scale):
    """One level of :func:`_lattice_ab`: rays ``want`` of ``xy`` (n, 2) interpolated on a
    square lattice of pitch ``step`` (m) where the lattice passes its error check.

    Returns a, b (n, S), the mask of rays filled, and the error scale used (the largest
    ray integral of the stress difference on this lattice when ``scale`` is None).
    """
    n, S = len(xy), len(s)
    lo = xy[want].min(axis=0)
    hi = xy[want].max(axis=0)
    nx, ny = np.maximum(1, np.ceil((hi - lo) / step - 1e-9)).astype(int)
    fx = np.clip((xy[:, 0] - lo[0]) / step, 0, nx)
    fy = np.clip((xy[:, 1] - lo[1]) / step, 0, ny)
    ix = np.minimum(fx.astype(int), nx - 1)
    iy = np.minimum(fy.astype(int), ny - 1)
    tx, ty = fx - ix, fy - iy
    corners = [(0, 0), (1, 0), (0, 1), (1, 1)]
    node = np.stack([(iy + dy) * (nx + 1) + (ix + dx) for dx, dy in corners], axis=1)  # (n, 4)
    wts = np.stack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty], axis=1)
    # the wanted rays' cell corners and a one-node halo (for the second differences)
    needed = np.zeros((ny + 1) * (nx + 1), bool)
    needed[node[want].ravel()] = True
    needed = binary_dilation(needed.reshape(ny + 1, nx + 1), np.ones((3, 3), bool)).ravel()
    k = np.flatnonzero(needed)
    gx = lo[0] + step * (k % (nx + 1))
    gy = lo[1] + step * (k // (nx + 1))
    z0n, z1n, vn = field.z_range(np.column_stack([gx, gy]))
    vn = np.asarray(vn, bool)
    use = np.zeros_like(needed)
    use[k[vn]] = True
    a_n = np.zeros((len(needed), S))
    b_n = np.zeros((len(needed), S))
    dzn = np.zeros(len(needed))
    kv = k[vn]
    xy_n = np.column_stack([gx, gy])[vn]
    a_n[kv], b_n[kv] = _sample_ab(field, xy_n, z0n[vn], z1n[vn], s, chunk, progress, "lattice rays")
    dzn[kv] = (z1n[vn] - z0n[vn]) / S
    # A posteriori check: bilinear interpolation of f errs by at most about
    # (|d2f/dx2| + |d2f/dy2|) step^2 / 8, and the second differences of the lattice rays
    # give step^2 f'' (a kink of the FE interpolant between nodes shows up as well).
    # Summed over the ray (|.| dz per slab) it bounds the error of the ray's stress
    # integral. Lattice rays where it exceeds ``rtol`` of the largest ray integral, or
    # whose stencil leaves the layer or the sampled halo, fail the check.
    a3 = (a_n * dzn[:, None]).reshape(ny + 1, nx + 1, S)
    b3 = (b_n * dzn[:, None]).reshape(ny + 1, nx + 1, S)
    u2 = use.reshape(ny + 1, nx + 1)
    err = np.zeros((ny + 1, nx + 1))
    err[~u2] = np.inf
    for ax in (0, 1):
        lo_ = tuple(slice(0, -2) if d == ax else slice(None) for d in (0, 1))
        mid = tuple(slice(1, -1) if d == ax else slice(None) for d in (0, 1))
        hi_ = tuple(slice(2, None) if d == ax else slice(None) for d in (0, 1))
        d2 = np.abs(a3[lo_] - 2 * a3[mid] + a3[hi_]) + np.abs(b3[lo_] - 2 * b3[mid] + b3[hi_])
        e = d2.sum(axis=-1) / 8.0
        e[~(u2[lo_] & u2[mid] & u2[hi_])] = np.inf
        err[mid] += e
        edge = tuple(slice(None) if d != ax else [0, -1] for d in (0, 1))
        if (ny, nx)[ax] >= 1:  # lattice rays on the border have no second difference
            err[edge] = np.where(u2[edge], err[edge], np.inf)
    if scale is None:
        scale = float(np.hypot(a3, b3).sum(axis=-1).max())
    good = (err <= rtol * scale).ravel() & use
    filled = want & np.all(good[node], axis=1)
    a = np.zeros((n, S))
    b = np.zeros((n, S))
    r = np.flatnonzero(filled)
    for c in range(4):
        w = wts[r, c, None]
        a[r] += w * a_n[node[r, c]]
        b[r] += w * b_n[node[r, c]]
    return a, b, filled, scale


def _lattice_ab(field, xy, want, step, pixel, s, chunk, progress, rtol):
    """sigma_xx - sigma_yy and 2 sigma_xy (n, S) on the rays ``want`` of ``xy`` (n, 2),
    interpolated bilinearly between rays of a square lattice at the same fractions s of
    each ray's height, halving the pitch from ``step`` (m) where the lattice fails its
    error check (:func:`_lattice_level`) until it comes within 1.5 pixels. Returns a, b
    and the mask of rays filled (the rest are for direct sampling)."""
    n, S = len(xy), len(s)
    a = np.zeros((n, S))
    b = np.zeros((n, S))
    filled = np.zeros(n, bool)
    scale = None
    left = want.copy()
    while step > 1.5 * pixel and left.any():
        la, lb, f, scale = _lattice_level(field, xy, left, step, s, chunk, progress, rtol, scale)
        a[f], b[f] = la[f], lb[f]
        filled |= f
        left &= ~f
        step *= 0.5
    return a, b, filled


def sample_points(
    field, xy, n_samples: int, *, chunk: int = 1 << 20
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stress combinations along vertical rays at arbitrary points (not a pixel grid).

    Parameters
    ----------
    field : StressField
    xy : (n, 2) float array
        Ray positions (m).
    n_samples : int
        Slabs of equal thickness per ray (midpoint rule, as :func:`sample_rays`).
    chunk : int
        Points located at a time.

    Returns
    -------
    a, b : (n, S) float arrays
        sigma_xx - sigma_yy and 2 sigma_xy (Pa) at the slab midpoints (zero on invalid
        rays).
    dz : (n,) float array
        Slab thickness (m; zero on invalid rays).
    valid : (n,) bool array
        Rays that cross the layer (outside the contact zones).

    Raises
    ------
    ValueError
        ``n_samples < 1``.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import sample_points
    >>> a, b, dz, valid = sample_points(field, [[0.0, 0.0], [1e-3, 2e-3]], n_samples=3)
    >>> a.shape, a[0].tolist(), dz.tolist(), valid.tolist()
    ((2, 3), [100000.0, 100000.0, 100000.0], [0.001, 0.001], [True, True])
    """
    if int(n_samples) < 1:
        raise ValueError(f"n_samples = {n_samples!r} is not allowed; need >= 1")
    xy = np.asarray(xy, float).reshape(-1, 2)
    S = int(n_samples)
    z0, z1, ok = field.z_range(xy)
    ok = np.asarray(ok, bool)
    s = (np.arange(S) + 0.5) / S
    a = np.zeros((len(xy), S))
    b = np.zeros((len(xy), S))
    d = np.flatnonzero(ok)
    if d.size:
        a[d], b[d] = _sample_ab(field, xy[d], z0[d], z1[d], s, chunk, False, "rays")
    return a, b, np.where(ok, (z1 - z0) / S, 0.0), ok


def sample_rays(
    field,
    grid: PixelGrid,
    n_samples: int,
    *,
    lateral_step: float | None = None,
    lateral_rtol: float = 1e-3,
    chunk: int = 1 << 20,
    progress: bool = False,
) -> RaySamples:
    """Sample ``field`` at ``n_samples`` slab midpoints along each pixel's vertical ray.

    The ray runs from the layer's bottom to its top (``field.z_range``); slabs of equal
    thickness, stress taken at their midpoints (midpoint rule, 2nd order in 1/S).

    Pixels that are mirror images under the field's symmetry planes (a field with a
    ``fold_xy`` method, such as a quarter or half FEM model) share one ray. With
    ``lateral_step`` (m), the stress is sampled on rays of a square lattice of that pitch
    and interpolated bilinearly to the pixels' rays at the same fraction of the layer
    height (the layer's bottom and top are still taken exactly under every pixel); rays
    whose lattice neighbours leave the layer (the contact zone, the sheet's edge) are
    sampled directly. A step well below the FE field's own resolution costs nothing in
    accuracy (tests/test_optics_fem.py measures it) and makes the sampling cost follow
    the field, not the image.

    Parameters
    ----------
    field : StressField
    grid : PixelGrid
    n_samples : int
        Slabs per ray.
    lateral_step : float, optional
        Pitch (m) of the ray lattice; None samples every distinct pixel ray.
    lateral_rtol : float
        Error bound of the lattice interpolation, relative to the largest ray integral
        of the stress difference; lattice cells above it are refined by halving.
    chunk : int
        Points located at a time.
    progress : bool
        Show a bar over the blocks.

    Returns
    -------
    RaySamples

    Raises
    ------
    ValueError
        ``n_samples < 1`` or a lateral step that is not > 0.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import PSM4_ASSUMED, PixelGrid, UniformStress
    >>> field = UniformStress(np.diag([1e5, 0.0, 0.0]), z0=0.0, z1=3e-3)  # 0.1 MPa, 3 mm
    >>> from fringekit.optics import sample_rays
    >>> rays = sample_rays(field, PixelGrid((2, 3), 1e-3), n_samples=4)
    >>> rays.ds.shape, bool(rays.valid.all()), float(rays.ds.max())  # Pa
    ((6, 4), True, 100000.0)
    """
    if int(n_samples) < 1:
        raise ValueError(f"n_samples = {n_samples!r} is not allowed; need >= 1")
    if lateral_step is not None and not (math.isfinite(lateral_step) and lateral_step > 0):
        raise ValueError(
            f"lateral_step = {lateral_step!r} is not allowed; give a pitch > 0 (m) or None"
        )
    n_samples = int(n_samples)
    xy = grid.xy()
    _, _, pix_valid = field.z_range(xy)
    rows_xy, index, mirror = _fold(field, xy, grid.pixel_size)
    z0, z1, ok = field.z_range(rows_xy)
    ok = np.asarray(ok, bool)
    valid = np.asarray(pix_valid, bool) & ok[index]
    R = len(rows_xy)
    s = (np.arange(n_samples) + 0.5) / n_samples
    a = np.zeros((R, n_samples))
    b = np.zeros((R, n_samples))
    direct = ok.copy()
    if lateral_step is not None and ok.any():
        la, lb, inside = _lattice_ab(
            field, rows_xy, ok, lateral_step, grid.pixel_size, s, chunk, progress, lateral_rtol
        )
        a[inside], b[inside] = la[inside], lb[inside]
        direct &= ~inside
    d = np.flatnonzero(direct)
    if d.size:
        a[d], b[d] = _sample_ab(field, rows_xy[d], z0[d], z1[d], s, chunk, progress, "rays")
    dz = np.where(ok, (z1 - z0) / n_samples, 0.0)
    ds, theta = principal_from_components(a, b)
    return RaySamples(
        ds=ds,
        theta=theta,
        dz=np.repeat(dz[:, None], n_samples, axis=1),
        valid=valid,
        index=index,
        mirror=mirror,
    )
