"""Mesh export/import: pyvista ``UnstructuredGrid``, VTU files and the npz cache format.

Facet sets travel as field data (``facets:<name>`` with shape (m, 2): owner cell,
local face) so the grid stays a pure tetrahedral grid that ParaView opens directly;
:func:`facet_grid` gives a 6-node triangle grid of one set for viewing.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

from .mesh import FACET_SETS, FacetSet, Mesh
from .spec import MeshSpec

__all__ = [
    "to_pyvista",
    "from_pyvista",
    "write_vtu",
    "read_vtu",
    "facet_grid",
    "save_npz",
    "load_npz",
]

_VTK_QUADRATIC_TETRA = 24
_VTK_QUADRATIC_TRIANGLE = 22


def to_pyvista(mesh: Mesh):
    """The mesh as a ``pyvista.UnstructuredGrid`` (points in m, cell data ``region``)."""
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    cells = np.hstack([np.full((mesh.n_cells, 1), 10), mesh.cells]).ravel()
    types = np.full(mesh.n_cells, _VTK_QUADRATIC_TETRA, dtype=np.uint8)
    grid = pv.UnstructuredGrid(cells, types, np.array(mesh.points))
    grid.cell_data["region"] = np.asarray(mesh.regions, dtype=np.int32)
    for name, fs in mesh.facets.items():
        grid.field_data[f"facets:{name}"] = np.stack([fs.cells, fs.local.astype(np.int64)], axis=1)
    if mesh.spec is not None:
        grid.field_data["mesh_spec_json"] = [json.dumps(mesh.spec.to_dict(), sort_keys=True)]
    return grid


def from_pyvista(grid) -> Mesh:
    """Inverse of :func:`to_pyvista`; raises ValueError on a grid that is not one of ours."""
    types = np.asarray(grid.celltypes)
    if types.size and np.any(types != _VTK_QUADRATIC_TETRA):
        raise ValueError("grid must contain only VTK_QUADRATIC_TETRA (24) cells")
    if "region" not in grid.cell_data:
        raise ValueError("grid has no cell data 'region'")
    conn = np.asarray(grid.cell_connectivity, dtype=np.int64).reshape(-1, 10)
    facets = {}
    for name in FACET_SETS:
        key = f"facets:{name}"
        if key in grid.field_data:
            arr = np.asarray(grid.field_data[key]).reshape(-1, 2)
            facets[name] = FacetSet(arr[:, 0], arr[:, 1])
    spec = None
    if "mesh_spec_json" in grid.field_data:
        spec = MeshSpec.from_dict(json.loads(str(np.asarray(grid.field_data["mesh_spec_json"])[0])))
    return Mesh(
        points=np.asarray(grid.points, dtype=np.float64),
        cells=conn,
        regions=np.asarray(grid.cell_data["region"]),
        facets=facets,
        spec=spec,
    )


def write_vtu(mesh: Mesh, path: str | os.PathLike) -> Path:
    """Write the mesh to a VTU file (binary, lossless)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    to_pyvista(mesh).save(path, binary=True)
    return path


def read_vtu(path: str | os.PathLike) -> Mesh:
    """Read a mesh written by :func:`write_vtu`."""
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    return from_pyvista(pv.read(Path(path)))


def facet_grid(mesh: Mesh, name: str):
    """A ``pyvista.UnstructuredGrid`` of 6-node triangles of one facet set (for viewing)."""
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    nodes = mesh.facet_nodes(name)
    cells = np.hstack([np.full((len(nodes), 1), 6), nodes]).ravel()
    types = np.full(len(nodes), _VTK_QUADRATIC_TRIANGLE, dtype=np.uint8)
    return pv.UnstructuredGrid(cells, types, np.array(mesh.points))


def save_npz(mesh: Mesh, path: str | os.PathLike) -> Path:
    """Write the mesh to ``path`` atomically (a crash never leaves a partial file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"points": mesh.points, "cells": mesh.cells, "regions": mesh.regions}
    for name, fs in mesh.facets.items():
        arrays[f"facet_cells__{name}"] = fs.cells
        arrays[f"facet_local__{name}"] = fs.local
    spec = "" if mesh.spec is None else json.dumps(mesh.spec.to_dict(), sort_keys=True)
    arrays["spec_json"] = np.array(spec)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    os.close(fd)
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


def load_npz(path: str | os.PathLike) -> Mesh:
    """Read a mesh written by :func:`save_npz`."""
    with np.load(Path(path), allow_pickle=False) as data:
        facets = {}
        for name in FACET_SETS:
            if f"facet_cells__{name}" in data:
                facets[name] = FacetSet(data[f"facet_cells__{name}"], data[f"facet_local__{name}"])
        spec_json = str(data["spec_json"])
        return Mesh(
            points=data["points"],
            cells=data["cells"],
            regions=data["regions"],
            facets=facets,
            spec=MeshSpec.from_dict(json.loads(spec_json)) if spec_json else None,
        )
