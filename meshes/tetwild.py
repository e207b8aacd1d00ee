"""fTetWild (through pytetwild) as the mesher of an arbitrary layered block.

Kept for comparison with the deterministic layered mesher and for geometry that is not a
flat layer stack. fTetWild is not reproducible: the same input gives a different mesh on
every run, even single-threaded (measured 5,475-5,688 nodes for one 12 mm block).

Pipeline (fTetWild behaviour measured on this project: ``docs/validation.md``, "Meshes"):

1. trimesh builds the closed surfaces of the layers, merged into one soup that keeps
   the internal interface face, so a single fTetWild run conforms at the interface.
2. A graded target size (:func:`meshes.sizing.target_size`) is carried to fTetWild
   by a background tet grid (fTetWild's ``--bg-mesh``).
3. fTetWild's boundary lies within its epsilon envelope, not on the planes; the caller
   snaps boundary and interface nodes to the exact planes (tolerance :func:`snap_tolerance`).
"""

from __future__ import annotations

import contextlib
import os
import tempfile

import numpy as np
import trimesh

from .sizing import background_grid, target_size
from .spec import MeshSpec

__all__ = [
    "tetwild_tets",
    "snap_tolerance",
    "FTETWILD_SIZE_FACTOR",
    "FTETWILD_MAX_PASSES",
    "EPSILON_REL",
]

#: fTetWild treats the background size as a soft target and its edges come out longer
#: than asked (measured: mean edge 1.3-1.9 x the target at the contact face with
#: epsilon 1e-3). The field passed to it is the requested size times this factor; the
#: test suite checks that the measured mean edge length in each refined zone stays
#: within 1.2 x the requested size.
FTETWILD_SIZE_FACTOR = 0.65

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


def tetwild_tets(spec: MeshSpec, num_threads: int, epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """Run fTetWild; returns linear tets (points in m, (c, 4) cells)."""
    import pytetwild  # lazy: fTetWild's extension, only for mesher = "tetwild"

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


def snap_tolerance(points: np.ndarray, epsilon: float) -> float:
    """Distance (m) within which fTetWild's boundary nodes may lie off their plane."""
    return 4 * epsilon * float(np.linalg.norm(np.ptp(points, axis=0)))
