"""The converged state at one load level, with stress recovery and VTU export."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from fringekit.meshes import Mesh, mirror_with_sources

from .element import TET_QUADRATURE

__all__ = ["IndenterState", "Solution", "unfold", "write_solution_vtu"]


@dataclass(frozen=True)
class IndenterState:
    """One indenter at a converged load state (physical values, whole indenter).

    Parameters
    ----------
    centre : (3,) float array
        Current sphere centre (m).
    radius : float
        Sphere radius (m).
    depth : float
        Indentation depth from first touch of the undeformed face (m).
    force : (3,) float array
        Force the indenter exerts on the sheet (N); z < 0 presses.
    contact_radius : float
        Radius of the contact edge (m): where the open gap beyond it closes, g^(2/3)
        fitted by a quadratic in r (:func:`fea.contact_edge.edge_radius`); the radius of
        the circle with the projected contact area where that fit's sd exceeds 0.5 %.
    max_penetration : float
        Largest penetration at a quadrature point (m).
    points : (k, 3) float array
        Current positions of the contact quadrature points (model part, m).
    pressure : (k,) float array
        Cauchy contact pressure at those points (Pa).
    contact_radius_sd : float
        Standard error of ``contact_radius`` from the edge fit (m); NaN for the area's
        circle. It is the fit's own: on the reference case the radius moves between
        meshes of 0.3-0.15 mm by up to 2.5 times it (1.1842-1.1878 mm; sd 0.0014 mm
        on the default mesh).

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, stats = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.2, 0.5])])
    >>> ind = solutions[-1].indenters[0]
    >>> round(float(-ind.force[2]), 3)  # N pressing
    0.5
    >>> round(ind.depth * 1e3, 2), round(ind.contact_radius * 1e3, 1)  # mm
    (0.15, 0.4)
    >>> sorted(ind.as_dict())[:4]
    ['centre_mm', 'contact_radius_mm', 'contact_radius_sd_mm', 'depth_mm']
    """

    centre: np.ndarray
    radius: float
    depth: float
    force: np.ndarray
    contact_radius: float
    max_penetration: float
    points: np.ndarray
    pressure: np.ndarray
    contact_radius_sd: float = math.nan

    def as_dict(self) -> dict:
        """Summary in the field's units (issue 6 summary.json keys)."""
        return {
            "force_N": [float(v) for v in self.force],
            "depth_mm": self.depth * 1e3,
            "contact_radius_mm": self.contact_radius * 1e3,
            "contact_radius_sd_mm": (
                None if math.isnan(self.contact_radius_sd) else self.contact_radius_sd * 1e3
            ),
            "centre_mm": [float(v) * 1e3 for v in self.centre],
            "radius_mm": self.radius * 1e3,
            "max_penetration_mm": self.max_penetration * 1e3,
        }


def _extrapolation_matrix() -> np.ndarray:
    """(10, 4): nodal values of the linear field through the 4 quadrature-point values."""
    rst = TET_QUADRATURE[0]
    Lq = np.column_stack([1 - rst.sum(axis=1), rst])  # (q, 4) barycentric of the qps
    corner = np.linalg.inv(Lq)  # corner values = inv(Lq) @ qp values
    E = np.zeros((10, 4))
    E[:4] = corner
    mids = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
    E[4:] = 0.5 * (corner[mids[:, 0]] + corner[mids[:, 1]])
    return E


@dataclass(frozen=True)
class Solution:
    """Converged state of the sensor at one load state (made by :func:`solve`).

    Parameters
    ----------
    mesh : Mesh
        The reference mesh.
    displacement : (n, 3) float array
        Nodal displacements (m).
    stress_qp : (c, q, 3, 3) float array
        Cauchy stress at the 4 quadrature points of each cell (Pa).
    jbar : (c,) float array
        Element mean dilatation (current / reference volume).
    indenters : tuple of IndenterState
    base_reaction : (3,) float array
        Force of the fixed base on the modelled part (N).
    model_fraction : tuple of float
        Share of each indenter that is modelled (1, 1/2, 1/4).
    load_factor : float
        Position along the load path (state index, may be fractional for a state
        reached before a failure).
    log : list of dict
        One row per Newton iteration.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, stats = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.2, 0.5])])
    >>> sol = solutions[-1]
    >>> sol.displacement.shape, sol.stress_qp.shape, sol.model_fraction
    ((245, 3), (108, 4, 3, 3), (0.25,))
    >>> sol.stress_nodes.shape  # recovered to the nodes, Pa
    (245, 3, 3)
    >>> round(float(sol.base_reaction[2]), 3)  # N on the quarter: a quarter of 0.5 N
    0.125
    """

    mesh: Mesh
    displacement: np.ndarray
    stress_qp: np.ndarray
    jbar: np.ndarray
    indenters: tuple[IndenterState, ...]
    base_reaction: np.ndarray
    model_fraction: tuple[float, ...]
    load_factor: float
    log: list = field(default_factory=list, repr=False)

    @cached_property
    def points(self) -> np.ndarray:
        """(n, 3) deformed node positions (m)."""
        return self.mesh.points + self.displacement

    @cached_property
    def stress_nodes(self) -> np.ndarray:
        """(n, 3, 3) Cauchy stress recovered to nodes (Pa).

        The 4 quadrature values of each cell define a linear field, extrapolated to the
        cell's nodes and averaged over the cells sharing a node, volume-weighted,
        separately per region so the sheet/substrate jump is kept on the sheet side
        of interface nodes (they take the sheet's value).
        """
        return self._recover((1, 0))  # substrate first, the sheet overwrites shared nodes

    def stress_nodes_region(self, region: int) -> np.ndarray:
        """(n, 3, 3) Cauchy stress recovered from the cells of one region only (Pa).

        Nodes outside the region get zero. At the sheet/substrate interface the in-plane
        stresses jump; this is the value on the given region's side (used for the light
        path through the polycarbonate, where :attr:`stress_nodes` holds the sheet's).
        """
        return self._recover((int(region),))

    def _recover(self, regions) -> np.ndarray:
        E = _extrapolation_matrix()
        cells = self.mesh.cells
        vals = np.einsum("aq,cqij->caij", E, self.stress_qp).reshape(len(cells), 10, 9)
        w = np.abs(self.mesh.volumes)
        out = np.zeros((self.mesh.n_points, 9))
        for region in regions:
            sel = self.mesh.regions == region
            if not np.any(sel):
                continue
            idx = cells[sel].ravel()
            wt = np.repeat(w[sel], 10)
            den = np.bincount(idx, weights=wt, minlength=self.mesh.n_points)
            has = den > 0
            for k in range(9):
                num = np.bincount(
                    idx, weights=wt * vals[sel][:, :, k].ravel(), minlength=self.mesh.n_points
                )
                out[has, k] = num[has] / den[has]
        out = out.reshape(-1, 3, 3)
        # mirror symmetry: on the plane x = 0 (y = 0) the components that change sign under
        # the mirror, sigma_xy and sigma_xz (sigma_xy and sigma_yz), vanish in the physical
        # field; the recovered values there are extrapolation error, and unfolding a
        # quarter model mirrored them into a seam (a jump of 8.5 grey levels against 2.6
        # between neighbouring rows of the sin 2theta six-step images)
        for name, odd in (("symmetry_x0", (0, 2)), ("symmetry_y0", (1, 2))):
            if name in self.mesh.facets and len(self.mesh.facets[name]):
                nodes = np.unique(self.mesh.facet_nodes(name))
                i, j = odd
                out[nodes, i, j] = out[nodes, j, i] = 0.0
                out[nodes, 0, 1] = out[nodes, 1, 0] = 0.0
        return out

    def sheet_volume_change(self) -> float:
        """Relative volume change of the sheet region (current/reference - 1)."""
        sel = self.mesh.regions == 0
        V = np.abs(self.mesh.volumes[sel])
        return float((self.jbar[sel] * V).sum() / V.sum() - 1.0)

    def summary(self) -> dict:
        return {
            "load_factor": self.load_factor,
            "indenters": [i.as_dict() for i in self.indenters],
            "base_reaction_N": [float(v) for v in self.base_reaction],
            "model_fraction": list(self.model_fraction),
            "newton_iterations": len(self.log),
        }


def unfold(sol: Solution) -> tuple[Mesh, np.ndarray, np.ndarray, np.ndarray]:
    """The solution of a half or quarter model on the full sensor, by mirroring.

    Returns (full mesh, displacement (n, 3) m, Cauchy stress (n, 3, 3) Pa, J-bar (c,)).
    A mirror about the plane x_a = 0 flips the displacement component a and the stress
    components with exactly one index a (sigma_xy, sigma_xz for x = 0). A full model is
    returned as it is.
    """
    mesh, u, s, jbar = sol.mesh, sol.displacement, sol.stress_nodes, sol.jbar
    symmetry = mesh.spec.symmetry if mesh.spec is not None else "full"
    for axis in {"quarter": (0, 1), "half": (1,)}.get(symmetry, ()):
        n = mesh.n_points
        mesh, src = mirror_with_sources(mesh, axis)
        flip = np.ones(3)
        flip[axis] = -1.0
        u = np.vstack([u, u[src[n:]] * flip])
        s = np.vstack([s, s[src[n:]] * (flip[:, None] * flip[None, :])])
        jbar = np.concatenate([jbar, jbar])
    return mesh, u, s, jbar


def write_solution_vtu(
    sol: Solution, path: str | os.PathLike, *, deformed: bool = True, full: bool = True
) -> Path:
    """Write the state as a VTU (quadratic tets) readable by ParaView and pyvista.

    SI units throughout (m, Pa), in the sensor frame (x, y on the contact face, z up,
    interface at z = 0). Point data: ``displacement_m``; ``cauchy_stress_Pa`` (9
    components, row-major sigma_xx, sigma_xy, ... sigma_zz); ``von_mises_stress_Pa``;
    ``secondary_principal_stress_difference_Pa`` = sqrt((sxx - syy)^2 + 4 sxy^2), what a
    camera looking along z sees. Cell data: ``region`` (0 photoelastic sheet,
    1 substrate) and ``volume_ratio_Jbar``, the element's mean dilatation (deformed over
    undeformed volume, 1 = no volume change). Field data: ``model`` says which part of
    the sensor was modelled and what the file holds.

    Parameters
    ----------
    sol : Solution
    path : str or os.PathLike
        File to write (replaced atomically); missing folders are made.
    deformed : bool
        Points at their deformed positions (default) or undeformed.
    full : bool
        Unfold a half or quarter model onto the whole sensor (default); False writes the
        modelled part only.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, stats = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.2, 0.5])])
    >>> import tempfile
    >>> import pyvista as pv
    >>> from fringekit.fea import write_solution_vtu
    >>> with tempfile.TemporaryDirectory() as d:
    ...     grid = pv.read(write_solution_vtu(solutions[-1], f"{d}/state.vtu"))
    >>> grid.n_cells == 4 * mesh.n_cells  # the quarter unfolded
    True
    >>> "cauchy_stress_Pa" in grid.point_data
    True
    """
    import pyvista as pv  # lazy: VTK takes ~0.3 s to load; only VTU files need it

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if full:
        mesh, u, s, jbar = unfold(sol)
    else:
        mesh, u, s, jbar = sol.mesh, sol.displacement, sol.stress_nodes, sol.jbar
    cells = mesh.cells
    grid = pv.UnstructuredGrid(
        np.hstack([np.full((len(cells), 1), 10), cells]).ravel(),
        np.full(len(cells), pv.CellType.QUADRATIC_TETRA, dtype=np.uint8),
        mesh.points + u if deformed else mesh.points,
    )
    grid.point_data["displacement_m"] = u
    grid.point_data["cauchy_stress_Pa"] = s.reshape(-1, 9)
    dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    grid.point_data["von_mises_stress_Pa"] = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
    grid.point_data["secondary_principal_stress_difference_Pa"] = np.sqrt(
        (s[:, 0, 0] - s[:, 1, 1]) ** 2 + 4 * s[:, 0, 1] ** 2
    )
    grid.cell_data["region"] = mesh.regions.astype(np.int32)
    grid.cell_data["volume_ratio_Jbar"] = jbar
    part = sol.mesh.spec.symmetry if sol.mesh.spec is not None else "full"
    grid.field_data["model"] = [
        f"{part} model"
        + (", unfolded onto the full sensor" if full and part != "full" else "")
        + f"; {'deformed' if deformed else 'undeformed'} coordinates in m; stresses in Pa"
    ]
    tmp = path.with_name(path.name + ".part.vtu")
    grid.save(tmp)
    os.replace(tmp, path)
    return path
