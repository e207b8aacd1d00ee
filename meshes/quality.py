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
    """Summary figures of a tetrahedral mesh (made by :func:`quality_report`).

    Parameters
    ----------
    n_points, n_cells, n_dofs : int
        Nodes, cells and displacement degrees of freedom (3 per node).
    cells_per_region : dict
        Region name -> number of cells.
    min_dihedral_deg, max_dihedral_deg : float
        Extreme interior dihedral angles (degrees).
    min_radius_ratio, mean_radius_ratio : float
        Normalised radius ratio 3 r_in / R_circ (1 for a regular tet, 0 when flat).
    min_volume_m3 : float
        Smallest cell volume (m^3).

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import quality_report
    >>> report = quality_report(mesh.points, mesh.cells, mesh.regions)
    >>> report.as_dict()["cells_per_region"]
    {'sheet': 108, 'substrate': 0}
    >>> print(report)  # doctest: +ELLIPSIS
    245 nodes, 108 quadratic tets (sheet: 108, substrate: 0), 735 DOF; dihedral ...
    """

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
    """Raised when a mesh has inverted or degenerate elements.

    A :class:`fringekit.errors.ComputeError` (and a ``ValueError``): the mesher could
    not produce a usable mesh of valid inputs.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.meshes import MeshQualityError, check_quality
    >>> flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)  # 4 points in a plane
    >>> try:
    ...     check_quality(flat, np.array([[0, 1, 2, 3]]))
    ... except MeshQualityError as err:
    ...     print(str(err).split(" (")[0])
    1 inverted or zero-volume tetrahedra
    """


def quality_report(points, cells, regions, region_names=("sheet", "substrate")) -> QualityReport:
    """The :class:`QualityReport` of a tet mesh (its corner nodes).

    Parameters
    ----------
    points : (n, 3) float array
        Node coordinates (m).
    cells : (c, 4) or (c, 10) int array
        Tetrahedra; only the 4 corner nodes are used.
    regions : (c,) int array
        Region id per cell.
    region_names : sequence of str
        Name of region id 0, 1, ...

    Returns
    -------
    QualityReport

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.meshes import quality_report
    >>> tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> r = quality_report(tet, np.array([[0, 1, 2, 3]]), np.array([0]))
    >>> r.n_dofs, round(r.min_dihedral_deg, 1), round(r.max_dihedral_deg, 1)
    (12, 54.7, 90.0)
    """
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
    points : (n, 3) float array
        Node coordinates (m).
    cells : (c, 4) or (c, 10) int array
        Tetrahedra; only the 4 corner nodes are used.
    min_dihedral_deg : float
        Smallest acceptable dihedral angle (degrees). Default 1 degree: below it the
        element Jacobian is too ill-conditioned for a large-deformation solve.
    min_radius_ratio : float
        Smallest acceptable normalised radius ratio (dimensionless).

    Returns
    -------
    None

    Raises
    ------
    MeshQualityError
        A cell of volume <= 0, or one below either threshold.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.meshes import check_quality
    >>> tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> check_quality(tet, np.array([[0, 1, 2, 3]]))  # fine: returns None
    >>> check_quality(tet, np.array([[0, 2, 1, 3]]))  # inverted
    Traceback (most recent call last):
    ...
    fringekit.meshes.quality.MeshQualityError: 1 inverted or zero-volume tetrahedra ...
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
