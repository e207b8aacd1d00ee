"""Deterministic graded triangulation of the rectangle a layered sensor occupies.

The point set is relaxed by the force-equilibrium method of DistMesh (P.-O. Persson and
G. Strang, "A simple mesh generator in MATLAB", SIAM Review 46(2), 2004): edges of a
Delaunay triangulation act as springs whose rest lengths follow the target size field,
points move along the net force, points pushed out of the rectangle are clamped back onto
it, and the triangulation is rebuilt when points have moved far enough.

Reproducibility: the start is a lattice thinned by a fixed low-discrepancy sequence (no
random numbers), the iteration uses only IEEE-754 correctly rounded arithmetic
(+, -, *, /, sqrt, clamping; no library transcendental functions whose last bit can
depend on the CPU's vector unit), forces are accumulated in a fixed order
(``np.bincount``), the one reduction is ``math.fsum`` (exactly rounded), and Qhull is
deterministic for identical input. The same inputs give the same triangulation, bit for
bit, on every run and on every machine with the same numpy and scipy.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from scipy.spatial import Delaunay

from fringekit.errors import ComputeError

from .sizing import target_size
from .spec import MeshSpec

__all__ = ["plane_size", "triangulate_plane", "PlaneMeshError"]

log = logging.getLogger("fringekit.meshes")

#: DistMesh constants (Persson & Strang 2004, Table 1): time step, rest-length scale
#: (>1 keeps springs in compression so points spread to the boundary), retriangulation
#: and convergence tolerances relative to the smallest target size.
DELTA_T = 0.2
F_SCALE = 1.2
RETRIANGULATE_TOL = 0.1
CONVERGED_TOL = 1e-3
#: Hard cap on relaxation steps; the meshes of this project converge in 100-400.
MAX_STEPS = 1500

#: Weyl-sequence increments of the thinning (the R2 sequence: 1/g and 1/g^2 with g the
#: plastic number), so the kept lattice points are spread evenly and fixed for all time.
_R2 = (0.7548776662466927, 0.5698402909980532)


class PlaneMeshError(ComputeError):
    """The plane triangulation did not reach an acceptable state."""


def plane_size(spec: MeshSpec, xy: np.ndarray) -> np.ndarray:
    """Target edge length (m) on the sheet plane at points xy (n, 2) (m): the sizing field
    (:func:`meshes.sizing.target_size`) on the contact face, where it is
    ``min_i (h_contact + growth * max(0, r_i - refine_radius))`` clipped to ``h_sheet``."""
    top = np.full((len(xy), 1), spec.layers.z_top)
    return target_size(spec, np.hstack([xy, top]))


def _initial_points(spec: MeshSpec, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Equilateral lattice of spacing h_contact thinned to density ~ 1 / h^2."""
    h0 = spec.sizing.h_contact
    dy = h0 * 0.8660254037844386  # sqrt(3) / 2
    nx = int(math.floor((hi[0] - lo[0]) / h0)) + 1
    ny = int(math.floor((hi[1] - lo[1]) / dy)) + 1
    j, i = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    x = lo[0] + i * h0 + (j % 2) * (0.5 * h0)
    y = lo[1] + j * dy
    pts = np.stack([x.ravel(), y.ravel()], axis=1)
    pts = pts[(pts[:, 0] <= hi[0]) & (pts[:, 1] <= hi[1])]
    k = np.arange(len(pts), dtype=np.float64) + 1.0
    u = (k * _R2[0]) % 1.0
    ratio = h0 / plane_size(spec, pts)
    return pts[u < ratio * ratio]


def _edges(p: np.ndarray) -> np.ndarray:
    """Unique sorted edges (e, 2) of the Delaunay triangulation of p."""
    tri = Delaunay(p).simplices
    bars = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    return np.unique(bars, axis=0)


def _relax(spec: MeshSpec, p: np.ndarray, fixed: int, lo, hi) -> tuple[np.ndarray, int]:
    """DistMesh relaxation; the first ``fixed`` points never move. Returns (points, steps)."""
    h0 = spec.sizing.h_contact
    last = np.full_like(p, np.inf)
    bars = None
    for step in range(1, MAX_STEPS + 1):
        move = p - last
        if bars is None or np.max(np.sqrt(np.sum(move * move, axis=1))) > RETRIANGULATE_TOL * h0:
            last = p.copy()
            bars = _edges(p)
        vec = p[bars[:, 0]] - p[bars[:, 1]]
        length = np.sqrt(vec[:, 0] * vec[:, 0] + vec[:, 1] * vec[:, 1])
        hbar = plane_size(spec, 0.5 * (p[bars[:, 0]] + p[bars[:, 1]]))
        scale = math.sqrt(math.fsum(length * length) / math.fsum(hbar * hbar))
        force = np.maximum(hbar * (F_SCALE * scale) - length, 0.0)
        fvec = vec * (force / length)[:, None]
        n = len(p)
        total = np.stack(
            [
                np.bincount(bars[:, 0], fvec[:, a], n) - np.bincount(bars[:, 1], fvec[:, a], n)
                for a in range(2)
            ],
            axis=1,
        )
        total[:fixed] = 0.0
        new = np.clip(p + DELTA_T * total, lo, hi)
        inside = np.all((new > lo) & (new < hi), axis=1)
        d = new[inside] - p[inside]
        p = new
        if not inside.any() or np.max(np.sqrt(np.sum(d * d, axis=1))) < CONVERGED_TOL * h0:
            return p, step
    return p, MAX_STEPS


def triangulate_plane(spec: MeshSpec) -> tuple[np.ndarray, np.ndarray]:
    """Graded triangulation of the modelled rectangle of ``spec`` (symmetry cuts applied).

    Parameters
    ----------
    spec : MeshSpec
        Lateral extent, symmetry, indenter sites and sizing (m).

    Returns
    -------
    points : (n, 2) float64
        Vertex coordinates (m); the rectangle's corners first, boundary vertices lie
        exactly on its edges.
    triangles : (t, 3) int64
        Counter-clockwise vertex ids.

    Raises
    ------
    PlaneMeshError
        If the relaxation leaves a degenerate triangle (smallest area below 1e-6 of
        h_contact^2).
    """
    xmin, xmax, ymin, ymax, _, _ = spec.bounds()
    lo, hi = np.array([xmin, ymin]), np.array([xmax, ymax])
    corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    start = _initial_points(spec, lo, hi)
    h0 = spec.sizing.h_contact
    gap = np.min(np.abs(start[:, None, :] - corners[None]).max(axis=2), axis=1)
    pts = np.vstack([corners, start[gap > 0.5 * h0]])
    pts, steps = _relax(spec, pts, len(corners), lo, hi)
    tri = Delaunay(pts).simplices.astype(np.int64)
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri[area2 < 0] = tri[area2 < 0][:, [0, 2, 1]]
    smallest = float(np.min(np.abs(area2))) / 2
    if smallest < 1e-6 * h0 * h0:
        raise PlaneMeshError(
            f"plane triangulation has a degenerate triangle (area {smallest:.3e} m^2 after "
            f"{steps} relaxation steps); change sizing.h_contact or sizing.growth slightly"
        )
    log.debug("plane triangulation: %d points, %d triangles, %d steps", len(pts), len(tri), steps)
    return pts, tri
