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
    """The mesh as a ``pyvista.UnstructuredGrid``.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    pyvista.UnstructuredGrid
        Quadratic tets with points in m, cell data ``region``, and field data holding
        the facet sets (``facets:<name>``, (m, 2): owner cell, local face) and the spec.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import to_pyvista
    >>> grid = to_pyvista(mesh)
    >>> grid.n_cells, grid.n_points, int(grid.cell_data["region"].max())
    (108, 245, 0)
    """
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    cells = np.hstack([np.full((mesh.n_cells, 1), 10), mesh.cells]).ravel()
    types = np.full(mesh.n_cells, _VTK_QUADRATIC_TETRA, dtype=np.uint8)
    grid = pv.UnstructuredGrid(cells, types, np.array(mesh.points))
    grid.cell_data["region"] = np.asarray(mesh.regions, dtype=np.int32)
    for name, fs in mesh.facets.items():
        if len(fs):  # VTK holds no empty arrays: an empty set is known by its name alone
            grid.field_data[f"facets:{name}"] = np.stack([fs.cells, fs.local.astype(np.int64)], 1)
    grid.field_data["facet_set_names"] = [json.dumps(list(mesh.facets))]
    if mesh.spec is not None:
        grid.field_data["mesh_spec_json"] = [json.dumps(mesh.spec.to_dict(), sort_keys=True)]
    return grid


def from_pyvista(grid) -> Mesh:
    """The :class:`Mesh` of a grid made by :func:`to_pyvista` (or read from its VTU).

    Parameters
    ----------
    grid : pyvista.UnstructuredGrid
        Quadratic tets with cell data ``region``.

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        The grid holds other cells than quadratic tets, or no ``region`` cell data.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import from_pyvista, to_pyvista
    >>> from_pyvista(to_pyvista(mesh)).same_as(mesh)
    True
    """
    types = np.asarray(grid.celltypes)
    if types.size and np.any(types != _VTK_QUADRATIC_TETRA):
        raise ValueError("grid must contain only VTK_QUADRATIC_TETRA (24) cells")
    if "region" not in grid.cell_data:
        raise ValueError("grid has no cell data 'region'")
    conn = np.asarray(grid.cell_connectivity, dtype=np.int64).reshape(-1, 10)
    names = FACET_SETS
    if "facet_set_names" in grid.field_data:  # files written before it: the non-empty sets
        names = json.loads(str(np.asarray(grid.field_data["facet_set_names"])[0]))
    facets = {}
    for name in names:
        key = f"facets:{name}"
        if key in grid.field_data:
            arr = np.asarray(grid.field_data[key]).reshape(-1, 2)
            facets[name] = FacetSet(arr[:, 0], arr[:, 1])
        elif name in FACET_SETS and "facet_set_names" in grid.field_data:
            facets[name] = FacetSet(np.zeros(0, np.int64), np.zeros(0, np.int8))
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
    """Write the mesh to a VTU file (binary, lossless) that ParaView opens.

    Parameters
    ----------
    mesh : Mesh
    path : str or os.PathLike
        File to write; missing folders are made.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> import tempfile
    >>> from fringekit.meshes import read_vtu, write_vtu
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_vtu(mesh, f"{d}/mesh.vtu")
    ...     print(path.name, read_vtu(path).same_as(mesh))
    mesh.vtu True
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    to_pyvista(mesh).save(path, binary=True)
    return path


def read_vtu(path: str | os.PathLike) -> Mesh:
    """Read a mesh written by :func:`write_vtu`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Mesh

    Raises
    ------
    ValueError
        The file is not a quadratic-tet grid with ``region`` cell data.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> import tempfile
    >>> from fringekit.meshes import read_vtu, write_vtu
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = read_vtu(write_vtu(mesh, f"{d}/mesh.vtu"))
    >>> back.n_cells, back.spec == mesh.spec
    (108, True)
    """
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    return from_pyvista(pv.read(Path(path)))


def facet_grid(mesh: Mesh, name: str):
    """A ``pyvista.UnstructuredGrid`` of the 6-node triangles of one facet set (for viewing).

    Parameters
    ----------
    mesh : Mesh
    name : str
        A facet set of the mesh (:data:`FACET_SETS`).

    Returns
    -------
    pyvista.UnstructuredGrid
        Quadratic triangles on the mesh's points (m).

    Raises
    ------
    KeyError
        The mesh has no facet set ``name``.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import facet_grid
    >>> facet_grid(mesh, "contact").n_cells
    18
    """
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    nodes = mesh.facet_nodes(name)
    cells = np.hstack([np.full((len(nodes), 1), 6), nodes]).ravel()
    types = np.full(len(nodes), _VTK_QUADRATIC_TRIANGLE, dtype=np.uint8)
    return pv.UnstructuredGrid(cells, types, np.array(mesh.points))


def save_npz(mesh: Mesh, path: str | os.PathLike) -> Path:
    """Write the mesh to ``path`` (npz) atomically: a crash never leaves a partial file.

    The format of the mesh cache (:func:`build_mesh`).

    Parameters
    ----------
    mesh : Mesh
    path : str or os.PathLike
        File to write; missing folders are made.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> import tempfile
    >>> from fringekit.meshes import load_npz, save_npz
    >>> with tempfile.TemporaryDirectory() as d:
    ...     print(load_npz(save_npz(mesh, f"{d}/mesh.npz")).same_as(mesh))
    True
    """
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
    """Read a mesh written by :func:`save_npz`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Mesh

    Raises
    ------
    OSError, ValueError, KeyError, zipfile.BadZipFile
        A missing, truncated or foreign file (:data:`UNREADABLE` lists them).

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> import tempfile
    >>> from fringekit.meshes import load_npz, save_npz
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = load_npz(save_npz(mesh, f"{d}/mesh.npz"))
    >>> back.points.shape, back.points.flags.writeable
    ((245, 3), False)
    """
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
