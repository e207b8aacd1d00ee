"""Graded target edge length and the background tet grid that carries it to fTetWild."""

from __future__ import annotations

import itertools

import numpy as np

from .spec import MeshSpec

__all__ = ["target_size", "background_grid"]


def target_size(spec: MeshSpec, points: np.ndarray) -> np.ndarray:
    """Target edge length (m) at points (n, 3) (m).

    ``h = min_i (h_contact + growth * d_i)`` where ``d_i`` is the distance to the
    refined zone of indenter i, a cylinder of radius ``refine_radius`` about its
    axis through the whole sheet; clipped to ``h_far`` everywhere and to ``h_sheet``
    inside the sheet (z >= 0). Every indenter of the full sheet counts, including
    mirror images outside a symmetric model, so sizing is symmetric too.

    Only correctly rounded operations (no ``hypot``), so the layered mesher, which
    evaluates it on the contact face, is reproducible bit for bit
    (:mod:`meshes.plane`).
    """
    siz, lay = spec.sizing, spec.layers
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    dz = np.maximum(0.0, np.maximum(-z, z - lay.z_top))
    h = np.full(len(points), siz.h_far)
    for ind in spec.indenters:  # loop over the few indenters, vectorised over points
        dx, dy = x - ind.x, y - ind.y
        a = np.maximum(0.0, np.sqrt(dx * dx + dy * dy) - siz.refine_radius)
        h = np.minimum(h, siz.h_contact + siz.growth * np.sqrt(a * a + dz * dz))
    return np.where(z >= 0.0, np.minimum(h, siz.h_sheet), h)


def _axis(lo: float, hi: float, coarse: float, fine_windows, fine: float) -> np.ndarray:
    """Grid coordinates over [lo, hi] with spacing ``fine`` inside the windows."""
    pts = [np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) / coarse)) + 1))]
    for a, b in fine_windows:
        a, b = max(lo, a), min(hi, b)
        if b > a:
            pts.append(np.linspace(a, b, max(2, int(np.ceil((b - a) / fine)) + 1)))
    ax = np.unique(np.concatenate(pts))
    # drop near-duplicates that would give sliver background cells
    keep = np.concatenate([[True], np.diff(ax) > 1e-3 * fine])
    return ax[keep]


def background_grid(spec: MeshSpec, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """Rectilinear background grid split into Kuhn tetrahedra (conforming).

    Parameters
    ----------
    spec : MeshSpec
    pad : float
        Margin added around the domain bounds (m), so fTetWild's boundary envelope is
        covered.

    Returns
    -------
    points : (n, 3) float array (m)
    tets : (6 * hexes, 4) int32 array
    """
    xmin, xmax, ymin, ymax, zmin, zmax = spec.bounds()
    siz = spec.sizing
    reach = siz.refine_radius + 4 * siz.h_contact / max(siz.growth, 1e-3)
    # The field is piecewise linear in r and z, so grid steps of h_contact (laterally,
    # near indenters) and h_sheet / 2 (through the sheet) represent it well enough.
    step = siz.h_contact
    near_x = [(i.x - reach, i.x + reach) for i in spec.indenters]
    near_y = [(i.y - reach, i.y + reach) for i in spec.indenters]
    xs = _axis(xmin - pad, xmax + pad, siz.h_sheet, near_x, step)
    ys = _axis(ymin - pad, ymax + pad, siz.h_sheet, near_y, step)
    zs = _axis(zmin - pad, zmax + pad, siz.h_far, [(-siz.h_sheet, zmax + pad)], 0.5 * siz.h_sheet)
    nx, ny, nz = len(xs), len(ys), len(zs)
    gx, gy, gz = np.meshgrid(xs, ys, zs, indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    idx = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    base = idx[:-1, :-1, :-1].ravel()
    strides = np.array([ny * nz, nz, 1])
    tets = []
    for perm in itertools.permutations(range(3)):  # the 6 Kuhn simplices of a hex
        v = [base]
        for ax in perm:
            v.append(v[-1] + strides[ax])
        tets.append(np.stack(v, axis=1))
    return points, np.vstack(tets).astype(np.int32)
