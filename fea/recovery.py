"""A converged iterate -> a :class:`fea.Solution`: stresses, reactions and contact results.

Runs once per converged load state: the Cauchy stress at every quadrature point
(:func:`fea.materials.cauchy_stress`), the base reaction, and per indenter its force
(whole indenter, the symmetry share undone), depth, contact radius, penetration and the
contact pressure at the points in contact.
"""

from __future__ import annotations

import math

import numpy as np

from .contact_edge import edge_radius
from .materials import cauchy_stress
from .model import Model, State
from .newton import evaluate
from .run import BodyCache
from .solution import IndenterState, Solution
from .stats import SolveStats

__all__ = ["make_solution"]


def _area_radius(model: Model, res, j: int, x: np.ndarray, on_planes: list) -> float:
    """Radius (m) of the circle with indenter ``j``'s projected contact area, its edge
    placed inside the facets by the sign of the trial pressure p - eps_N g; with the
    convex hull of that patch, which bridges pressure-free points inside it (the hull's
    samples sit a fraction of a sub-triangle inside the edge, the plain area misses the
    holes: the larger of the two)."""
    faces = model.cand[j]
    indicator = np.where(res.p > 0, res.p, -model.eps_n[j] * res.gap)
    area = max(
        model.face.projected_contact_area(x, faces, indicator) / model.frac[j],
        model.face.contact_hull_area(x, faces, indicator, on_planes),
    )
    return math.sqrt(area / math.pi)


def _indenter_state(model: Model, st: State, j: int, x: np.ndarray) -> IndenterState:
    """Force, depth, contact radius and pressure of indenter ``j`` at ``st``."""
    ind = model.indenters[j]
    res = st.results[j]  # the converged contact state (before the last multiplier copy)
    faces = model.cand[j]
    act = res.p > 0
    on_planes = [a for a in model.sym_axes if abs(model.c0[j, a]) < 1e-12]
    force = res.force[:, 6].sum(axis=0) / model.frac[j]
    force[on_planes] = 0.0  # the symmetry planes the indenter sits on carry none across
    cur = model.face.current_area(x, faces)
    ref = model.face.weights[faces]
    pts = model.face.points(x, faces)
    # the edge from the open gap beyond it (fea.contact_edge); the area's circle where
    # that fit cannot resolve it (too few open points near the edge, or its sd > 0.5 %)
    edge = edge_radius(pts, res.gap, act, st.c[j, :2], tuple(on_planes))
    if edge is None:
        radius, radius_sd = _area_radius(model, res, j, x, on_planes), math.nan
    else:
        radius, radius_sd = edge
    pen = float(max(0.0, -res.gap[act].min())) if np.any(act) else 0.0
    return IndenterState(
        centre=st.c[j].copy(),
        radius=ind.radius,
        depth=float(model.c0[j, 2] - st.c[j, 2]),
        force=force,
        contact_radius=radius,
        max_penetration=pen,
        points=pts[act],
        pressure=(res.p * ref / np.where(cur > 0, cur, 1.0))[act],
        contact_radius_sd=radius_sd,
    )


def make_solution(
    model: Model,
    st: State,
    s: float,
    iter_log: list,
    stats: SolveStats,
    cache: BodyCache | None = None,
) -> Solution:
    """The :class:`Solution` of converged state ``st`` at load-path position ``s``
    (``cache``: the body evaluation of the last Newton iterate, reused)."""
    f_ind, _ = model.targets(s)
    _, _, _, _, body, _ = evaluate(model, st, f_ind, tangent=False, stats=stats, cache=cache)
    F = body.F[model.inverse]  # back to mesh cell order
    jbar = body.Jbar[model.inverse]
    sigma = np.empty_like(F)
    for idx, mat in model.mesh_groups:
        sigma[idx] = cauchy_stress(mat, F[idx], jbar[idx])
    bottom = np.unique(model.mesh.facet_nodes("bottom"))
    base_reaction = body.force[bottom].sum(axis=0)  # support force on the body
    x = model.mesh.points + st.u
    return Solution(
        mesh=model.mesh,
        displacement=st.u.copy(),
        stress_qp=sigma,
        jbar=jbar,
        indenters=tuple(_indenter_state(model, st, j, x) for j in range(model.m)),
        base_reaction=base_reaction,
        model_fraction=tuple(float(v) for v in model.frac),
        load_factor=float(s),
        log=list(iter_log),
    )
