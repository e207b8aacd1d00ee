"""The discrete contact problem: DOF numbering, supports, contact candidates, load targets.

:class:`Model` holds what is fixed during a solve (the mesh sorted by material, reference
gradients, fixed DOFs, the contact face, the indenters and settings) plus the contact
candidate facets and the sparse pattern, which change only when the contact zone grows.
:class:`State` is one iterate: displacements, indenter centres and the per-facet
contact multipliers, stick anchors and active flags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fringekit.meshes import Mesh

from .analytic import depth_guess, dimitriadis_force
from .assembly import Pattern, cell_dofs
from .contact import ContactFace
from .element import reference_gradients
from .materials import Material
from .problem import ContactSettings, Indenter, SolverSettings

__all__ = ["Model", "State"]


class Model:
    """Everything fixed during a run: DOF numbering, patterns, reference gradients.

    Parameters
    ----------
    mesh : meshes.Mesh
    indenters : sequence of Indenter
        Those in the modelled part.
    materials : dict region -> Material
    contact : ContactSettings
    settings : SolverSettings
    parents : sequence of int, optional
        The load path as a tree: load state k (1..S) is reached from state
        ``parents[k - 1]`` (0 = unloaded). Default: from state k - 1.
    """

    def __init__(
        self,
        mesh: Mesh,
        indenters,
        materials: dict[int, Material],
        contact: ContactSettings,
        settings: SolverSettings,
        parents=None,
    ):
        self.mesh = mesh
        self.indenters = tuple(indenters)
        self.contact = contact
        self.settings = settings
        self.n, self.m = mesh.n_points, len(self.indenters)
        self._sort_cells(materials)
        fixed = self._supports()
        for j, ind in enumerate(self.indenters):
            self._check_indenter(j, ind)
        self._indenter_dofs(fixed)
        self._contact_face()
        S = self.indenters[0].n_states
        self.parents = tuple(range(S)) if parents is None else tuple(int(p) for p in parents)
        self._state_targets()

    # -- set-up steps ------------------------------------------------------------------
    def _sort_cells(self, materials: dict) -> None:
        """Cells sorted by region: every material is one contiguous range, so the element
        kernels run on views (fea.assembly); Solution arrays are put back in mesh order."""
        mesh = self.mesh
        self.order = np.argsort(mesh.regions, kind="stable")
        self.inverse = np.argsort(self.order)
        self.cells = mesh.cells[self.order]
        self.grads = reference_gradients(mesh.points, self.cells)
        self.groups = []
        self.mesh_groups = []
        sorted_regions = mesh.regions[self.order]
        for region in np.unique(mesh.regions):
            if int(region) not in materials:
                raise ValueError(
                    f"mesh region {int(region)} has no material; materials given for "
                    f"regions {sorted(materials)}"
                )
            mat = materials[int(region)]
            if not isinstance(mat, Material):
                raise ValueError(
                    f"materials[{int(region)}] = {mat!r} is not a fea.Material "
                    "(NeoHookean or MooneyRivlin)"
                )
            self.groups.append((np.flatnonzero(sorted_regions == region), mat))
            self.mesh_groups.append((np.flatnonzero(mesh.regions == region), mat))
        self.sheet = materials[0]

    def _supports(self) -> np.ndarray:
        """(n + m, 3) fixed flags: bottom all components, symmetry planes their normal."""
        mesh = self.mesh
        fixed = np.zeros((self.n + self.m, 3), dtype=bool)
        fixed[np.unique(mesh.facet_nodes("bottom"))] = True
        self.frac = np.ones(self.m)
        self.sym_axes: list[int] = []
        for name, axis in (("symmetry_x0", 0), ("symmetry_y0", 1)):
            if name in mesh.facets and len(mesh.facets[name]):
                fixed[np.unique(mesh.facet_nodes(name)), axis] = True
                self.sym_axes.append(axis)
        zmax = float(mesh.points[:, 2].max())
        self.z_top = zmax
        spec = mesh.spec
        self.thickness = spec.layers.sheet_thickness if spec is not None else zmax
        self.lo, self.hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
        self.lateral_free = np.zeros((self.m, 2), dtype=bool)
        return fixed

    def _check_indenter(self, j: int, ind: Indenter) -> None:
        """Indenter ``j`` fits on the sheet; its share on symmetry planes and its free
        lateral components (shear under friction)."""
        lo, hi = self.lo, self.hi
        pos = (ind.x, ind.y)
        for a in range(2):
            if pos[a] - ind.radius < lo[a] - 1e-12 and not (
                a in self.sym_axes and abs(pos[a]) < 1e-12
            ):
                raise ValueError(
                    f"indenters[{j}] at {'xy'[a]} = {pos[a]!r} m with radius {ind.radius!r} m "
                    f"reaches beyond the sheet edge {'xy'[a]} = {lo[a]!r} m"
                )
            if pos[a] + ind.radius > hi[a] + 1e-12:
                raise ValueError(
                    f"indenters[{j}] at {'xy'[a]} = {pos[a]!r} m with radius {ind.radius!r} m "
                    f"reaches beyond the sheet edge {'xy'[a]} = {hi[a]!r} m"
                )
        if ind.radius >= 0.5 * min(hi[0] - lo[0], hi[1] - lo[1]) * (2 if self.sym_axes else 1):
            raise ValueError(
                f"indenters[{j}].radius = {ind.radius!r} m is too large for the sheet "
                f"({(hi - lo)[:2]} m modelled)"
            )
        shear = ind.shear_targets()
        for a in range(2):
            on_plane = a in self.sym_axes and abs(pos[a]) < 1e-12
            if on_plane:
                self.frac[j] *= 0.5
                if np.any(shear[:, a] != 0):
                    raise ValueError(
                        f"indenters[{j}].shear_force has a {'xy'[a]} component but the "
                        f"indenter sits on the symmetry plane {'xy'[a]} = 0; use a full "
                        f"model or a half model with shear along x"
                    )
            elif np.any(shear[:, a] != 0):
                if self.contact.friction == 0:
                    raise ValueError(
                        f"indenters[{j}].shear_force is not zero but friction = 0: a "
                        "frictionless sphere carries no tangential load; set a friction "
                        "coefficient or inf for full stick"
                    )
                self.lateral_free[j, a] = True

    def _indenter_dofs(self, fixed: np.ndarray) -> None:
        """Fix the indenters' prescribed components and number the free DOFs."""
        n, m = self.n, self.m
        for j, ind in enumerate(self.indenters):
            fixed[n + j, :2] = ~self.lateral_free[j]
            fixed[n + j, 2] = not ind.force_control
        self.fixed = fixed.ravel()
        self.dofmap = np.full(3 * (n + m), -1, dtype=np.int64)
        free = np.flatnonzero(~self.fixed)
        self.dofmap[free] = np.arange(len(free))
        self.n_free = len(free)
        self.free = free
        self.ind_free = [self.dofmap[3 * (n + j) + np.flatnonzero(~fixed[n + j])] for j in range(m)]

    def _contact_face(self) -> None:
        """The contact face, facet sizes, indenter start centres and empty candidates."""
        mesh = self.mesh
        self.face = ContactFace.from_points(mesh.points, mesh.facet_nodes("contact"))
        fx = mesh.points[self.face.nodes[:, :3]]
        edges = np.linalg.norm(fx - np.roll(fx, 1, axis=1), axis=-1)
        self.face_size = edges.max(axis=1)
        self.centroids = fx.mean(axis=1)
        self.symmetric = not (0 < self.contact.friction < math.inf)
        self.c0 = np.array([[i.x, i.y, self.z_top + i.radius] for i in self.indenters])
        self.cand: list[np.ndarray] = [np.zeros(0, dtype=np.int64) for _ in self.indenters]
        self.eps_n = np.zeros(self.m)
        self.pattern: Pattern | None = None
        self.pattern_id = 0
        self.elem_dofs = self.dofmap[cell_dofs(self.cells)]  # in the element tangent's order
        self.elem_scatter = None
        self.contact_scatter: list = []

    # -- loads -------------------------------------------------------------------------
    def _state_targets(self) -> None:
        """Loads (S + 1, m, 3) (model share, N) and centres (S + 1, m, 3) (m) of the
        unloaded state and of every load state."""
        S = len(self.parents)
        f = np.zeros((S + 1, self.m, 3))
        c = np.repeat(self.c0[None], S + 1, axis=0)
        for j, ind in enumerate(self.indenters):
            if ind.force_control:
                f[1:, j, 2] = -ind.normal_targets() * self.frac[j]
            else:
                c[1:, j, 2] = self.c0[j, 2] - ind.normal_targets()
            f[1:, j, :2] = ind.shear_targets() * self.frac[j]
        self.state_f, self.state_c = f, c

    def targets(self, s: float, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Applied indenter loads (model share, N) and prescribed centres (m) at load-path
        position ``s`` (0 = unloaded, k = load state k; linear from state k's parent at
        s = k - 1 to state k at s = k). ``k`` names the segment where ``s`` is its start
        (by default the segment ending at or after ``s``)."""
        if k is None:
            k = max(1, math.ceil(s - 1e-9))
        p, t = self.parents[k - 1], s - (k - 1)
        f0, c0 = self.state_f[p], self.state_c[p]
        return f0 + t * (self.state_f[k] - f0), c0 + t * (self.state_c[k] - c0)

    def z_free(self, j: int) -> bool:
        """True when indenter ``j``'s vertical position is an unknown (force control)."""
        return not self.fixed[3 * (self.n + j) + 2]

    def open_spring(self, j: int, f: np.ndarray, c: np.ndarray):
        """Tangent-only spring on the free components of indenter ``j`` out of contact.

        Without contact a force-controlled indenter has no stiffness: the tangent is
        singular in its free components and the Newton step throws the indenter away
        (energy norms of 1e11 J on the foot example). The spring is the bonded-layer
        contact stiffness dF/dd (Dimitriadis et al. 2002) at the depth that formula
        gives for the current load ``f`` (N, model share; at the current depth under
        displacement control; at least 2 % of the radius), so the step moves an open
        indenter to about 2/3 of its expected depth (F ~ d^1.5). It enters the tangent
        only, never the residual: the converged state is unchanged. On the foot example
        it took the Newton iterations from 83 to 49 (two failed first increments with
        energy norms of 1e11 J before).

        Returns
        -------
        (positions, local indices, values) for :meth:`Pattern.matrix` (N/m).
        """
        ind = self.indenters[j]
        E, h = self.sheet.E, self.thickness
        if ind.force_control:
            d = depth_guess(abs(float(f[2])) / self.frac[j], ind.radius, E, h)
        else:
            d = float(self.c0[j, 2] - c[2])
        d = max(d, 0.02 * ind.radius)
        dd = 1e-3 * d
        k = (
            dimitriadis_force(d + dd, ind.radius, E, h)
            - dimitriadis_force(d - dd, ind.radius, E, h)
        ) / (2 * dd)
        dofs = self.ind_free[j]
        pos = np.searchsorted(self.pattern.keys, dofs.astype(np.int64) * (self.n_free + 1))
        return pos, np.arange(len(dofs)), np.full(len(dofs), float(k) * self.frac[j])

    # -- numbering and contact candidates ------------------------------------------------
    def _node_dofs(self, nodes: np.ndarray) -> np.ndarray:
        g = (3 * nodes[..., None] + np.arange(3)).reshape(len(nodes), -1)
        return self.dofmap[g]

    def contact_dofs(self, j: int, faces: np.ndarray) -> np.ndarray:
        """(f, 21) equation numbers of contact facets ``faces`` with indenter ``j``."""
        nd = self._node_dofs(self.face.nodes[faces])
        ind = self.dofmap[3 * (self.n + j) + np.arange(3)]
        return np.hstack([nd, np.broadcast_to(ind, (len(faces), 3))])

    def set_candidates(self, cand: list[np.ndarray]) -> None:
        """New candidate facets per indenter: penalties, and the pattern when they change."""
        changed = self.pattern is None or any(
            not np.array_equal(a, b) for a, b in zip(cand, self.cand, strict=True)
        )
        self.cand = cand
        for j in range(len(self.indenters)):
            h = float(np.mean(self.face_size[cand[j]])) if len(cand[j]) else 1e-3
            self.eps_n[j] = self.contact.penalty_factor * self.sheet.E / h
        if changed:
            blocks = [self.elem_dofs] + [self.contact_dofs(j, c) for j, c in enumerate(cand)]
            self.pattern = Pattern(self.n_free, blocks, symmetric=self.symmetric)
            self.pattern_id += 1
            self.elem_scatter = self.pattern.scatter(self.elem_dofs)
            self.contact_scatter = [
                self.pattern.scatter(self.contact_dofs(j, c)) for j, c in enumerate(cand)
            ]

    def candidates_near(self, x: np.ndarray, centres: np.ndarray, extra: float = 0.0):
        """Facets whose current centroid is within reach of each indenter (horizontal)."""
        cen = np.einsum("fa,fai->fi", np.full((1, 3), 1 / 3), x[self.face.nodes[:, :3]])
        out = []
        hmax = float(self.face_size.max())
        for j, ind in enumerate(self.indenters):
            d = np.hypot(cen[:, 0] - centres[j, 0], cen[:, 1] - centres[j, 1])
            out.append(np.flatnonzero(d < ind.radius + 2 * hmax + extra))
        return out

    def recandidate(self, st: State, cand: list[np.ndarray]) -> None:
        """Switch to candidates ``cand``, carrying ``st``'s contact state over; the points
        of the facets new to the set start from their current positions."""
        st.remap(self.cand, cand)
        self.set_candidates(cand)
        self.set_touch_base(st)

    def refresh_candidates(self, st: State) -> None:
        """After an accepted increment refresh the candidate facets for the next one."""
        cand = self.candidates_near(self.mesh.points + st.u, st.c)
        if any(not np.array_equal(a, b) for a, b in zip(cand, self.cand, strict=True)):
            self.recandidate(st, cand)

    def set_touch_base(self, st: State) -> None:
        """The positions relative to each centre that the first-touch anchors of the next
        evaluation start from (:func:`fea.contact.first_touch_anchors`): ``st``'s."""
        x = self.mesh.points + st.u
        st.y_prev = [self.face.points(x, c) - st.c[j] for j, c in enumerate(self.cand)]


@dataclass
class State:
    """One iterate of the solve (mutable: Newton updates it in place).

    Attributes
    ----------
    u : (n, 3) nodal displacements (m)
    c : (m, 3) indenter centres (m)
    lam : per indenter (f, q) augmented-Lagrangian multipliers (contact pressure, N)
    anchor : per indenter (f, q, 3) stick anchors on the sphere, relative to its centre (m)
    active : per indenter (f, q) bool, in contact at the last converged state
    results : the converged contact results, or None
    touched : per indenter (f, q) bool, in contact at the current iterate: their anchors
        are fixed; the others are anchored where they first touch
    y_prev : per indenter (f, q, 3) positions relative to the centre at the current
        iterate (m), where the first-touch anchors of the next evaluation start from
    """

    u: np.ndarray
    c: np.ndarray
    lam: list
    anchor: list
    active: list
    results: list | None = None
    touched: list = field(default_factory=list)
    y_prev: list = field(default_factory=list)

    @classmethod
    def initial(cls, model: Model) -> State:
        """The unloaded state with empty contact data on the model's candidates."""
        nq = model.face.n_qp
        return cls(
            u=np.zeros((model.n, 3)),
            c=model.c0.copy(),
            lam=[np.zeros((0, nq)) for _ in model.indenters],
            anchor=[np.zeros((0, nq, 3)) for _ in model.indenters],
            active=[np.zeros((0, nq), dtype=bool) for _ in model.indenters],
            touched=[np.zeros((0, nq), dtype=bool) for _ in model.indenters],
            y_prev=[np.zeros((0, nq, 3)) for _ in model.indenters],
        )

    def copy(self) -> State:
        return State(
            self.u.copy(),
            self.c.copy(),
            [a.copy() for a in self.lam],
            [a.copy() for a in self.anchor],
            [a.copy() for a in self.active],
            self.results,
            [a.copy() for a in self.touched],
            [a.copy() for a in self.y_prev],
        )

    def commit(self, results) -> None:
        """Make the evaluation ``results`` at this state the current iterate's contact
        state: the points in contact keep the anchors they were given, and the next
        first-touch anchors start from these positions."""
        for j, res in enumerate(results):
            self.touched[j] = res.p > 0
            self.y_prev[j] = res.y
            if res.anchor is not None:
                self.anchor[j] = res.anchor

    def remap(self, old: list[np.ndarray], cand: list[np.ndarray]) -> None:
        """Carry multipliers, anchors and contact flags from facets ``old`` to ``cand``
        (zero on facets new to the set)."""
        for j in range(len(cand)):
            nq = self.lam[j].shape[1]
            pos = np.minimum(np.searchsorted(old[j], cand[j]), max(len(old[j]) - 1, 0))
            hit = old[j][pos] == cand[j] if len(old[j]) else np.zeros(len(cand[j]), bool)
            for name, shape, dtype in (
                ("lam", (nq,), float),
                ("anchor", (nq, 3), float),
                ("active", (nq,), bool),
                ("touched", (nq,), bool),
            ):
                new = np.zeros((len(cand[j]), *shape), dtype=dtype)
                new[hit] = getattr(self, name)[j][pos[hit]]
                getattr(self, name)[j] = new
