"""A global search per indenter for ``fringekit invert``: the tangential load's basin.

The fit's cost is narrow in the direction of an indenter's tangential load: the fringes
near the contact turn with it. On the coarse bench's image of four sheared heads
(six-step), with the others held at a converged joint fit, one head's window cost was 455
at that fit (its tangential load 0.19 N pointing 45 deg), 450 at the true load (1.9 N at
242 deg) and 530-575 thirty degrees either side of the truth: a fit started without
tangential load converges to the nearest minimum, with the load pointing the wrong way
and a neighbour's load distorted to explain the rest.

:func:`hop` visits each indenter in turn, the others held:

1. **Scan.** Tangential directions every 360/SCAN_DIRECTIONS deg x ratios every
   SCAN_RATIO_STEP up to the library's x normal loads (SCAN_LOAD_FACTORS times the fitted
   one and SCAN_LOADS across the library), the axis held (and also at the detected axis
   when the fit moved it), on at most SCAN_PIXELS pixels of the window, each ray one
   equivalent retarder whose intensities come from a table of the polariscope's response
   (:class:`RetarderTable`, built once per pass), with the gain and offset of the joint
   fit; every candidate of one load state is one vectorised evaluation.
2. **Refine.** The best HOP_STARTS distinct candidates that beat the current parameters
   start a least-squares fit of that indenter's five parameters on its window (every 2nd
   pixel, Jones integration near the axes), its position within HOP_BOX_MM of where it was.
3. **Accept** the best refined fit when it lowers the window's robust cost by more than
   ACCEPT of it.

The caller fits all indenters jointly again when one changed, and repeats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from fringekit._threads import single_blas_thread
from fringekit.inversion.model import N_PARAMS, ImageModel, range_penalty, unpack
from fringekit.library.lattice import interpolate_turned

__all__ = ["hop", "hop_to", "search_after_drop", "retarder_lookup", "robust_cost", "RetarderTable"]

#: The window about an indenter whose pixels the search fits (mm).
WINDOW_MM = 3.0
SCAN_DIRECTIONS = 36
SCAN_RATIO_STEP = 0.1
#: Normal loads scanned: these factors times the fitted one, and SCAN_LOADS log-spaced
#: over the library's range.
SCAN_LOAD_FACTORS = (0.85, 1.0, 1.2)
SCAN_LOADS = 8
#: At most this many window pixels are scanned (a regular stride through them).
SCAN_PIXELS = 600
TABLE_PER_FRINGE = 24
TABLE_ANGLES = 72
#: A table is built this much beyond the magnitudes that asked for it.
TABLE_MARGIN = 1.5
#: Distinct candidates refined per indenter: at least this far apart in direction (deg)
#: or ratio.
HOP_STARTS = 3
DISTINCT_DEG = 30.0
DISTINCT_RATIO = 0.2
#: A refined candidate moves the axis at most this far from where it was (mm).
HOP_BOX_MM = 0.5
HOP_NFEV = 15
#: Forward-difference step of the local fits' Jacobian, times max(1, |parameter|) (mm,
#: N), as ImageModel.jacobian takes it. The library's fields are float32: at scipy's
#: default (1.5e-8) a step moves the synthesised intensities by less than their rounding,
#: and the local fit's direction then hangs on it (one test's head ended 1 or 24 deg off
#: as the last bits of the interpolation changed).
DIFF_STEP = 1e-3
#: An axis the fit moved farther than this (mm) from where detection put it is scanned
#: at both places: a neighbour's wrong load can pull it off.
ANCHOR_MM = 0.1
ACCEPT = 0.02


def robust_cost(r: np.ndarray, f_scale: float, axis=None):
    """scipy's soft-L1 cost of residuals ``r``: 0.5 sum f^2 2 (sqrt(1 + (r/f)^2) - 1),
    over ``axis`` (all of ``r`` by default)."""
    z = (np.asarray(r, float) / f_scale) ** 2
    return f_scale**2 * np.sum(np.sqrt(1.0 + z) - 1.0, axis=axis)


def _window(model: ImageModel, q: np.ndarray, k: int, exclude) -> np.ndarray:
    """Usable pixels within WINDOW_MM of indenter k, outside the contact circles of every
    parameter set in ``exclude`` (a list of (p, diam))."""
    xy = model.xy * 1e3
    win = model.usable & (np.hypot(xy[:, 0] - q[k, 0], xy[:, 1] - q[k, 1]) < WINDOW_MM)
    for p, diam in exclude:
        win &= model.outside_contacts(unpack(p, diam))
    return win


def _others(model: ImageModel, inds, k: int) -> np.ndarray:
    """Summed slab pairs (P, S, 2) of every indenter but k at the model's pixels, and of
    its residual (:meth:`ImageModel.background`)."""
    lib, xy = model.lib, model.xy
    out = np.zeros((len(xy), lib.lattice.n_slabs, 2), np.float32)
    for j, ind in enumerate(inds):  # a handful of indenters
        if j != k:
            out += lib.slabs(ind, xy)[0]
    return model.with_background(out)


@dataclass(frozen=True)
class RetarderTable:
    """A model's intensities of rays that are one linear retarder each, tabulated over
    the summed slab vector's magnitude (TABLE_PER_FRINGE steps per fringe at the
    shortest wavelength, from 0 to ``top``) and angle (every 360/TABLE_ANGLES deg).

    The polariscope is evaluated on the table's nodes only; a lookup is bilinear (0.1-1 %
    of the fringe amplitude from the direct evaluation). The table depends on the
    model's optics and method, not on its pixels, so one serves every scan of a pass.

    Attributes
    ----------
    step : float — the magnitude step (Pa m, the slab vectors' unit)
    values : (n_mag, TABLE_ANGLES + 1, C) float array — intensities per channel
    """

    step: float
    values: np.ndarray

    @property
    def top(self) -> float:
        """The largest magnitude the table holds."""
        return self.step * (len(self.values) - 1)

    @classmethod
    def build(cls, sub: ImageModel, top: float) -> RetarderTable:
        """The table of ``sub``'s optics up to magnitude ``top``."""
        lam = sub.wavelengths
        k = float(np.max(sub.law.retardation_per_stress_length(lam)))
        top = top * (1 + 1e-9) + 1e-30
        n_mag = int(np.ceil(top * 2 * k / (2 * np.pi) * TABLE_PER_FRINGE)) + 2
        m_nodes = np.linspace(0.0, top, n_mag)
        a_nodes = np.linspace(-np.pi, np.pi, TABLE_ANGLES + 1)
        mm, aa = np.meshgrid(m_nodes, a_nodes, indexing="ij")
        nodes = np.stack([mm * np.cos(aa), mm * np.sin(aa)], axis=-1).reshape(-1, 1, 2)
        flat = np.zeros(len(nodes), bool)  # every node one equivalent retarder
        values = sub.intensities(nodes, [], flat).reshape(n_mag, TABLE_ANGLES + 1, -1)
        return cls(float(m_nodes[1]), values)

    def lookup(self, tot: np.ndarray) -> np.ndarray:
        """Intensities (M, P, C) of rays with summed slab vectors ``tot`` (M, P, 2).

        Raises
        ------
        ValueError
            If a magnitude exceeds the table's ``top`` (build a larger table).
        """
        mag = np.hypot(tot[..., 0], tot[..., 1])
        top = float(mag.max()) if mag.size else 0.0
        if top > self.top:
            raise ValueError(f"slab magnitude {top:.4g} beyond the table's {self.top:.4g}")
        return self._bilinear(mag, np.arctan2(tot[..., 1], tot[..., 0]))

    def _bilinear(self, mag: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """Intensities (..., C) at magnitudes ``mag`` (within ``top``) and angles ``ang``
        (rad) of the slab vectors."""
        n_mag, n_ang, channels = self.values.shape
        fm = mag / self.step
        im = np.minimum(fm.astype(int), n_mag - 2)
        tm = (fm - im)[..., None]
        fa = (ang + np.pi) / (2 * np.pi / TABLE_ANGLES)
        ia = np.minimum(fa.astype(int), TABLE_ANGLES - 1)
        ta = (fa - ia)[..., None]
        # the corners as rows of the flattened table (np.take: 1.4-3.4 times faster than
        # indexing with two arrays on a scan's 1.8M rays), summed in the same order
        flat = self.values.reshape(-1, channels)
        k = im * n_ang + ia
        out = (1 - tm) * (1 - ta) * np.take(flat, k, axis=0)
        out += tm * (1 - ta) * np.take(flat, k + n_ang, axis=0)
        out += (1 - tm) * ta * np.take(flat, k + 1, axis=0)
        out += tm * ta * np.take(flat, k + n_ang + 1, axis=0)
        return out


def retarder_lookup(
    sub: ImageModel, tot: np.ndarray, table: RetarderTable | None = None
) -> tuple[np.ndarray, RetarderTable]:
    """Intensities (M, P, C) of equivalent-retarder rays ``tot`` (M, P, 2) from ``table``,
    built (with TABLE_MARGIN headroom, so that later scans reuse it) when it is missing or
    too small; returns (intensities, the table used)."""
    mag = np.hypot(tot[..., 0], tot[..., 1])  # once: the scan's millions of rays
    top = float(mag.max()) if mag.size else 0.0
    if table is None or top > table.top:
        table = RetarderTable.build(sub, TABLE_MARGIN * top)
    return table._bilinear(mag, np.arctan2(tot[..., 1], tot[..., 0])), table


def _scan_loads(lib, fz_now: float) -> np.ndarray:
    """Normal loads the scan tries: about the fitted one, and across the library."""
    lo = 0.5 * float(lib.load_N[1])
    spread = np.geomspace(lo, lib.max_load_N, SCAN_LOADS)
    return np.unique(
        np.clip(np.concatenate([fz_now * np.array(SCAN_LOAD_FACTORS), spread]), lo, lib.max_load_N)
    )


def _scan(model: ImageModel, p, diam, k: int, gains, offs, f_scale, centres, table=None):
    """Scanned candidates for indenter k with its axis at each of ``centres`` (mm):
    (costs (M,), rows (M, 5)), the current cost and the intensity table used."""
    lib = model.lib
    q = p.reshape(-1, N_PARAMS)
    inds = unpack(p, diam)
    win = np.flatnonzero(_window(model, q, k, [(p, diam)]))
    stride = max(1, int(np.ceil(len(win) / SCAN_PIXELS)))
    sub = model.restrict(win[::stride])
    xy = sub.xy
    others = _others(sub, inds, k).sum(axis=1)  # (P, 2): one retarder per ray
    d = lib.nearest_diameter(diam[k] * 1e3)
    psi = np.linspace(0.0, 2 * np.pi, SCAN_DIRECTIONS, endpoint=False)
    ratios = np.arange(0.0, lib.max_ratio + 1e-9, SCAN_RATIO_STEP)
    tots = [(others + lib.slabs(inds[k], xy)[0].sum(axis=1))[None]]  # the current first
    rows = [q[k]]
    for fz in _scan_loads(lib, q[k, 2]):  # a few load states, each vectorised
        for ratio in ratios:
            AB = lib.state(d, float(fz), float(ratio))[0].sum(axis=2, keepdims=True)
            dirs = psi if ratio > 0 else psi[:1]
            ft = ratio * fz
            for cx, cy in centres:  # one or two
                dx, dy = (xy[:, 0] - cx * 1e-3)[None], (xy[:, 1] - cy * 1e-3)[None]
                ab = interpolate_turned(AB, lib.lattice, dx, dy, dirs[:, None])[..., 0, :]
                tots.append(others[None] + ab)
                rows += [[cx, cy, fz, ft * np.cos(a), ft * np.sin(a)] for a in dirs]
    lin, table = retarder_lookup(sub, np.concatenate(tots), table)
    costs = robust_cost(sub.misfit(gains * lin + offs), f_scale, axis=(1, 2))
    return costs[1:], np.array(rows[1:]), float(costs[0]), table


def _distinct(costs: np.ndarray, rows: np.ndarray, now: float) -> list[np.ndarray]:
    """The best HOP_STARTS candidates below ``now``, pairwise distinct in the tangential
    load's direction or ratio."""
    chosen: list[np.ndarray] = []
    for i in np.argsort(costs):
        if costs[i] >= now or len(chosen) == HOP_STARTS:
            break
        v = rows[i]
        ratio, ang = np.hypot(v[3], v[4]) / v[2], np.degrees(np.arctan2(v[4], v[3]))
        close = False
        for w in chosen:
            if np.hypot(v[0] - w[0], v[1] - w[1]) > 0.05:  # another centre
                continue
            rw, aw = np.hypot(w[3], w[4]) / w[2], np.degrees(np.arctan2(w[4], w[3]))
            turn = abs((ang - aw + 180.0) % 360.0 - 180.0)
            if abs(ratio - rw) < DISTINCT_RATIO and (turn < DISTINCT_DEG or min(ratio, rw) < 0.05):
                close = True
                break
        if not close:
            chosen.append(v)
    return chosen


def _refine(fine: ImageModel, p, diam, k, starts, gains, offs, f_scale):
    """Local fits of indenter k from ``starts``; returns (best cost, best row) and the
    current row's cost on the same pixels."""
    lib = fine.lib
    q = p.reshape(-1, N_PARAMS)
    exclude = [(p, diam)]
    for v in starts:
        alt = q.copy()
        alt[k] = v
        exclude.append((alt.ravel(), diam))
    sub = fine.restrict(_window(fine, q, k, exclude))
    inds = unpack(p, diam)
    xy = sub.xy
    others = _others(sub, inds, k)

    def residual(v: np.ndarray) -> np.ndarray:
        ind = unpack(v, diam[k : k + 1])[0]
        trial = inds[:k] + [ind] + inds[k + 1 :]
        lin = sub.intensities(others + lib.slabs(ind, xy)[0], trial)
        r = sub.misfit(gains * lin + offs).ravel()
        return np.concatenate([r, range_penalty(v, lib.max_ratio, f_scale)[0]])

    t = lib.max_ratio * lib.max_load_N
    best = (float(robust_cost(residual(q[k]), f_scale)), q[k])
    now = best[0]
    for v in starts:
        lo = np.array([v[0] - HOP_BOX_MM, v[1] - HOP_BOX_MM, 0.0, -t, -t])
        hi = np.array([v[0] + HOP_BOX_MM, v[1] + HOP_BOX_MM, lib.max_load_N, t, t])
        with single_blas_thread():  # fringekit._threads: its SVDs are faster on one
            res = least_squares(
                residual,
                np.clip(v, lo + 1e-9, hi - 1e-9),
                bounds=(lo, hi),
                loss="soft_l1",
                f_scale=f_scale,
                x_scale="jac",
                max_nfev=HOP_NFEV,
                ftol=1e-4,
                xtol=1e-4,
                diff_step=DIFF_STEP,
            )
        c = float(robust_cost(res.fun, f_scale))
        if c < best[0]:
            best = (c, res.x)
    return best, now


def hop(fine: ImageModel, p: np.ndarray, diam, noise: float, anchors=None, which=None):
    """One pass of the search over every indenter, or those of ``which`` (indices)
    (module docstring).

    Parameters
    ----------
    fine : ImageModel — every 2nd pixel, with the Jones integration near the axes (its
        ``exact``)
    p : (n * 5,) x, y (mm), Fz, Fx, Fy (N) of a converged joint fit
    diam : list of n sphere diameters (m)
    noise : float — the image's noise sd (intensity)
    anchors : (n, 2) float array or None — where detection put each axis (mm); an axis
        the fit moved more than ANCHOR_MM from it is also scanned there

    Returns
    -------
    (p, changed) — the parameters and how many indenters moved to another basin.
    """
    p = np.array(p, float)
    f_scale = 3.0 * noise
    changed = 0
    table = None  # one intensity table for every indenter's scan
    _, gains, offs, _ = fine.fitted(unpack(p, diam))
    for k in range(len(diam)) if which is None else which:  # a handful, each vectorised
        centres = [tuple(p[k * N_PARAMS : k * N_PARAMS + 2])]
        if anchors is not None and np.hypot(*(anchors[k] - centres[0])) > ANCHOR_MM:
            centres.append(tuple(anchors[k]))
        costs, rows, now, table = _scan(fine, p, diam, k, gains, offs, f_scale, centres, table)
        starts = _distinct(costs, rows, now)
        if not starts:
            continue
        (c, v), c_now = _refine(fine, p, diam, k, starts, gains, offs, f_scale)
        if c < (1.0 - ACCEPT) * c_now:
            p[k * N_PARAMS : (k + 1) * N_PARAMS] = v
            changed += 1
            _, gains, offs, _ = fine.fitted(unpack(p, diam))  # of the image with it moved
    return p, changed


def hop_to(fine: ImageModel, p: np.ndarray, diam, noise: float, k: int, centres) -> tuple:
    """Local fits of indenter k started at each of ``centres`` (mm), with its fitted
    normal load and either its tangential load or none, the others held; the best is
    taken when it lowers the window's robust cost by more than ACCEPT of it.

    The scan of :func:`hop` holds the axis where it is, so it misses a basin whose axis
    lies a few tenths of a millimetre away: where a contact's fringes were shared by
    two candidates, the place between them is such a centre (the model selection of
    ``fringekit.inversion.fit``).

    Parameters
    ----------
    fine : ImageModel — as :func:`hop`'s
    p : (n * 5,) x, y (mm), Fz, Fx, Fy (N) of a converged joint fit
    diam : list of n sphere diameters (m)
    noise : float — the image's noise sd (intensity)
    k : int — the indenter
    centres : (m, 2) float array-like — start axes (mm)

    Returns
    -------
    (p, changed) — the parameters and 1 when indenter k moved, else 0.
    """
    p = np.array(p, float)
    q = p.reshape(-1, N_PARAMS)[k]
    _, gains, offs, _ = fine.fitted(unpack(p, diam))
    starts = [
        np.array([cx, cy, q[2], fx, fy])
        for cx, cy in np.reshape(centres, (-1, 2))
        for fx, fy in (q[3:5], (0.0, 0.0))
    ]
    (c, v), c_now = _refine(fine, p, diam, k, starts, gains, offs, 3.0 * noise)
    if c < (1.0 - ACCEPT) * c_now:
        p[k * N_PARAMS : (k + 1) * N_PARAMS] = v
        return p, 1
    return p, 0


def search_after_drop(fine: ImageModel, p, diam, noise: float, before, kept, anchors) -> tuple:
    """The basins of the indenters left after model selection dropped others, searched
    again where they were near a dropped one (within 2 WINDOW_MM): the tangential scan
    (:func:`hop`), then fits started between each such pair (:func:`hop_to`: midway
    between their detected axes, and at the load-weighted mean of their fitted ones).

    A candidate that shared a contact's fringes with another leaves its partner alone with
    them, and the partner's basin was searched while it explained half. A library frame of
    the tests (two contacts, one detected as two candidates 1.7 mm either side of it, the
    substrate meshed more coarsely) kept the partner 0.42 mm off with its 0.3 N
    tangential load read as 0.002 N (window residual 0.10 against 0.004 for the other
    contact), and stated it reliable; the scan about its axis found nothing, a fit
    started midway between the two detected axes found the contact to 0.001 mm and
    0.002 N.

    Parameters
    ----------
    fine : ImageModel — as :func:`hop`'s
    p : (m * 5,) the converged joint fit of the indenters left
    diam : list of m sphere diameters (m)
    noise : float — the image's noise sd (intensity)
    before : (n * 5,) the fit before the drop, of all n candidates
    kept : (m,) int — which of the n are left, in the order of ``p``
    anchors : (n, 2) float array — where detection put each of the n axes (mm)

    Returns
    -------
    (p, moved) — the parameters and how many searches moved an indenter.
    """
    q = np.reshape(before, (-1, N_PARAMS))
    kept = np.asarray(kept, int)
    gone = np.setdiff1d(np.arange(len(q)), kept)
    axes = np.reshape(p, (-1, N_PARAMS))[:, :2]
    gap = np.hypot(*(axes[:, None, :] - q[gone][None, :, :2]).transpose(2, 0, 1))
    near = (gap < 2 * WINDOW_MM).nonzero()
    if not len(near[0]):
        return np.array(p, float), 0
    p, moved = hop(fine, p, diam, noise, anchors[kept], which=sorted(set(near[0].tolist())))
    for i, j in zip(*near, strict=True):  # a pair or two
        a, b = kept[i], gone[j]
        w = q[[a, b], 2] / max(float(q[[a, b], 2].sum()), 1e-12)
        centres = [(anchors[a] + anchors[b]) / 2, w @ q[[a, b], :2]]
        p, changed = hop_to(fine, p, diam, noise, int(i), centres)
        moved += changed
    return p, moved
