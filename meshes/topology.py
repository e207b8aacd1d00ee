"""Pure array kernels on tetrahedral connectivity (VTK node order).

VTK ``QUADRATIC_TETRA`` (10 nodes): corners 0-3, then mid-edge nodes on the edges
(0,1), (1,2), (2,0), (0,3), (1,3), (2,3). VTK ``QUADRATIC_TRIANGLE`` (6 nodes):
corners 0-2, then mid-edge nodes on (0,1), (1,2), (2,0).
A tetrahedron is positively oriented when ``(p1-p0) x (p2-p0) . (p3-p0) > 0``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "TET_EDGES",
    "TET_FACES",
    "TET_FACE_MIDS",
    "signed_volumes",
    "orient_positive",
    "add_midside_nodes",
    "face_keys",
    "boundary_faces",
    "unique_edges",
]

#: Corner pairs of the six tetrahedron edges in VTK mid-node order (nodes 4..9).
TET_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])

#: The four faces of a positive tetrahedron, corners ordered so the normal
#: (b-a) x (c-a) points OUT of the cell.
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])

#: For each face in TET_FACES, the local mid-node indices of its edges (a,b), (b,c), (c,a).
TET_FACE_MIDS = np.array([[6, 5, 4], [4, 8, 7], [5, 9, 8], [7, 9, 6]])


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes of linear tetrahedra.

    Parameters
    ----------
    points : (n, 3) float array
    tets : (c, >=4) int array; only the first four (corner) columns are used.

    Returns
    -------
    (c,) float array, positive for VTK-positive orientation (units of points cubed).
    """
    p = points[tets[:, :4]]
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    return np.einsum("ij,ij->i", np.cross(a, b), c) / 6.0


def orient_positive(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Return linear tets (c, 4) reordered so every signed volume is >= 0."""
    tets = np.array(tets[:, :4], dtype=np.int64, copy=True)
    neg = signed_volumes(points, tets) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2].copy(), tets[neg, 1].copy()
    return tets


def unique_edges(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique corner edges of linear tets.

    Returns
    -------
    edges : (e, 2) int array, sorted pairs.
    inverse : (c, 6) int array, edge id of each local edge in TET_EDGES order.
    """
    pairs = np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1)
    edges, inverse = np.unique(pairs, axis=0, return_inverse=True)
    return edges, inverse.reshape(-1, 6)


def add_midside_nodes(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upgrade linear tets to 10-node quadratic tets with straight edges.

    Mid-edge nodes are placed exactly at edge midpoints and shared between cells.

    Parameters
    ----------
    points : (n, 3) float array
    tets : (c, 4) int array, positively oriented.

    Returns
    -------
    points10 : (n + e, 3) float array; the first n rows are ``points``.
    cells10 : (c, 10) int64 array in VTK QUADRATIC_TETRA order.
    """
    edges, inverse = unique_edges(tets)
    mids = 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])
    points10 = np.vstack([points, mids])
    cells10 = np.hstack([tets, inverse + len(points)]).astype(np.int64)
    return points10, cells10


def face_keys(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All cell faces as sorted corner triples.

    Returns
    -------
    sorted_faces : (4c, 3) int array, corner ids of each face sorted ascending.
    oriented : (4c, 3) int array, corner ids in outward TET_FACES order.
    Row ``4*i + k`` is face k of cell i.
    """
    oriented = cells[:, TET_FACES].reshape(-1, 3)
    return np.sort(oriented, axis=1), oriented


def boundary_faces(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces that belong to exactly one cell.

    Returns
    -------
    cell : (b,) int array, the owning cell of each boundary face.
    local : (b,) int array, the face index (0..3) in TET_FACES.
    """
    keys, _ = face_keys(cells)
    _, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    once = np.flatnonzero(counts[inv.ravel()] == 1)
    return once // 4, once % 4
