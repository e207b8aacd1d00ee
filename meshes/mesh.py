"""The ``Mesh`` data object: quadratic tetrahedra with regions and named facet sets."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType

import numpy as np

from .spec import MeshSpec
from .topology import TET_FACE_MIDS, TET_FACES, signed_volumes

__all__ = ["FacetSet", "Mesh", "REGION_SHEET", "REGION_SUBSTRATE", "REGION_NAMES", "FACET_SETS"]

#: Region id (``Mesh.regions``) of the cells of the photoelastic sheet.
REGION_SHEET = 0
#: Region id of the cells of the substrate (the polycarbonate plate).
REGION_SUBSTRATE = 1
#: Region names by id: ``REGION_NAMES[REGION_SHEET] == "sheet"``.
REGION_NAMES = ("sheet", "substrate")

#: Names of the boundary facet sets a mesh may carry. ``symmetry_y0`` is the mirror
#: plane y = 0 (half and quarter models), ``symmetry_x0`` the plane x = 0 (quarter).
FACET_SETS = ("contact", "interface", "bottom", "sides", "symmetry_y0", "symmetry_x0")


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class FacetSet:
    """Boundary (or interface) facets as 6-node triangles owned by a cell.

    Parameters
    ----------
    cells : (m,) int64 array
        Owning cell of each facet. For ``interface`` the owner is the sheet cell.
    local : (m,) int8 array
        Face index 0..3 in :data:`meshes.topology.TET_FACES` of the owner.

    Raises
    ------
    ValueError
        ``cells`` and ``local`` not 1-D of equal length.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.meshes import FacetSet
    >>> fs = FacetSet(cells=np.array([0, 0]), local=np.array([1, 3]))
    >>> len(fs), fs.cells.dtype.name, fs.local.dtype.name
    (2, 'int64', 'int8')
    """

    cells: np.ndarray
    local: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "cells", _readonly(np.asarray(self.cells, dtype=np.int64)))
        object.__setattr__(self, "local", _readonly(np.asarray(self.local, dtype=np.int8)))
        if self.cells.shape != self.local.shape or self.cells.ndim != 1:
            raise ValueError("FacetSet.cells and FacetSet.local must be 1-D of equal length")

    def __len__(self) -> int:
        return len(self.cells)

    def nodes(self, cells10: np.ndarray) -> np.ndarray:
        """(m, 6) node ids in VTK QUADRATIC_TRIANGLE order, normal pointing out of the owner."""
        corner = TET_FACES[self.local]
        mids = TET_FACE_MIDS[self.local]
        local = np.hstack([corner, mids])
        return np.take_along_axis(cells10[self.cells], local, axis=1)


@dataclass(frozen=True)
class Mesh:
    """Quadratic tetrahedral mesh of a bonded sheet/substrate block.

    Made by :func:`build_mesh`; the arrays are read-only.

    Parameters
    ----------
    points : (n, 3) float64 array
        Node coordinates (m). Corner nodes first, mid-edge nodes after.
    cells : (c, 10) int64 array
        VTK QUADRATIC_TETRA connectivity, all positively oriented.
    regions : (c,) int8 array
        :data:`REGION_SHEET` or :data:`REGION_SUBSTRATE` per cell.
    facets : mapping str -> FacetSet
        Named facet sets, see :data:`FACET_SETS`.
    spec : MeshSpec or None
        The inputs the mesh was generated from.

    Raises
    ------
    ValueError
        Arrays of the wrong shape, node ids out of range, or unknown facet set names.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> mesh.points.shape, mesh.cells.shape
    ((245, 3), (108, 10))
    >>> sorted(mesh.facets)
    ['bottom', 'contact', 'interface', 'sides', 'symmetry_x0', 'symmetry_y0']
    >>> mesh.facet_nodes("contact").shape  # 6-node triangles of the contact face
    (18, 6)
    >>> from fringekit.meshes import REGION_SHEET
    >>> round(mesh.region_volume(REGION_SHEET) * 1e9, 3)  # 5 x 5 x 2 mm quarter, mm^3
    50.0
    """

    points: np.ndarray
    cells: np.ndarray
    regions: np.ndarray
    facets: Mapping[str, FacetSet] = field(default_factory=dict)
    spec: MeshSpec | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)
        cells = np.asarray(self.cells, dtype=np.int64)
        regions = np.asarray(self.regions, dtype=np.int8)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
        if cells.ndim != 2 or cells.shape[1] != 10:
            raise ValueError(f"cells must have shape (c, 10), got {cells.shape}")
        if regions.shape != (len(cells),):
            raise ValueError(f"regions must have shape ({len(cells)},), got {regions.shape}")
        if cells.size and (cells.min() < 0 or cells.max() >= len(pts)):
            raise ValueError("cells reference node ids outside 0..len(points)-1")
        unknown = set(self.facets) - set(FACET_SETS)
        if unknown:
            raise ValueError(f"unknown facet set names {sorted(unknown)}; allowed: {FACET_SETS}")
        object.__setattr__(self, "points", _readonly(pts))
        object.__setattr__(self, "cells", _readonly(cells))
        object.__setattr__(self, "regions", _readonly(regions))
        object.__setattr__(self, "facets", MappingProxyType(dict(self.facets)))

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    @property
    def n_dofs(self) -> int:
        """Displacement degrees of freedom (3 per node)."""
        return 3 * len(self.points)

    @cached_property
    def volumes(self) -> np.ndarray:
        """(c,) cell volumes (m^3). Exact for straight-edged quadratic tets."""
        return signed_volumes(self.points, self.cells)

    def region_volume(self, region: int) -> float:
        """Total volume of the cells of one region (m^3)."""
        return float(self.volumes[self.regions == region].sum())

    def facet_nodes(self, name: str) -> np.ndarray:
        """(m, 6) node ids of the named facet set (VTK QUADRATIC_TRIANGLE order)."""
        if name not in self.facets:
            raise KeyError(f"mesh has no facet set {name!r}; it has {sorted(self.facets)}")
        return self.facets[name].nodes(self.cells)

    def same_as(self, other: Mesh) -> bool:
        """True when every array and every facet set is identical (bitwise)."""
        if set(self.facets) != set(other.facets):
            return False
        return (
            np.array_equal(self.points, other.points)
            and np.array_equal(self.cells, other.cells)
            and np.array_equal(self.regions, other.regions)
            and all(
                np.array_equal(self.facets[k].cells, other.facets[k].cells)
                and np.array_equal(self.facets[k].local, other.facets[k].local)
                for k in self.facets
            )
            and self.spec == other.spec
        )
