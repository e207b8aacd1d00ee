"""Generate the quadratic tetrahedral mesh of a bonded sheet/substrate block.

Two meshers make the linear tets (``MeshSpec.mesher``):

- ``"layered"`` (default): a graded plane triangulation extruded through the layers
  (:mod:`meshes.layered`). Deterministic: the same spec gives the same mesh, node for
  node, on every run and machine with the same numpy and scipy.
- ``"tetwild"``: fTetWild (:mod:`meshes.tetwild`), not reproducible run to run; kept for
  comparison and for geometry that is not a flat layer stack.

Then, for both: nodes of boundary and interface faces are put exactly on their planes
(fTetWild's lie within its envelope), quality is checked (inverted or degenerate cells
raise :class:`MeshQualityError`), cells are labelled by centroid (sheet: z > 0), facets
are classified by plane, and mid-edge nodes are added at exact midpoints.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .layered import layered_tets
from .mesh import REGION_SHEET, REGION_SUBSTRATE, FacetSet, Mesh
from .quality import MeshQualityError, check_quality
from .spec import MeshSpec
from .tetwild import EPSILON_REL, snap_tolerance, tetwild_tets
from .topology import TET_FACES, add_midside_nodes, boundary_faces, face_keys, orient_positive

__all__ = ["mesh_uncached", "MESHER_VERSION"]

log = logging.getLogger("fringekit.meshes")

#: Bumped whenever a mesher changes what it produces (part of the cache key).
MESHER_VERSION = "4"

#: Tolerance (m) for "on the plane" with the layered mesher, whose planes are exact.
_EXACT_TOL = 1e-12


def _planes(spec: MeshSpec) -> dict[str, list[tuple[int, float]]]:
    """Boundary facet set name -> list of (axis, coordinate) planes (m)."""
    xmin, xmax, ymin, ymax, zmin, zmax = spec.bounds()
    planes = {"contact": [(2, zmax)], "bottom": [(2, zmin)], "sides": [(0, xmax), (1, ymax)]}
    if spec.symmetry == "quarter":
        planes["symmetry_x0"] = [(0, xmin)]
    else:
        planes["sides"].append((0, xmin))
    if spec.symmetry in ("half", "quarter"):
        planes["symmetry_y0"] = [(1, ymin)]
    else:
        planes["sides"].append((1, ymin))
    return planes


def _interface_faces(tets: np.ndarray, regions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sheet cell, local face) of every face shared by a sheet and a substrate cell."""
    keys, _ = face_keys(tets)
    _, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    shared = np.flatnonzero(counts[inv] == 2)
    order = shared[np.argsort(inv[shared], kind="stable")]
    a, b = order[0::2], order[1::2]
    ca, cb = a // 4, b // 4
    across = regions[ca] != regions[cb]
    a, b, ca = a[across], b[across], ca[across]
    sheet_first = regions[ca] == REGION_SHEET
    owner = np.where(sheet_first, a, b)
    return owner // 4, owner % 4


def _snap(points: np.ndarray, ids: np.ndarray, axis: int, value: float, tol: float, what: str):
    """Set points[ids, axis] = value after checking they lie within tol of the plane."""
    dev = np.abs(points[ids, axis] - value)
    if dev.size and dev.max() > tol:
        raise MeshQualityError(
            f"{what}: {np.sum(dev > tol)} nodes lie {dev.max():.3e} m off their plane "
            f"(tolerance {tol:.3e} m); the mesher did not honour the geometry"
        )
    points[ids, axis] = value


def mesh_uncached(spec: MeshSpec, *, num_threads: int = 0) -> Mesh:
    """Mesh a bonded sheet/substrate block with quadratic tetrahedra, without the cache.

    Users call :func:`meshes.build_mesh` (``use_cache=False`` meshes again and does not
    write the cache), which calls this. With the default ``spec.mesher = "layered"`` the
    result depends only on ``spec`` (and the numpy and scipy versions), bit for bit.

    Parameters
    ----------
    spec : MeshSpec
        Geometry, indenter sites, sizing and symmetry (SI units).
    num_threads : int
        fTetWild threads (``mesher = "tetwild"`` only); 0 uses all cores.

    Returns
    -------
    Mesh
        Points (m), 10-node tets, region per cell and the facet sets ``contact``,
        ``interface`` (empty for a single sheet), ``bottom``, ``sides`` and the
        symmetry planes of the model.

    Raises
    ------
    MeshQualityError
        If the tets cannot be put onto the exact geometry or contain inverted or
        degenerate cells.

    Examples
    --------
    >>> from fringekit.meshes import MeshSpec, Sizing
    >>> from fringekit.meshes.build import mesh_uncached
    >>> sizing = Sizing(h_contact=2e-3, h_sheet=3e-3, h_far=10e-3)
    >>> spec = MeshSpec(sizing=sizing, symmetry="quarter")
    >>> mesh = mesh_uncached(spec)
    >>> mesh.cells.shape[1], sorted(mesh.facets)[:2]
    (10, ['bottom', 'contact'])
    """
    t0 = time.perf_counter()
    if spec.mesher == "layered":
        pts, tets = layered_tets(spec)
        mesh = _finish(spec, pts, tets, _EXACT_TOL)
    else:
        try:
            mesh = _tetwild_once(spec, num_threads, EPSILON_REL)
        except MeshQualityError as exc:
            log.warning("%s; retrying with a tighter fTetWild envelope", exc)
            mesh = _tetwild_once(spec, num_threads, EPSILON_REL / 2)
    log.info(
        "meshed %d nodes / %d tets in %.1f s (%s)",
        mesh.n_points,
        mesh.n_cells,
        time.perf_counter() - t0,
        spec.mesher,
    )
    return mesh


def _tetwild_once(spec: MeshSpec, num_threads: int, epsilon: float) -> Mesh:
    """One fTetWild run followed by :func:`_finish` within its envelope."""
    pts, tets = tetwild_tets(spec, num_threads, epsilon)
    return _finish(spec, pts, tets, snap_tolerance(pts, epsilon))


def _finish(spec: MeshSpec, pts: np.ndarray, tets: np.ndarray, tol: float) -> Mesh:
    """Orient, snap to planes (within tol, m), check, label and upgrade to quadratic."""
    tets = orient_positive(pts, tets)
    used = np.unique(tets)
    if used.size != len(pts):  # drop unreferenced nodes
        remap = np.full(len(pts), -1, dtype=np.int64)
        remap[used] = np.arange(used.size)
        pts, tets = pts[used], remap[tets]

    lay = spec.layers
    centroid_z = pts[tets].mean(axis=1)[:, 2]
    regions = np.where(centroid_z > 0.0, REGION_SHEET, REGION_SUBSTRATE).astype(np.int8)

    # Snap interface nodes to z = 0.
    iface_cell, iface_local = _interface_faces(tets, regions)
    iface_nodes = np.unique(tets[iface_cell[:, None], TET_FACES[iface_local]])
    _snap(pts, iface_nodes, 2, 0.0, tol, "interface")

    # Classify each boundary face by its normal and the nearest plane of that
    # orientation, then snap only the nodes of faces on that plane: a node on an edge
    # of the block gets both coordinates, nodes off the planes never move.
    bcell, blocal = boundary_faces(tets)
    fc = tets[bcell[:, None], TET_FACES[blocal]]  # (b, 3) corner ids
    p = pts[fc]
    normal_axis = np.argmax(np.abs(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])), axis=1)
    centre = p.mean(axis=1)
    planes = [(name, axis, value) for name, pl in _planes(spec).items() for axis, value in pl]
    label = np.full(len(bcell), -1)
    best = np.full(len(bcell), np.inf)
    for k, (_, axis, value) in enumerate(planes):
        dist = np.abs(centre[:, axis] - value)
        take = (normal_axis == axis) & (dist <= tol) & (dist < best)
        label[take], best[take] = k, dist[take]
    if np.any(label < 0):
        bad = np.flatnonzero(label < 0)
        raise MeshQualityError(
            f"{bad.size} boundary faces lie on no face of the block (first centroid "
            f"{centre[bad[0]]} m); the mesher produced an inner hole or a surface off the geometry"
        )
    for k, (name, axis, value) in enumerate(planes):
        _snap(pts, np.unique(fc[label == k]), axis, value, tol, name)
    check_quality(pts, tets)

    if lay.substrate_thickness == 0 and len(iface_cell):
        raise MeshQualityError("a single-layer mesh has interface faces")

    pts10, cells10 = add_midside_nodes(pts, tets)
    set_of_face = np.array([name for name, _, _ in planes])[label]
    facets = {
        name: FacetSet(bcell[set_of_face == name], blocal[set_of_face == name])
        for name in _planes(spec)
    }
    facets["interface"] = FacetSet(iface_cell, iface_local)
    return Mesh(points=pts10, cells=cells10, regions=regions, facets=facets, spec=spec)
