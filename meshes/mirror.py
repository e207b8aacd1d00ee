"""Unfold a symmetric model by mirroring it about its symmetry plane."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .mesh import FacetSet, Mesh
from .topology import TET_FACES

__all__ = ["mirror", "mirror_with_sources"]

#: Swapping corners 1 and 2 of a VTK QUADRATIC_TETRA (and the mid-edge nodes with them)
#: restores a positive orientation after a reflection.
_SWAP = np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])
#: Face index of a cell face after the swap (same corner set).
_FACE_AFTER_SWAP = np.array(
    [
        next(k for k in range(4) if set(TET_FACES[k]) == {int(_SWAP[c]) for c in face})
        for face in TET_FACES
    ]
)
_PLANES = {0: "symmetry_x0", 1: "symmetry_y0"}


def mirror(mesh: Mesh, axis: int) -> Mesh:
    """Mirror ``mesh`` about its symmetry plane (see :func:`mirror_with_sources`).

    Parameters
    ----------
    mesh : Mesh
        A half or quarter model.
    axis : {0, 1}
        Mirror about x = 0 (0) or y = 0 (1). A quarter model is mirrored about x = 0
        first.

    Returns
    -------
    Mesh
        Both halves, the plane's facet set removed, ``spec.symmetry`` one step fuller.

    Raises
    ------
    ValueError
        ``axis`` not 0 or 1, or the mesh has no symmetry plane on that axis.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import mirror
    >>> half = mirror(mesh, 0)
    >>> full = mirror(half, 1)
    >>> half.spec.symmetry, full.spec.symmetry, full.n_cells == 4 * mesh.n_cells
    ('half', 'full', True)
    """
    return mirror_with_sources(mesh, axis)[0]


def mirror_with_sources(mesh: Mesh, axis: int) -> tuple[Mesh, np.ndarray]:
    """Mirror ``mesh`` about its symmetry plane ``x = 0`` (axis 0) or ``y = 0`` (axis 1).

    The result holds both halves with shared nodes on the plane and loses that plane's
    facet set: a quarter model mirrored about x = 0 is the half model of the same
    discretisation, mirrored again about y = 0 the full model. Used to write a symmetric
    model's results on the full sensor and to check symmetry boundary conditions on
    identical meshes.

    Parameters
    ----------
    mesh : Mesh
        A half or quarter model.
    axis : {0, 1}
        The plane's normal: x (0) or y (1).

    Returns
    -------
    mirrored : Mesh
    sources : (n_mirrored,) int64 array
        The point of ``mesh`` each point of ``mirrored`` is (a copy or the mirror image
        of): the first ``mesh.n_points`` are the identity, so nodal fields unfold as
        ``field[sources]`` with the components that change sign flipped on the copies.

    Raises
    ------
    ValueError
        ``axis`` not 0 or 1, or the mesh has no symmetry plane on that axis.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> from fringekit.meshes import mirror_with_sources
    >>> half, sources = mirror_with_sources(mesh, 0)
    >>> n = mesh.n_points
    >>> half.n_points - n  # the copies: every node off the plane x = 0
    210
    >>> import numpy as np
    >>> bool(np.array_equal(half.points[n:, 0], -mesh.points[sources[n:], 0]))
    True
    """
    if axis not in _PLANES:
        raise ValueError(f"axis = {axis!r} is not allowed; use 0 (x = 0) or 1 (y = 0)")
    plane = _PLANES[axis]
    if mesh.spec is not None and mesh.spec.symmetry == "quarter" and axis == 1:
        raise ValueError(
            "mirror a quarter model about x = 0 (axis 0) first: half models keep y >= 0"
        )
    if plane not in mesh.facets:
        raise ValueError(f"mesh has no {plane} facet set to mirror about")
    pts = mesh.points
    scale = max(float(np.ptp(pts[:, axis])), 1e-300)
    on_plane = np.abs(pts[:, axis]) <= 1e-9 * scale
    n = len(pts)
    new_id = np.where(on_plane, np.arange(n), n + np.cumsum(~on_plane) - 1)
    copy = pts[~on_plane].copy()
    copy[:, axis] *= -1.0
    points = np.vstack([pts, copy])
    cells2 = new_id[mesh.cells][:, _SWAP]
    cells = np.vstack([mesh.cells, cells2])
    regions = np.concatenate([mesh.regions, mesh.regions])
    c = len(mesh.cells)
    facets = {
        name: FacetSet(
            np.concatenate([fs.cells, fs.cells + c]),
            np.concatenate([fs.local, _FACE_AFTER_SWAP[fs.local]]),
        )
        for name, fs in mesh.facets.items()
        if name != plane
    }
    spec = mesh.spec
    if spec is not None:
        sym = {"quarter": "half", "half": "full"}.get(spec.symmetry, spec.symmetry)
        spec = replace(spec, symmetry=sym)
    sources = np.concatenate([np.arange(n), np.flatnonzero(~on_plane)])
    return Mesh(points, cells, regions, facets, spec), sources
