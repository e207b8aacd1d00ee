"""The FEM solution as a stress field for the optics (the deformed sheet).

Rays are vertical lines in the CURRENT configuration: each pixel's ray runs from the
deformed interface to the deformed contact face under the same (x, y). Both surfaces are
graphs over (x, y) and are interpolated linearly on their 6-node facets split into four
3-node triangles (matplotlib's C++ triangle finder). Stress at sample points comes from
the nodal (recovered) Cauchy stress of :class:`fea.Solution`, interpolated linearly on the
deformed sheet cut into 8 linear sub-tetrahedra per quadratic tetrahedron; the points are
located and interpolated by VTK's probe filter through pyvista.

Quarter and half models are unfolded by reflection: a point is folded onto the modelled
part (|x|, |y| on symmetry planes) and the shear components that change sign under the
mirror (sigma_xy and sigma_xz for x -> -x; sigma_xy and sigma_yz for y -> -y) are flipped.
"""

from __future__ import annotations

import numpy as np

__all__ = ["FEMStressField", "TET10_TO_TET4"]

#: 8 linear tetrahedra of a VTK QUADRATIC_TETRA: the four corner tets and the inner
#: octahedron (mid-nodes 4..9) split along its 4-9 diagonal.
TET10_TO_TET4 = np.array(
    [
        [0, 4, 6, 7],
        [4, 1, 5, 8],
        [6, 5, 2, 9],
        [7, 8, 9, 3],
        [4, 9, 5, 8],
        [4, 9, 8, 7],
        [4, 9, 7, 6],
        [4, 9, 6, 5],
    ]
)
#: 4 linear triangles of a 6-node triangle (corners 0-2, mids (01), (12), (20)).
TRI6_TO_TRI3 = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])


class FEMStressField:
    """A :class:`fea.Solution` seen by the optics: a :class:`StressField` of the deformed sheet.

    Rays are vertical lines in the current configuration, from the deformed interface
    to the deformed contact face; the stress is the solution's recovered nodal stress,
    interpolated linearly (module docstring). Half and quarter models are unfolded.

    Parameters
    ----------
    solution : fea.Solution
    mask_contact : bool
        Rays within an indenter's contact radius are not valid (the indenter covers them
        and the fringes there are beyond any camera's resolution; the seed paper masks the
        centre too).
    region : {"sheet", "substrate"}
        The photoelastic sheet (rays from the deformed interface to the deformed contact
        face) or the polycarbonate (from the fixed bottom to the deformed interface, with
        the stress recovered from substrate cells only).

    Raises
    ------
    ValueError
        An unknown region, or a mesh without cells of that region.

    Examples
    --------
    The smallest FEM case end to end (about a second, most of it loading VTK and the
    first solve):

    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> from fringekit.optics import PSM4_ASSUMED, FEMStressField, PixelGrid, optical_map
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, _ = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.5])])
    >>> field = FEMStressField(solutions[-1])
    >>> omap = optical_map(field, PixelGrid((9, 9), 1e-3), PSM4_ASSUMED, n_samples=8)
    >>> bool(omap.mask[4, 4]), int(omap.mask.sum())  # the contact zone at the centre is masked
    (False, 80)
    >>> import numpy as np
    >>> round(float(np.nanmax(omap.fringe_order())), 2)
    0.35
    """

    def __init__(self, solution, *, mask_contact: bool = True, region: str = "sheet"):
        import matplotlib.tri as mtri  # lazy (~0.2 s), as pyvista: only FEM fields need them
        import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only FEM fields need it

        mesh = solution.mesh
        x = solution.points
        self.solution = solution
        self.sym_axes = tuple(
            a for a, name in ((0, "symmetry_x0"), (1, "symmetry_y0")) if name in mesh.facets
        )
        if region not in ("sheet", "substrate"):
            raise ValueError(f"region = {region!r} is not allowed; use 'sheet' or 'substrate'")
        rid = 0 if region == "sheet" else 1
        if not np.any(mesh.regions == rid):
            raise ValueError(f"the mesh has no {region} cells (substrate thickness 0?)")
        self.region = region
        sel = mesh.cells[mesh.regions == rid]
        lin = sel[:, TET10_TO_TET4].reshape(-1, 4)
        cells = np.hstack([np.full((len(lin), 1), 4), lin]).ravel()
        self._grid = pv.UnstructuredGrid(cells, np.full(len(lin), pv.CellType.TETRA, np.uint8), x)
        s_nodes = solution.stress_nodes if rid == 0 else solution.stress_nodes_region(1)
        self._grid.point_data["s"] = s_nodes.reshape(-1, 9)

        def surface(name):
            tri = mesh.facet_nodes(name)[:, TRI6_TO_TRI3].reshape(-1, 3)
            used, inv = np.unique(tri, return_inverse=True)
            t = mtri.Triangulation(x[used, 0], x[used, 1], inv.reshape(-1, 3))
            return mtri.LinearTriInterpolator(t, x[used, 2])

        if rid == 0:
            self._top = surface("contact")
            # a sheet on a rigid base (substrate thickness 0) has an empty interface set:
            # its bottom is the fixed z = 0 face
            iface = mesh.facets.get("interface")
            self._bottom = surface("interface" if iface is not None and len(iface) else "bottom")
        else:
            self._top = surface("interface")
            self._bottom = surface("bottom")
        self._contact = (
            [(ind.centre[:2].copy(), ind.contact_radius) for ind in solution.indenters]
            if mask_contact
            else []
        )
        lo = mesh.points.min(axis=0)
        hi = mesh.points.max(axis=0)
        self.extent = (lo, hi)

    def _fold(self, p: np.ndarray):
        q = np.array(p, dtype=float, copy=True)
        flips = []
        for a in self.sym_axes:
            neg = q[..., a] < 0
            q[..., a] = np.abs(q[..., a])
            flips.append((a, neg))
        return q, flips

    def fold_xy(self, xy) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions (P, 2) (m) folded onto the modelled part, and whether each was
        mirrored an odd number of times (its secondary principal angle changes sign).

        A pixel and its mirror images see the same stresses up to those signs, so
        optics.grid.sample_rays integrates one ray for all of them. For a full model the
        positions come back unchanged."""
        folded, flips = self._fold(np.asarray(xy, float))
        odd = np.zeros(len(folded), bool)
        for _, neg in flips:
            odd ^= neg
        return folded, odd

    def z_range(self, xy):
        """Bottom and top heights (m) of the layer under xy (P, 2), and validity.

        Sheet: deformed interface and contact face; substrate: bottom and deformed interface.
        """
        xy = np.asarray(xy, float)
        q, _ = self._fold(np.column_stack([xy, np.zeros(len(xy))]))
        z1 = np.ma.filled(self._top(q[:, 0], q[:, 1]), np.nan)
        z0 = np.ma.filled(self._bottom(q[:, 0], q[:, 1]), np.nan)
        valid = np.isfinite(z0) & np.isfinite(z1) & (z1 > z0)
        for c, a in self._contact:
            valid &= np.hypot(xy[:, 0] - c[0], xy[:, 1] - c[1]) > a
        z0 = np.where(valid, z0, 0.0)
        z1 = np.where(valid, z1, 0.0)
        return z0, z1, valid

    def stress(self, points):
        """Cauchy stress (..., 3, 3) (Pa) at points (..., 3) in the deformed sheet.

        Points outside the deformed sheet get zero stress (they carry no light path).
        """
        import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only FEM fields need it

        p = np.asarray(points, float)
        shape = p.shape[:-1]
        q, flips = self._fold(p.reshape(-1, 3))
        probe = pv.PolyData(q).sample(self._grid)
        ok = np.asarray(probe.point_data["vtkValidPointMask"], bool)
        s = np.asarray(probe.point_data["s"], float).reshape(-1, 3, 3).copy()
        s[~ok] = 0.0
        for a, neg in flips:
            neg = neg.reshape(-1)
            for i, j in ((0, 1), (0, 2)) if a == 0 else ((0, 1), (1, 2)):
                s[neg, i, j] *= -1.0
                s[neg, j, i] *= -1.0
        self.outside_fraction = float(1.0 - ok.mean()) if ok.size else 0.0
        return s.reshape(shape + (3, 3))
