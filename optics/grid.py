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
from dataclasses import dataclass

import numpy as np

from .jones import secondary_principal

__all__ = ["PixelGrid", "RaySamples", "sample_rays"]


@dataclass(frozen=True)
class PixelGrid:
    """A rectangular camera grid.

    Parameters
    ----------
    shape : (rows, cols)
        Image shape in pixels (>= 1 each).
    pixel_size : float
        Pixel pitch on the sheet (m).
    center : (x0, y0)
        Sheet coordinates of the image centre (m).
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
    """Stress sampled along vertical rays.

    Only what the optics needs is kept: the secondary principal stress difference and
    angle at each slab midpoint (optics.jones.secondary_principal), not the full tensor.

    Attributes
    ----------
    ds : (P, S) float, Pa — secondary principal stress difference.
    theta : (P, S) float, rad — secondary principal angle.
    dz : (P, S) float, m — slab thickness along the ray.
    valid : (P,) bool — rays that cross the photoelastic layer.
    """

    ds: np.ndarray
    theta: np.ndarray
    dz: np.ndarray
    valid: np.ndarray


def sample_rays(
    field, grid: PixelGrid, n_samples: int, *, chunk: int = 1 << 14, progress: bool = False
) -> RaySamples:
    """Sample ``field`` at ``n_samples`` slab midpoints along each pixel's vertical ray.

    The ray runs from the layer's bottom to its top (``field.z_range``); slabs of equal
    thickness, stress taken at their midpoints (midpoint rule, 2nd order in 1/S).
    Rays are processed in blocks of ``chunk`` so the (chunk, S, 3, 3) stress block
    stays small; invalid rays get zero stress and zero thickness. ``progress`` shows a
    bar over the blocks.
    """
    if int(n_samples) < 1:
        raise ValueError(f"n_samples = {n_samples!r} is not allowed; need >= 1")
    n_samples = int(n_samples)
    xy = grid.xy()
    z0, z1, valid = field.z_range(xy)
    valid = np.asarray(valid, bool)
    P = len(xy)
    s = (np.arange(n_samples) + 0.5) / n_samples
    ds = np.zeros((P, n_samples))
    theta = np.zeros((P, n_samples))
    idx = np.flatnonzero(valid)
    from tqdm.auto import tqdm

    starts = range(0, idx.size, chunk)
    for start in tqdm(starts, desc="rays", unit="block", disable=not progress, leave=False):
        rows = idx[start : start + chunk]
        pts = np.empty((rows.size, n_samples, 3))
        pts[..., 0] = xy[rows, 0, None]
        pts[..., 1] = xy[rows, 1, None]
        pts[..., 2] = z0[rows, None] + (z1 - z0)[rows, None] * s[None, :]
        ds[rows], theta[rows] = secondary_principal(field.stress(pts))
    dz = np.where(valid, (z1 - z0) / n_samples, 0.0)
    return RaySamples(ds=ds, theta=theta, dz=np.repeat(dz[:, None], n_samples, axis=1), valid=valid)
