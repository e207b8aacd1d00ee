"""Newton-Raphson with line search and augmented-Lagrangian updates for one increment.

:func:`evaluate` assembles the total potential, its reduced residual and (optionally) the
reduced tangent at a :class:`fea.model.State`; :func:`newton` iterates to equilibrium
with a backtracking line search (energy or residual decrease, never an inverted
element) and updates the contact multipliers (lambda <- p, inexact Uzawa) once the
residual is small; :func:`solve_increment` adds the check that no facet outside the
candidate set penetrates, and the stick/slip return mapping of the anchors.

Each iterate Newton moves to is committed (:meth:`fea.model.State.commit`): a point that
came into contact on the way keeps the anchor where it first touched, so the stick
energy is continuous along every line search and no iterate sticks a point to where it
was at the increment's start.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .assembly import body_state, body_tangent
from .contact import sphere_contact
from .model import Model, State
from .run import BodyCache, Run
from .stats import SolveStats

__all__ = [
    "evaluate",
    "is_cycling",
    "line_search",
    "newton",
    "solve_increment",
]

log = logging.getLogger("fringekit.fea")

#: residual (relative to the load) below which the multipliers are updated
AL_SWITCH = 1e-3
#: residual (relative to the load) below which the previous factorization is tried
#: first (fea.linsolve.LinearSolver.solve, ``reuse``)
REUSE_BELOW = 1e-4
#: contact pressure, in units of the sheet's Young's modulus, above which the negative
#: curvature term of the contact tangent is capped (fea.contact.sphere_contact,
#: ``p_curvature_cap``). Converged Hertzian peak pressures of the built-in cases are
#: 0.3-0.8 E, where the tangent stays exact.
CURVATURE_CAP = 1.0
#: residual (relative to the load) below which a two-value cycle of the Newton iterates is
#: broken by a multiplier update (see newton)
CYCLE_AL = 1e-2


def _body(model: Model, st: State, tangent: bool, stats: SolveStats, cache: BodyCache | None):
    """The body's element evaluation at ``st.u`` (with its tangent when asked): reused
    from ``cache`` when it holds one at the same displacements, the tangent formed on it
    when missing; what is computed is counted in ``stats``."""
    body = cache.get(st.u) if cache is not None else None
    if body is None:
        body = body_state(st.u, model.cells, model.grads, model.groups, tangent=False)
        stats.residual_evaluations += 1
    elif not tangent or body.Ke is not None:
        return body
    if tangent and body.min_J > 0:
        body = body_tangent(body, model.grads, model.groups)
        stats.tangent_assemblies += 1
    if cache is not None and body.min_J > 0:
        cache.put(st.u, body)
    return body


def evaluate(
    model: Model,
    st: State,
    f_ind: np.ndarray,
    *,
    tangent: bool,
    stats: SolveStats,
    cache: BodyCache | None = None,
):
    """Energy, reduced residual, reduced tangent and per-indenter contact results.

    Parameters
    ----------
    model : Model
    st : State
    f_ind : (m, 3) applied indenter loads, model share (N)
    tangent : bool
        Also assemble the reduced tangent (sparse, N/m).
    stats : SolveStats
        Assembly and contact times, and the evaluations made, are added to it.
    cache : BodyCache, optional
        Reuse the body evaluation when it was made at ``st.u``; store a new one.

    Returns
    -------
    (energy (J), r (n_free,) N, K or None, contact results, body state, R (n + m, 3) N),
    or None when an element is inverted.
    """
    t0 = time.perf_counter()
    body = _body(model, st, tangent, stats, cache)
    t1 = time.perf_counter()
    stats.time_assembly += t1 - t0
    if body.min_J <= 0:
        return None
    R = np.zeros((model.n + model.m, 3))
    R[: model.n] = body.force
    energy = body.energy
    x = model.mesh.points + st.u
    mu = model.contact.friction
    results = []
    parts = [(*model.elem_scatter, body.Ke.ravel())] if tangent else []
    for j, ind in enumerate(model.indenters):
        faces = model.cand[j]
        res = sphere_contact(
            model.face.points(x, faces),
            model.face.weights[faces],
            st.c[j],
            ind.radius,
            st.lam[j],
            model.eps_n[j],
            mu=mu,
            anchor=st.anchor[j] if mu > 0 else None,
            anchored=st.touched[j] if mu > 0 else None,
            y_from=st.y_prev[j] if mu > 0 else None,
            eps_t=model.contact.tangential_factor * model.eps_n[j],
            tangent=tangent,
            p_curvature_cap=CURVATURE_CAP * model.sheet.E,
        )
        results.append(res)
        energy += res.energy - float(f_ind[j] @ st.c[j])
        nodes = model.face.nodes[faces].ravel()
        for i in range(3):
            R[: model.n, i] += np.bincount(
                nodes, weights=res.force[:, :6, i].ravel(), minlength=model.n
            )
        R[model.n + j] += res.force[:, 6].sum(axis=0) - f_ind[j]
        if tangent:
            parts.append((*model.contact_scatter[j], res.K.ravel()))
            if not np.any(res.p > 0) and len(model.ind_free[j]):
                # an indenter out of contact has no stiffness in its free components
                parts.append(model.open_spring(j, f_ind[j], st.c[j]))
    t2 = time.perf_counter()
    stats.time_contact += t2 - t1
    r = R.ravel()[model.free]
    K = model.pattern.matrix(parts) if tangent else None
    stats.time_assembly += time.perf_counter() - t2
    return energy, r, K, results, body, R


def penetration_ratio(model: Model, st: State, results) -> float:
    """Largest penetration of an active point relative to its indenter's depth."""
    worst = 0.0
    for j, res in enumerate(results):
        depth = model.c0[j, 2] - st.c[j, 2]
        act = res.p > 0
        pen = float(max(0.0, -res.gap[act].min())) if np.any(act) else 0.0
        if depth > 0:
            worst = max(worst, pen / depth)
    return worst


def _slide_anchors(model: Model, st: State, j: int, res) -> None:
    """Return mapping: slipping points move their anchor so that eps_t |s| = mu p."""
    if not np.any(res.slip):
        return
    mu = model.contact.friction
    eps_t = model.contact.tangential_factor * model.eps_n[j]
    x = model.mesh.points + st.u
    y = model.face.points(x, model.cand[j]) - st.c[j]
    sn = np.linalg.norm(res.s, axis=-1)
    scale = np.where(res.slip, mu * res.p / (eps_t * np.where(sn > 0, sn, 1.0)), 1.0)
    s_new = res.s * scale[..., None]
    a = y - s_new
    a = model.indenters[j].radius * a / np.linalg.norm(a, axis=-1, keepdims=True)
    st.anchor[j][res.slip] = a[res.slip]


def solve_increment(run: Run, st: State, s_new: float, iter_log: list, final=True):
    """Newton with augmented-Lagrangian updates for one increment. Mutates ``st``.
    Returns (converged, reason for failure). An increment on the way to a load state
    (not ``final``) of frictionless contact, which is path-independent, is solved to
    equilibrium without multiplier updates (its pressure still becomes the next
    increment's multiplier); with friction every increment is solved in full."""
    model = run.model
    f_ind, _ = model.targets(s_new)
    fscale = float(np.abs(f_ind).max())
    penalty_only = not final and model.contact.friction == 0
    for _attempt in range(4):
        ok, reason, results = newton(run, st, f_ind, fscale, iter_log, penalty_only)
        if not ok:
            return False, reason
        # penetration check against EVERY contact facet, not only the candidates
        x = model.mesh.points + st.u
        all_q = model.face.points(x)
        expanded = False
        for j, ind in enumerate(model.indenters):
            d = np.linalg.norm(all_q - st.c[j], axis=-1) - ind.radius
            pen_faces = np.flatnonzero((d < 0).any(axis=1))
            if np.setdiff1d(pen_faces, model.cand[j]).size:
                expanded = True
        if not expanded:
            for j, res in enumerate(results):
                st.lam[j] = res.p.copy()
                st.active[j] = res.p > 0
                if model.contact.friction > 0:
                    _slide_anchors(model, st, j, res)
            st.results = results
            return True, ""
        cand = model.candidates_near(x, st.c, extra=2 * float(model.face_size.max()))
        model.recandidate(st, cand)
    return False, "the contact zone kept growing beyond the candidate facets"


def line_search(run: Run, st: State, f_ind, dx, energy: float, rnorm: float):
    """Backtracking on energy or residual; never an inverted element.

    Returns (accepted evaluation or None, step length alpha). Trials evaluate energy and
    residual only; the accepted iterate gets its tangent when a linear solve needs it
    (:func:`fea.assembly.body_tangent`, on the trial's kinematics), so a rejected trial
    costs no tangent.
    """
    model = run.model
    alpha = 1.0
    base_u, base_c = st.u.copy(), st.c.copy()
    dfull = np.zeros((model.n + model.m) * 3)
    dfull[model.free] = dx
    du = dfull.reshape(-1, 3)
    for _ in range(8):
        st.u = base_u + alpha * du[: model.n]
        st.c = base_c + alpha * du[model.n :]
        trial = evaluate(model, st, f_ind, tangent=False, stats=run.stats, cache=run.cache)
        if trial is not None:
            e_t, r_t = trial[0], trial[1]
            if e_t <= energy + 1e-12 * abs(energy) or np.linalg.norm(r_t) < rnorm:
                return trial, alpha
        alpha *= 0.5
    st.u, st.c = base_u, base_c
    return None, alpha


def is_cycling(history: list[float]) -> bool:
    """The last four residuals alternate between two values (to 0.1 %): Newton is
    bouncing between two active sets instead of converging."""
    if len(history) < 4:
        return False
    a, b, c, d = history[-4:]
    return abs(d - b) <= 1e-3 * d and abs(c - a) <= 1e-3 * c and abs(d - c) > 1e-3 * d


def _update_multipliers(run: Run, st: State, results, f_ind):
    """Uzawa step lambda <- p; returns the evaluation at the same displacements (the
    tangent only when the body's is at hand: Newton assembles it when it needs it)."""
    for j, res in enumerate(results):
        st.lam[j] = res.p.copy()
    run.stats.al_updates += 1
    body = run.cache.get(st.u)
    has_k = body is not None and body.Ke is not None
    return _current(run, st, f_ind, tangent=has_k)


def _current(run: Run, st: State, f_ind, *, tangent: bool):
    """Evaluate ``st`` and commit it as the current iterate (None: an inverted element)."""
    out = evaluate(run.model, st, f_ind, tangent=tangent, stats=run.stats, cache=run.cache)
    if out is not None:
        st.commit(out[3])
    return out


def newton(run: Run, st: State, f_ind, fscale: float, iter_log: list, penalty_only=False):
    """Newton-Raphson with line search; multiplier updates once the residual is small.

    The multipliers are updated (lambda <- p) whenever the residual has dropped below
    :data:`AL_SWITCH` times the load and the penetration still exceeds the tolerance;
    the iteration then continues from the same displacements (inexact Uzawa).

    Returns (converged, reason for failure, contact results).
    """
    model, lin, stats = run.model, run.lin, run.stats
    settings, contact = model.settings, model.contact
    updates = 0
    e0 = None
    e_last = None
    history: list[float] = []  # residual norms of this Newton run (N)
    prev = _current(run, st, f_ind, tangent=True)
    if prev is None:
        return False, "inverted element at the start of the increment", None
    for it in range(settings.max_iterations):
        energy, r, K, results, body, _ = prev
        rnorm = float(np.linalg.norm(r))
        contact_force = max(
            (float(np.abs(res.force[:, 6].sum(axis=0)).max()) for res in results), default=0.0
        )
        scale = max(fscale, contact_force, 1e-6)
        history.append(rnorm)
        cycling = is_cycling(history)
        if cycling and rnorm <= CYCLE_AL * scale and updates < contact.max_updates:
            # a contact point flips in and out of the active set from one iterate to the
            # next: a multiplier update moves its trial pressure off the switch
            prev = _update_multipliers(run, st, results, f_ind)
            updates += 1
            stats.cycle_breaks += 1
            history.clear()
            e_last = None
            continue
        if rnorm <= AL_SWITCH * scale:
            ratio = 0.0 if penalty_only else penetration_ratio(model, st, results)
            if ratio > contact.penetration_tol:
                if updates >= contact.max_updates:
                    return (
                        False,
                        f"penetration still {ratio:.3g} of the depth after {updates} "
                        "multiplier updates",
                        None,
                    )
                prev = _update_multipliers(run, st, results, f_ind)
                updates += 1
                e_last = None
                continue
            if rnorm <= settings.force_tol * scale and (
                e_last is None or e_last <= settings.energy_tol * e0
            ):
                iter_log.append({"iteration": it, "residual_N": rnorm, "energy_norm_J": 0.0})
                return True, "", results
        t_it, f_it = time.perf_counter(), lin.time_factorize
        if K is None:  # an accepted trial, not converged: its tangent, on its kinematics
            prev = _current(run, st, f_ind, tangent=True)
            energy, r, K, results, body, _ = prev
        dx = lin.solve(
            K,
            -r,
            symmetric=model.symmetric,
            pattern_id=model.pattern_id,
            reuse=rnorm < REUSE_BELOW * scale,
        )
        stats.newton_iterations += 1
        if not np.all(np.isfinite(dx)):
            return False, "the linear solve returned non-finite values", None
        enorm = abs(float(dx @ r))
        e0 = enorm if e0 is None else max(e0, enorm)
        e_last = enorm
        accepted, alpha = line_search(run, st, f_ind, dx, energy, rnorm)
        row = {"iteration": it, "residual_N": rnorm, "energy_norm_J": enorm, "alpha": alpha}
        iter_log.append(row)
        log.debug("fea: %s", row)
        if accepted is None:
            return False, "the line search found no decreasing, admissible step", None
        st.commit(accepted[3])
        prev = accepted  # without its tangent: formed at the next step if one is needed
        stats.iteration_times.append((time.perf_counter() - t_it, lin.time_factorize - f_it))
        run.watch.check(it, rnorm, settings.max_iterations)
    return False, f"Newton did not converge in {settings.max_iterations} iterations", None
