"""Element quality measures and the mesh quality report."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from fringekit.errors import ComputeError

from .topology import signed_volumes

__all__ = [
    "dihedral_angles",
    "radius_ratios",
    "QualityReport",
    "quality_report",
    "MeshQualityError",
    "check_quality",
]

# Edges (i, j) and the two vertices (k, l) NOT on that edge: the faces opposite k and l
# are the two faces that meet along the edge.
_EDGE_OPPOSITE = np.array(
    [[0, 1, 2, 3], [0, 2, 1, 3], [0, 3, 1, 2], [1, 2, 0, 3], [1, 3, 0, 2], [2, 3, 0, 1]]
)


def _face_area_vectors(p: np.ndarray) -> np.ndarray:
    """(c, 4, 3) outward area vectors of the faces opposite each corner of positive tets."""
    out = np.empty(p.shape[:1] + (4, 3))
    for k in range(4):  # loop over the four faces of one element type
        i, j, l = [m for m in range(4) if m != k]
        n = 0.5 * np.cross(p[:, j] - p[:, i], p[:, l] - p[:, i])
        # orient away from the opposite corner
        s = np.sign(np.einsum("ij,ij->i", n, p[:, i] - p[:, k]))
        out[:, k] = n * s[:, None]
    return out


def dihedral_angles(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(c, 6) interior dihedral angles of each tetrahedron at its six edges (degrees).

    The interior angle at an edge is pi minus the angle between the outward normals
    of the two faces that meet there.
    """
    p = points[cells[:, :4]]
    a = _face_area_vectors(p)
    n = a / np.maximum(np.linalg.norm(a, axis=2, keepdims=True), np.finfo(float).tiny)
    k, l = _EDGE_OPPOSITE[:, 2], _EDGE_OPPOSITE[:, 3]
    cosang = np.clip(np.einsum("cei,cei->ce", n[:, k], n[:, l]), -1.0, 1.0)
    return np.degrees(np.pi - np.arccos(cosang))


def radius_ratios(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(c,) normalised radius ratio 3 r_in / R_circ: 1 for a regular tet, 0 when flat."""
    p = points[cells[:, :4]]
    vol = np.abs(signed_volumes(points, cells))
    area = np.linalg.norm(_face_area_vectors(p), axis=2).sum(axis=1)
    r_in = 3.0 * vol / np.maximum(area, np.finfo(float).tiny)
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    num = (
        np.einsum("ij,ij->i", a, a)[:, None] * np.cross(b, c)
        + np.einsum("ij,ij->i", b, b)[:, None] * np.cross(c, a)
        + np.einsum("ij,ij->i", c, c)[:, None] * np.cross(a, b)
    )
    r_circ = np.linalg.norm(num, axis=1) / np.maximum(12.0 * vol, np.finfo(float).tiny)
    return np.where(vol > 0, 3.0 * r_in / np.maximum(r_circ, np.finfo(float).tiny), 0.0)


@dataclass(frozen=True)
class QualityReport:
    """Summary figures of a tetrahedral mesh."""

    n_points: int
    n_cells: int
    n_dofs: int
    cells_per_region: dict
    min_dihedral_deg: float
    max_dihedral_deg: float
    min_radius_ratio: float
    mean_radius_ratio: float
    min_volume_m3: float

    def as_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        regions = ", ".join(f"{k}: {v}" for k, v in self.cells_per_region.items())
        return (
            f"{self.n_points} nodes, {self.n_cells} quadratic tets ({regions}), "
            f"{self.n_dofs} DOF; dihedral {self.min_dihedral_deg:.1f}..{self.max_dihedral_deg:.1f} "
            f"deg; radius ratio min {self.min_radius_ratio:.3f}, mean {self.mean_radius_ratio:.3f}"
        )


class MeshQualityError(ComputeError, ValueError):
    """Raised when a mesh has inverted or degenerate elements."""


def quality_report(points, cells, regions, region_names=("sheet", "substrate")) -> QualityReport:
    """Compute the :class:`QualityReport` of a tet mesh (corner nodes are used)."""
    dih = dihedral_angles(points, cells)
    rr = radius_ratios(points, cells)
    vol = signed_volumes(points, cells)
    counts = {name: int(np.sum(regions == i)) for i, name in enumerate(region_names)}
    return QualityReport(
        n_points=int(len(points)),
        n_cells=int(len(cells)),
        n_dofs=int(3 * len(points)),
        cells_per_region=counts,
        min_dihedral_deg=float(dih.min()),
        max_dihedral_deg=float(dih.max()),
        min_radius_ratio=float(rr.min()),
        mean_radius_ratio=float(rr.mean()),
        min_volume_m3=float(vol.min()),
    )


def check_quality(points, cells, *, min_dihedral_deg: float = 1.0, min_radius_ratio: float = 1e-3):
    """Raise :class:`MeshQualityError` on inverted or degenerate tets.

    Parameters
    ----------
    min_dihedral_deg : float
        Smallest acceptable dihedral angle (degrees). Default 1 degree: below it the
        element Jacobian is too ill-conditioned for a large-deformation solve.
    min_radius_ratio : float
        Smallest acceptable normalised radius ratio (dimensionless).
    """
    vol = signed_volumes(points, cells)
    bad = np.flatnonzero(vol <= 0)
    if bad.size:
        raise MeshQualityError(
            f"{bad.size} inverted or zero-volume tetrahedra (first: cell {bad[0]}, "
            f"volume {vol[bad[0]]:.3e} m^3); allowed: volume > 0"
        )
    dih = dihedral_angles(points, cells).min(axis=1)
    rr = radius_ratios(points, cells)
    bad = np.flatnonzero((dih < min_dihedral_deg) | (rr < min_radius_ratio))
    if bad.size:
        raise MeshQualityError(
            f"{bad.size} degenerate tetrahedra (first: cell {bad[0]}, min dihedral "
            f"{dih[bad[0]]:.3f} deg, radius ratio {rr[bad[0]]:.2e}); allowed: dihedral >= "
            f"{min_dihedral_deg} deg and radius ratio >= {min_radius_ratio}"
        )
