"""Newton-Raphson continuation for the bonded sheet under rigid spherical indenters.

Unknowns: the displacements of the free mesh DOFs and, per indenter, the free components
of its centre (force control: the target force is a load on the indenter, whose
equilibrium closes the system). The total potential

.. math::

    \\Pi(u, c) = \\Pi_\\mathrm{body}(u) + \\sum_j \\Pi_{c,j}(u, c_j) - \\sum_j f_j \\cdot c_j

is minimised along the load path (fea.assembly, fea.contact). Each requested load state
is reached by one or more increments; each increment runs Newton with a backtracking
line search (energy or residual decrease, never an inverted element), then
augmented-Lagrangian multiplier updates until the penetration is below the tolerance.
A failed increment is cut back by halving; when the cut-backs are exhausted a
:class:`SolverError` carries the states converged so far.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence

import numpy as np
from tqdm.auto import tqdm

from fringekit.errors import ComputeError, Interrupted
from fringekit.meshes import Mesh

from .analytic import depth_guess, dimitriadis_force, hertz_force
from .inversion import inverted_elements
from .linsolve import LinearSolver
from .materials import POLYCARBONATE_DEFAULT, SHEET_DEFAULT, Material
from .model import Model, State
from .newton import solve_increment
from .problem import ContactSettings, Indenter, SolverSettings
from .recovery import make_solution
from .run import Run
from .solution import Solution
from .stats import SolveStats
from .watchdog import Watchdog

__all__ = [
    "first_fraction",
    "friction_limit",
    "solve",
    "SolverError",
    "SolveInterrupted",
    "SolveStats",
    "dimitriadis_force",
    "hertz_force",
]

log = logging.getLogger("fringekit.fea")

#: the first increment ends where the bonded-layer formula gives this depth / thickness
FIRST_DEPTH = 0.1
#: with friction, an increment raises no indenter's normal load by more than this factor
#: (see _friction_cap)
FRICTION_STEP = 1.25
#: with friction, an increment changes no indenter's tangential load by more than this
#: fraction of its normal load (see friction_limit)
TANGENT_STEP = 0.1
#: with friction the first increment from the unloaded sheet ends at this fraction of
#: FIRST_DEPTH: its anchors come from the sphere's straight approach to the flat sheet
FRICTION_FIRST = 0.3


class SolverError(ComputeError):
    """The solver could not reach a load state.

    A :class:`fringekit.errors.ComputeError`.

    Parameters
    ----------
    message : str
    solutions : list of Solution
        Every state converged before the failure (the last one is kept).

    Examples
    --------
    Too few Newton iterations and no cut-back for a load far beyond the small sheet:

    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, SolverError, SolverSettings, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> hard = SolverSettings(max_iterations=2, max_cutbacks=0, backend="scipy")
    >>> try:
    ...     solve(mesh, [Indenter(radius=1e-3, normal_force=[0.1, 50.0])], settings=hard)
    ... except SolverError as err:
    ...     print(len(err.solutions), str(err)[:48])
    0 the solver could not reach load state 1 of 2 (in
    """

    def __init__(self, message: str, solutions: list):
        super().__init__(message)
        self.solutions = solutions


class SolveInterrupted(SolverError, Interrupted):
    """The user interrupted the solve (Ctrl-C); ``solutions`` keeps the converged states.

    A :class:`SolverError` and a :class:`fringekit.errors.Interrupted`.

    Parameters
    ----------
    message : str
    solutions : list of Solution
        Every state converged before the interruption.

    Examples
    --------
    >>> from fringekit.fea import SolveInterrupted, SolverError
    >>> err = SolveInterrupted("interrupted by the user on the way to load state 2 of 3", [])
    >>> isinstance(err, SolverError), err.solutions
    (True, [])
    """


def _check_indenters(indenters: tuple) -> int:
    """The number of load states S, after checking every indenter has S targets."""
    if not indenters:
        raise ValueError("indenters = () is not allowed; give at least one Indenter")
    S = indenters[0].n_states
    for j, ind in enumerate(indenters):
        if not isinstance(ind, Indenter):
            raise ValueError(f"indenters[{j}] = {ind!r} is not an fea.Indenter")
        if ind.n_states != S:
            raise ValueError(
                f"indenters[{j}] has {ind.n_states} load states but indenters[0] has {S}; "
                "every indenter needs one target per load state"
            )
    return S


def _reach_state(run: Run, st: State, s_done: float, k: int, ds: float, n_done: int):
    """Increments from ``s_done`` to load state ``k``, halving on failure.

    Returns (state, s reached = k, the iteration log of the state).

    Raises
    ------
    SolverError
        When the increment falls below 0.5 ** max_cutbacks (``solutions`` is filled by
        the caller).
    """
    model = run.model
    iter_log: list[dict] = []
    while s_done < k - 1e-12:
        s_new = min(s_done + ds, float(k), _friction_cap(model, s_done, k))
        model.refresh_candidates(st)
        trial = st.copy()
        _predict(model, trial, s_new)
        run.watch.start(_reached(model, s_new, k))
        ok, reason = solve_increment(run, trial, s_new, iter_log, final=s_new >= k - 1e-12)
        if ok:
            st = trial
            s_done = s_new
            run.stats.increments += 1
            ds = min(2 * ds, float(k) - s_done) if s_done < k else ds
        else:
            run.stats.cutbacks += 1
            ds *= 0.5
            log.warning(
                "fea: cut back: %s not reached (%s); trying %s",
                _reached(model, s_new, k),
                reason,
                _reached(model, s_done + ds, k),
            )
            if ds < 0.5**model.settings.max_cutbacks:
                S = model.indenters[0].n_states
                raise SolverError(
                    f"the solver could not reach load state {k} of {S} "
                    f"({_reached(model, float(k), k)}): {reason}; it reached "
                    f"{_reached(model, s_done, k)} ({n_done} load state(s) converged); try more "
                    "load states on the way, a finer contact mesh or more cut-backs",
                    [],
                )
    return st, s_done, iter_log


def solve(
    mesh: Mesh,
    indenters: Sequence[Indenter] = (Indenter(),),
    *,
    materials: dict[int, Material] | None = None,
    contact: ContactSettings | None = None,
    settings: SolverSettings | None = None,
    progress: bool | Callable[[int, int, Solution], None] = False,
    parents: Sequence[int] | None = None,
) -> tuple[list[Solution], SolveStats]:
    """Solve the contact problem along the load path; one Solution per load state.

    Parameters
    ----------
    mesh : Mesh
        Quadratic tet mesh with facet sets ``contact`` and ``bottom`` (and symmetry
        planes, which get roller conditions); regions 0 (sheet) and 1 (substrate).
    indenters : sequence of Indenter
        Rigid spheres with load paths of equal length S. Physical loads on the whole
        indenter; the modelled share (1/2 or 1/4 on symmetry planes) is applied.
    materials : dict region -> Material
        Default: {0: SHEET_DEFAULT, 1: POLYCARBONATE_DEFAULT}.
    contact, settings : ContactSettings, SolverSettings
    progress : bool or callable
        True shows a tqdm bar over load states; a callable gets (k, S, solution).
    parents : sequence of S int, optional
        A load path that branches: load state k is reached from the converged state
        ``parents[k - 1]`` (0 = unloaded, an earlier state otherwise) instead of from
        state k - 1. A response library solves one chain of normal loads with a
        tangential branch from each (:mod:`fringekit.library.build`).

    Returns
    -------
    solutions : list of Solution
        One per load state.
    stats : SolveStats

    Raises
    ------
    SolverError
        When a load state cannot be reached; ``err.solutions`` keeps converged states.
    SolveInterrupted
        On Ctrl-C, with the converged states.
    ValueError
        Indenters of different load-path lengths or invalid ``parents``.

    Examples
    --------
    0.2 N then 0.5 N on a 2 mm sheet (a quarter model of 245 nodes; a second or so):

    >>> from fringekit.meshes import IndenterSite, Layers, MeshSpec, Sizing, build_mesh
    >>> from fringekit.fea import Indenter, solve
    >>> layers = Layers(sheet_thickness=2e-3, substrate_thickness=0.0, width=10e-3, length=10e-3)
    >>> sizing = Sizing(h_contact=1e-3, refine_radius=1.5e-3, h_far=4e-3, h_sheet=2e-3)
    >>> spec = MeshSpec(layers, (IndenterSite(radius=1e-3),), sizing, symmetry="quarter")
    >>> mesh = build_mesh(spec, use_cache=False)
    >>> solutions, stats = solve(mesh, [Indenter(radius=1e-3, normal_force=[0.2, 0.5])])
    >>> [round(float(-s.indenters[0].force[2]), 3) for s in solutions]  # N, whole indenter
    [0.2, 0.5]
    >>> round(solutions[-1].indenters[0].depth * 1e3, 2)  # mm
    0.15
    """
    t_start = time.perf_counter()
    indenters = tuple(indenters)
    S = _check_indenters(indenters)
    parents = _check_parents(parents, S)
    materials = dict(materials or {0: SHEET_DEFAULT, 1: POLYCARBONATE_DEFAULT})
    contact = contact or ContactSettings()
    settings = settings or SolverSettings()
    stats = SolveStats()
    model = Model(mesh, indenters, materials, contact, settings, parents)
    lin = LinearSolver(settings.backend, settings.precision)
    stats.dofs = model.n_free
    stats.backend = lin.backend
    _log_start(model, lin)
    st = State.initial(model)
    model.recandidate(st, model.candidates_near(mesh.points, st.c))
    stats.time_setup = time.perf_counter() - t_start
    bar = None
    if progress is True:
        bar = tqdm(total=S, desc="load states", unit="state")
    run = Run(model, lin, stats, watch=Watchdog(bar=bar))
    solutions: list[Solution] = []
    s_done = 0.0
    kept = {0: (st.copy(), list(model.cand))}  # converged states later branches start from
    try:
        for k in range(1, S + 1):
            it_before = stats.newton_iterations
            p = parents[k - 1]
            if p != k - 1:  # a branch: restart from state p, with its candidates
                st, s_done = _restart(kept, model, p), float(k - 1)
            ds = _first_increment(model, k) if p == 0 else float(k) - s_done
            try:
                st, s_done, iter_log = _reach_state(run, st, s_done, k, ds, len(solutions))
            except SolverError as exc:
                raise SolverError(str(exc), solutions) from None
            except KeyboardInterrupt:
                raise SolveInterrupted(
                    f"interrupted by the user on the way to load state {k} of {S} "
                    f"({_reached(model, float(k), k)}), at {_reached(model, s_done, k)}",
                    solutions,
                ) from None
            inverted = inverted_elements(mesh.points, mesh.cells, st.u)
            if inverted:  # a fold between quadrature points (fea.inversion): no state
                raise SolverError(
                    f"load state {k} of {S} ({_reached(model, float(k), k)}) converged to an "
                    f"inverted state: {inverted}; the load is beyond what the mesh can carry",
                    solutions,
                )
            sol = make_solution(model, st, s_done, iter_log, stats, run.cache)
            _keep(kept, model, st, k, parents)
            solutions.append(sol)
            stats.iterations_per_state.append(stats.newton_iterations - it_before)
            if bar is not None:
                bar.update(1)
            elif callable(progress):
                progress(k, S, sol)
    finally:
        if bar is not None:
            bar.close()
        _close(stats, lin, t_start)
    return solutions, stats


def _log_start(model: Model, lin: LinearSolver) -> None:
    log.info(
        "fea: %d free DOFs, %d indenters, %d load states, linear solver %s (%s)",
        model.n_free,
        model.m,
        len(model.parents),
        lin.backend,
        "symmetric indefinite" if model.symmetric else "unsymmetric",
    )


def _restart(kept: dict, model: Model, p: int) -> State:
    """A copy of kept state ``p``, with the model switched to its candidates."""
    st, cand = kept[p]
    model.set_candidates(list(cand))
    return st.copy()


def _keep(kept: dict, model: Model, st: State, k: int, parents: tuple) -> None:
    """Keep converged state ``k`` (with its candidates) when a later state starts from it;
    drop the kept states no later state starts from."""
    if k in parents[k:]:
        kept[k] = (st.copy(), list(model.cand))
    for q in [q for q in kept if q not in parents[k:]]:
        del kept[q]


def _close(stats: SolveStats, lin: LinearSolver, t_start: float) -> None:
    """The linear solver's counters into ``stats``; its memory released."""
    stats.time_analysis = lin.time_analysis
    stats.time_factorize = lin.time_factorize
    stats.time_solve = lin.time_solve
    stats.factorizations = lin.n_factorizations
    stats.factor_reuses = lin.n_reuses
    lin.release()
    stats.time_total = time.perf_counter() - t_start


def _check_parents(parents, S: int) -> tuple[int, ...]:
    """The parent of every load state, after checking each names an earlier state."""
    if parents is None:
        return tuple(range(S))
    out = tuple(int(p) for p in parents)
    if len(out) != S or any(not 0 <= p < k for k, p in enumerate(out, start=1)):
        raise ValueError(
            f"parents = {list(parents)!r} is not allowed; give {S} values, the k-th an "
            "earlier load state (0 = unloaded .. k - 1)"
        )
    return out


def _whole_loads(model: Model, s: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(m,) whole-indenter normal loads (N, pressing > 0; 0 for indenters whose depth is
    prescribed) and (m, 2) tangential loads at load-path position ``s`` of segment ``k``."""
    f, _ = model.targets(s, k)
    z_free = np.array([model.z_free(j) for j in range(len(model.indenters))])
    return np.where(z_free, -f[:, 2] / model.frac, 0.0), f[:, :2] / model.frac[:, None]


def friction_limit(
    loads_from, loads_to, s_done: float, k: int, shear_from=None, shear_to=None
) -> float:
    """The furthest load-path position an increment from ``s_done`` may reach with friction.

    A point that comes into contact is anchored where the Newton iterates first carry it
    across the contact condition (:func:`fea.contact.first_touch_anchors`), along
    straight steps: the larger the increment, the further that path is from the
    loading's. The normal loads therefore rise by at most :data:`FRICTION_STEP` per
    increment (the contact radius by about 8 %, a ~ F^(1/3)), and the tangential loads
    change by at most :data:`TANGENT_STEP` of the normal load (the patch's leading edge
    touches anew as it shifts); the first increment from the unloaded sheet is short too
    (:func:`first_fraction`). On the coarse test block, 3 N in 1, 4, 8 and 16 load states
    then gives depths within 0.16 % of each other (2 % with the doubling increments
    alone); 2 N then 0.6 N tangential in one state against four gave tangential
    displacements 2.6 % apart without the tangential limit.

    Parameters
    ----------
    loads_from, loads_to : (m,) float arrays
        Whole normal loads (N) at ``s_done`` and at the segment's end ``k``.
    shear_from, shear_to : (m, 2) float arrays, optional
        Whole tangential loads (N) there.
    s_done : float
        Load-path position reached (state k - 1 < s_done < k, or its parent's).
    k : int
        The load state the segment ends at.

    Returns
    -------
    float, the position limit (``inf`` when no normal load rises that much).

    Examples
    --------
    From 2 N towards 8 N in state 1, the next increment stops at 2.5 N:

    >>> friction_limit([2.0], [8.0], 0.25, 1)
    0.3125
    """
    a, b = np.asarray(loads_from, float), np.asarray(loads_to, float)
    t = np.inf
    rise = (a > 0) & (b > FRICTION_STEP * a)
    if np.any(rise):
        t = float(((FRICTION_STEP - 1.0) * a[rise] / (b[rise] - a[rise])).min())
    if shear_from is not None and shear_to is not None:
        dt = np.hypot(*(np.asarray(shear_to, float) - np.asarray(shear_from, float)).T)
        big = (a > 0) & (dt > TANGENT_STEP * a)
        if np.any(big):
            t = min(t, float((TANGENT_STEP * a[big] / dt[big]).min()))
    return float(s_done + t * (k - s_done)) if np.isfinite(t) else np.inf


def first_fraction(loads, radii, E: float, h: float, friction: float) -> float:
    """Load fraction of the first increment towards a state from the unloaded sheet.

    Placing an undeformed sheet against a sphere at a deep guessed depth starts Newton
    with a huge penalty residual (113 N for 8 N on the test block, 28 iterations of
    damped steps). The first increment therefore stops where the bonded-layer formula
    predicts a depth of 0.1 sheet thickness (F ~ d^1.5); the increments then double.
    8 N in one state on the coarse test block: 24 Newton iterations instead of 28.
    With friction it stops at :data:`FRICTION_FIRST` of that depth: the points it brings
    into contact are anchored along the sphere's straight approach to the flat sheet,
    which the sheet's own motion departs from as the contact grows.

    Parameters
    ----------
    loads : (m,) float array
        Whole normal loads (N) of the state; 0 where the depth is prescribed.
    radii : (m,) float array
        Sphere radii (m).
    E : float
        The sheet's Young's modulus (Pa).
    h : float
        Sheet thickness (m).
    friction : float
        Friction coefficient (0 frictionless, ``inf`` full stick).

    Returns
    -------
    float in [0.05, 1].

    Examples
    --------
    8 N on the reference sheet (3 mm, 4 MPa, 1.75 mm radius), without and with stick:

    >>> round(first_fraction([8.0], [1.75e-3], 4e6, 3e-3, 0.0), 3)
    0.31
    >>> round(first_fraction([8.0], [1.75e-3], 4e6, 3e-3, float("inf")), 3)
    0.051
    """
    first = FIRST_DEPTH * h * (FRICTION_FIRST if friction > 0 else 1.0)
    frac = 1.0
    for load, radius in zip(loads, radii, strict=True):
        if load > 0:
            d = depth_guess(float(load), float(radius), E, h)
            if d > first:
                frac = min(frac, (first / d) ** 1.5)
    return max(frac, 0.05)


def _friction_cap(model: Model, s_done: float, k: int) -> float:
    """:func:`friction_limit` of the model's loads (``inf`` without friction)."""
    if model.contact.friction <= 0:
        return np.inf
    (a, ta), (b, tb) = _whole_loads(model, s_done, k), _whole_loads(model, float(k), k)
    return friction_limit(a, b, s_done, k, ta, tb)


def _first_increment(model: Model, k: int = 1) -> float:
    """:func:`first_fraction` of load state k."""
    radii = [ind.radius for ind in model.indenters]
    loads, _ = _whole_loads(model, float(k), k)
    return first_fraction(loads, radii, model.sheet.E, model.thickness, model.contact.friction)


def _reached(model: Model, s: float, k: int | None = None) -> str:
    """The loads (N) or depths (mm) at load-path position ``s`` (of segment ``k``),
    whole indenters."""
    f, c = model.targets(s, k)
    parts = []
    for j, ind in enumerate(model.indenters):
        if ind.force_control:
            text = f"{-f[j, 2] / model.frac[j] + 0.0:.4g} N"  # + 0.0: no "-0 N"
        else:
            text = f"depth {(model.c0[j, 2] - c[j, 2]) * 1e3:.4g} mm"
        if ind.shear_force is not None and np.any(f[j, :2] != 0):
            fx, fy = f[j, :2] / model.frac[j]
            text += f" with shear ({fx:.4g}, {fy:.4g}) N"
        parts.append(text)
    return "indenter loads " + ", ".join(parts)


def _predict(model: Model, st: State, s_new: float) -> None:
    """Set prescribed components; give a first-contact depth guess to force-controlled ones.

    Once an indenter is in contact no predictor is applied: the first Newton iteration
    from the last converged state with the new load IS the tangent (Euler) predictor.
    Before first contact the indenter is placed at the depth the bonded-layer formula
    gives for the new load (Dimitriadis et al. 2002).

    Not placing it and letting the open-indenter spring (:meth:`fea.model.Model.open_spring`)
    take the first step was tried: Newton iterations foot 132k DOF 49 -> 23, reference
    8 N 38 -> 26, but 34 -> 45 on the 0.4 mm reference mesh; and all 3 CI runs with it
    failed tests on coarse fresh meshes (a Coulomb case did not converge; 64 vs 128 ray
    samples differed by 0.03-0.06 fringe twice, where 32 local meshes gave < 0.003)
    that had passed for many runs before. Not understood, so the placement stays.
    """
    f_new, c_new = model.targets(s_new)
    for j, ind in enumerate(model.indenters):
        for a in range(3):
            if model.fixed[3 * (model.n + j) + a]:
                st.c[j, a] = c_new[j, a]
        if model.z_free(j) and not np.any(st.active[j]) and f_new[j, 2] < 0:
            E, h = model.sheet.E, model.thickness
            d_new = depth_guess(-f_new[j, 2] / model.frac[j], ind.radius, E, h)
            st.c[j, 2] = min(st.c[j, 2], model.c0[j, 2] - d_new)
