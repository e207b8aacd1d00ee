"""Generate the quadratic tetrahedral mesh of a bonded sheet/substrate block.

Pipeline (fTetWild behaviour measured on this project: ``docs/validation.md``, "Meshes"):

1. trimesh builds the closed surfaces of the layers, merged into one soup that keeps
   the internal interface face, so a single fTetWild run conforms at the interface.
2. A graded target size (:func:`meshes.sizing.target_size`) is carried to fTetWild
   by a background tet grid (fTetWild's ``--bg-mesh``).
3. fTetWild's boundary lies within its epsilon envelope, not on the planes: nodes of
   boundary and interface faces are snapped to the exact planes, then quality is
   checked (inverted or degenerate cells raise :class:`MeshQualityError`).
4. Cells are labelled by centroid (sheet: z > 0), facets are classified by plane,
   and mid-edge nodes are added at exact midpoints.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
import time

import numpy as np
import trimesh

from .mesh import REGION_SHEET, REGION_SUBSTRATE, FacetSet, Mesh
from .quality import MeshQualityError, check_quality
from .sizing import background_grid, target_size
from .spec import MeshSpec
from .topology import TET_FACES, add_midside_nodes, boundary_faces, face_keys, orient_positive

__all__ = ["generate_mesh", "FTETWILD_SIZE_FACTOR", "MESHER_VERSION"]

log = logging.getLogger("fringekit.meshes")

#: fTetWild treats the background size as a soft target and its edges come out longer
#: than asked (measured: mean edge 1.3-1.9 x the target at the contact face with
#: epsilon 1e-3). The field passed to it is the requested size times this factor; the
#: test suite checks that the measured mean edge length in each refined zone stays
#: within 1.2 x the requested size.
FTETWILD_SIZE_FACTOR = 0.65

#: Bumped whenever the meshing algorithm changes what it produces (part of the cache key).
MESHER_VERSION = "1"

#: Cap on fTetWild's optimisation passes (its default is 80). A pass ends the
#: optimisation once the worst AMIPS energy is below 10; the test blocks need 0-19 passes,
#: the reference and foot meshes 0-2. On rare runs (2 of 44 repeats of an 8 x 8 mm
#: quarter block) the worst energy stays above 10, and from pass ~13 fTetWild refines to
#: escape: 8k vertices grew to 820k by pass 28 and the call ran 5-8 minutes (seen in CI).
#: Stopping at 20 keeps such a mesh near 14k vertices; the quality check after it still
#: rejects inverted cells.
FTETWILD_MAX_PASSES = 20

#: fTetWild envelope relative to the bounding-box diagonal (its default). Tighter
#: envelopes cost 10-20x the time (measured 3 s -> 65 s for a quarter block at 2e-4).
EPSILON_REL = 1e-3

_MM = 1e3  # fTetWild runs in millimetres so its absolute tolerances are well scaled


def _layer_surface(spec: MeshSpec) -> trimesh.Trimesh:
    """Triangle soup of the layer boxes; the shared interface face appears twice."""
    xmin, xmax, ymin, ymax, _, _ = spec.bounds()
    lay = spec.layers
    slabs = [(0.0, lay.z_top)]
    if lay.substrate_thickness > 0:
        slabs.append((lay.z_bottom, 0.0))
    boxes = []
    for z0, z1 in slabs:
        lo, hi = np.array([xmin, ymin, z0]), np.array([xmax, ymax, z1])
        box = trimesh.creation.box(bounds=np.vstack([lo, hi]) * _MM)
        boxes.append(box)
    soup = trimesh.util.concatenate(boxes)
    soup.merge_vertices(digits_vertex=9)
    return soup


@contextlib.contextmanager
def _cwd(path: str):
    """Temporarily change the working directory (contextlib.chdir is Python >= 3.11)."""
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def _tetrahedralise(
    spec: MeshSpec, num_threads: int, epsilon: float
) -> tuple[np.ndarray, np.ndarray]:
    """Run fTetWild; returns linear tets (points in m, (c, 4) cells)."""
    import pytetwild

    surf = _layer_surface(spec)
    diag = float(np.linalg.norm(np.ptp(surf.vertices, axis=0)))
    pad = 4 * epsilon * diag / _MM + spec.sizing.h_contact
    bg_pts, bg_tets = background_grid(spec, pad)
    h = target_size(spec, bg_pts) * FTETWILD_SIZE_FACTOR
    # fTetWild writes a debug file (__tracked_surface.stl) into the working directory:
    # run it from a scratch directory so nothing lands in the user's folder.
    with tempfile.TemporaryDirectory(prefix="fringekit-ftetwild-") as scratch, _cwd(scratch):
        v, c = pytetwild.tetrahedralize(
            np.asarray(surf.vertices, dtype=np.float64),
            np.asarray(surf.faces, dtype=np.int32),
            edge_length_abs=spec.sizing.h_far * _MM,
            epsilon=epsilon,
            vtk_ordering=True,
            num_threads=num_threads,
            num_opt_iter=FTETWILD_MAX_PASSES,
            bg_vertices=bg_pts * _MM,
            bg_tets=bg_tets,
            bg_values=h * _MM,
        )
    return np.asarray(v, dtype=np.float64) / _MM, np.asarray(c, dtype=np.int64)


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
            f"(tolerance {tol:.3e} m); fTetWild did not honour the geometry"
        )
    points[ids, axis] = value


def generate_mesh(spec: MeshSpec, *, num_threads: int = 0) -> Mesh:
    """Mesh a bonded sheet/substrate block with quadratic tetrahedra (no cache).

    Parameters
    ----------
    spec : MeshSpec
        Geometry, indenter sites, sizing and symmetry (SI units).
    num_threads : int
        fTetWild threads; 0 uses all cores.

    Returns
    -------
    Mesh
        Points (m), 10-node tets, region per cell and the facet sets ``contact``,
        ``interface`` (empty for a single sheet), ``bottom``, ``sides`` and the
        symmetry planes of the model.

    Raises
    ------
    MeshQualityError
        If fTetWild's output cannot be snapped onto the exact geometry or contains
        inverted or degenerate cells.
    """
    t0 = time.perf_counter()
    try:
        mesh = _mesh_once(spec, num_threads, EPSILON_REL)
    except MeshQualityError as exc:
        log.warning("%s; retrying with a tighter fTetWild envelope", exc)
        mesh = _mesh_once(spec, num_threads, EPSILON_REL / 2)
    log.info(
        "meshed %d nodes / %d tets in %.1f s", mesh.n_points, mesh.n_cells, time.perf_counter() - t0
    )
    return mesh


def _mesh_once(spec: MeshSpec, num_threads: int, epsilon: float) -> Mesh:
    """One fTetWild run followed by snapping, labelling and the quadratic upgrade."""
    pts, tets = _tetrahedralise(spec, num_threads, epsilon)
    tets = orient_positive(pts, tets)
    used = np.unique(tets)
    if used.size != len(pts):  # drop unreferenced nodes
        remap = np.full(len(pts), -1, dtype=np.int64)
        remap[used] = np.arange(used.size)
        pts, tets = pts[used], remap[tets]

    diag = float(np.linalg.norm(np.ptp(pts, axis=0)))
    tol = 4 * epsilon * diag  # fTetWild's envelope is epsilon * diag; quality is checked after
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
            f"{centre[bad[0]]} m); fTetWild produced an inner hole or a surface off the geometry"
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
