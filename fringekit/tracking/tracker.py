"""Contacts followed through a stream of frames: each frame's fit starts from the last.

A frame of a stream differs little from the one before it, so the inverse need not start
from scratch (:func:`fringekit.inversion.fit.invert_image`: detection, a start scan, two
fits, a basin search and model selection, 2-60 s for four contacts). :class:`Tracker`
starts once, when the first contact appears (the quick start of
:mod:`fringekit.inversion.quick`, or that whole inverse when the quick one does not explain
the frame), and then per frame:

1. **Warm fit.** Every contact's x, y, Fz, Fx, Fy start at the previous frame's answer
   moved on by its last change (constant velocity), and Gauss-Newton steps with a
   Jacobian kept from an earlier frame (the chord method: J. M. Ortega and W. C.
   Rheinboldt, *Iterative Solution of Nonlinear Equations in Several Variables*, 1970,
   sec. 7.1) bring them to the least-squares answer on every ``stride``-th pixel, the
   exposure's gain and offset solved exactly at every step as in ``invert``. The
   Jacobian (finite differences, one batch per contact) is made again only when a
   contact has moved more than ``JAC_MOVE_MM`` or its loads by more than ``JAC_LOAD`` of
   the largest library load since it was made, or when a step fails to lower the cost.
   A step costs one synthesis of the image: 9-14 ms for four contacts at 64 x 64 fitted
   pixels.
2. **Checks.** The residual near each contact, in fringe amplitudes, is compared with its
   own running median over ``HISTORY`` frames: above ``JUMP`` times it (and above
   ``invert``'s warning level) the frame is *recovered*: each contact's tangential basin
   is searched (:func:`fringekit.inversion.hop.hop`) and a robust joint fit run, within
   the same frame. A contact whose normal load is no longer significant (below 3 sd) is
   *released*; the residual image is searched for a new contact (``invert``'s
   detection, the present ones excluded), which is *touched*: started from the
   library's scan and fitted with the others, and kept from TOUCH_FRACTION of the
   library's first load when its load is told from zero (a touch is taken from that
   level and let go below 3 sd, so a load ramping through it keeps one id).
3. **Identity.** Each contact keeps the id it got at its touch until its release: the
   parameters of a contact are one block of the fit, carried from frame to frame, so
   two contacts that pass each other keep their blocks (two spheres' axes stay a
   diameter apart, and a frame moves them far less). When two blocks meet on one
   contact (a lifted contact's fit sliding onto a neighbour's rings), the one kept takes
   the id of the contact that was there (:func:`~fringekit.tracking.ids.heirs`).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from fringekit._threads import single_blas_thread
from fringekit.inversion.detect import detect, noise_sd
from fringekit.inversion.fit import (
    EXACT_MM,
    WINDOW_MM,
    fit_bounds,
    fit_indenters,
    invert_image,
    start_params,
    subsample,
)
from fringekit.inversion.hop import hop
from fringekit.inversion.match import match_candidates
from fringekit.inversion.model import N_PARAMS, ImageModel, unpack
from fringekit.inversion.quick import near_residual, quick_start
from fringekit.inversion.selection import MIN_LOAD_FRACTION, prune, sphere_gaps
from fringekit.inversion.uncertainty import model_sd, stated_sd
from fringekit.inversion.verdict import WARN_RESIDUAL, InvertError, at_library_edge, window_rms
from fringekit.tracking.frame import TrackedFrame
from fringekit.tracking.ids import assign, heirs, previous_params, twins, velocity
from fringekit.tracking.settle import settle_new
from fringekit.tracking.warm import ChordFit

__all__ = [
    "HISTORY",
    "JUMP",
    "TRACK_STRIDE",
    "Tracker",
]

#: Every this many pixels in both directions are fitted per frame (invert's last stage
#: fits every 2nd; four times fewer pixels make a frame four times faster).
TRACK_STRIDE = 4
#: A contact is matched to a detection within this distance (mm) of it: less than a
#: sphere diameter (3.5 mm), the least distance between two contacts' axes.
GATE_MM = 3.0
#: A new contact found in a warm frame's residual lies this far (mm) inside the frame
#: at least (a residual at the frame's edge is more often a misfit of the field there).
BORDER_MM = 1.0
#: A frame more than this many frames after the last one solved (a camera's dropped
#: frames) is searched afresh (:meth:`Tracker._redetect`) before its warm fit is trusted.
MAX_GAP = 3
#: A frame is recovered when the residual near a contact exceeds this many times its
#: running median over HISTORY frames (and invert's warning level).
JUMP = 2.0
HISTORY = 10
#: The correlation areas behind the stated sd (a Fourier transform per parameter) are
#: measured again every this many frames, and after every event.
AREA_EVERY = 10
#: A new contact the release dropped in the frame it was found in (a residual peak of the
#: model's misfit, not a contact: FEM frames near 4 N contacts showed one in 6 of 20
#: frames, each search about 1 s) is not searched for again within GATE_MM of that place
#: for this many frames.
REJECTED_FRAMES = 5
#: ... unless the residual there grows this many times (:meth:`Tracker._touch`).
GROWN = 1.5
#: A touch is kept from this fraction of the library's first load (:meth:`Tracker._release`).
TOUCH_FRACTION = 0.25


class Tracker:
    """Follow every contact of a library's sensor through a stream of images.

    Parameters
    ----------
    blank : ImageModel
        The image model of the stream's frames (library, pixel grid, method, optics);
        its measured image is replaced frame by frame.
    stride : int
        Every ``stride``-th pixel in both directions is fitted per frame.

    Examples
    --------
    See :func:`fringekit.tracking.track`, which feeds a tracker from a frame source.
    """

    def __init__(self, blank: ImageModel, stride: int = TRACK_STRIDE):
        self.blank = blank
        self.stride = int(stride)
        self.p = np.zeros(0)
        self.diam: list = []
        self.ids = np.zeros(0, int)
        self.next_id = 1
        self.noise: float | None = None
        self.chord = ChordFit(0.0)
        self.last_step = np.zeros(0)
        self.history: list[list[float]] = []
        self.area: np.ndarray | None = None
        self.area_age = 0
        self.index: int | None = None  # the last frame's
        self.p_before = np.zeros(0)  # the parameters of the frame before
        self.ids_before = np.zeros(0, int)  # and their ids
        self.rejected: list[list] = []  # [frame, x, y mm, residual there] (REJECTED_FRAMES)

    def step(self, measured, usable, nodata, index, time_s, censored=None) -> TrackedFrame:
        """The contacts of one frame: linear intensities ``measured`` (P, C), ``usable``
        and ``nodata`` (P,) bool and ``censored`` (P, C) bool or None, as
        :class:`ImageModel` holds them. BLAS runs on one thread: the frame's products are
        small and the rays use the cores already.

        Raises :class:`~fringekit.inversion.verdict.InvertError` when no contact is
        tracked yet and the frame shows fringes that the whole inverse cannot explain
        (:func:`~fringekit.tracking.track` records it in ``frames_refused`` and starts
        afresh at the next frame)."""
        with single_blas_thread():
            pixels = {"measured": measured, "usable": usable, "nodata": nodata}
            return self._step(replace(self.blank, **pixels, censored=censored), index, time_s)

    def _step(self, full: ImageModel, index: int, time_s: float) -> TrackedFrame:
        t0 = time.perf_counter()
        sub = replace(subsample(full, self.stride), exact=EXACT_MM * 1e-3)
        if self.noise is None:
            self.noise = noise_sd(full)
            self.chord.noise = self.noise
        events: list[str] = []
        times: dict = {}
        before = (self.p.copy(), self.ids.copy())
        self.p_before, self.ids_before = before
        gap = index - self.index if self.index is not None else 1
        self.index = index
        converged = True
        if not self.diam:
            self._start(full, events, times)
            times["start_s"] = time.perf_counter() - t0
        elif gap > MAX_GAP:  # the contacts moved unseen: look for them again
            suspect = np.ones(len(self.diam), bool)
            found = self._redetect(sub, full, events, suspect, gate=np.inf)
            converged = self._warm(sub, 0 if found else gap)  # (:meth:`_warm`)
            times["fit_s"] = time.perf_counter() - t0
        else:
            converged = self._warm(sub, max(gap, 1))
            times["fit_s"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        frame = self._check(sub, full, converged, events) if self.diam else None
        times["check_s"] = time.perf_counter() - t1
        times["frame_s"] = time.perf_counter() - t0
        if frame is None:
            z = np.zeros((0, N_PARAMS))
            e = np.zeros(0)
            return TrackedFrame(
                index, time_s, np.zeros(0, int), z, z, e, e.astype(bool), tuple(events), times
            )
        sd, rms = frame
        self.last_step = velocity(before, (self.p, self.ids), max(gap, 1))
        q, lib = self.p.reshape(-1, N_PARAMS).copy(), self.blank.lib
        ok = np.asarray(rms <= WARN_RESIDUAL, bool) & ~np.logical_or(*at_library_edge(q, lib))
        return TrackedFrame(index, time_s, self.ids.copy(), q, sd, rms, ok, tuple(events), times)

    def reset(self) -> None:
        """Forget every contact (the next frame starts afresh, new ids), and the places a
        touch was rejected at."""
        self._reset(np.zeros(0), [])
        self.ids = np.zeros(0, int)
        self.index = None
        self.rejected = []

    def _start(self, full: ImageModel, events: list, times: dict) -> None:
        """No contact tracked: look for them (:func:`~fringekit.inversion.quick.quick_start`);
        when that leaves one unexplained, the whole inverse (``invert``'s), whose refusal
        (:class:`~fringekit.inversion.verdict.InvertError`: fringes the library cannot
        explain) is the frame's. ``times`` gets the seconds of each that ran
        (``quick_start_s``, ``inverse_s``)."""
        half = subsample(full, 2)
        cand = detect(half, self.noise)
        if not len(cand):
            return
        t0 = time.perf_counter()
        cand = match_candidates(half, cand)
        p, diam = quick_start(full, cand, self.stride, self.noise)
        times["quick_start_s"] = time.perf_counter() - t0
        if p is None:
            t0 = time.perf_counter()
            try:
                res = invert_image(full, noise=self.noise)
            finally:
                times["inverse_s"] = time.perf_counter() - t0
            p, diam = res.params.ravel(), list(res.diameters)
        if not diam:
            return
        self._reset(p, diam)
        self.ids = self._new_ids(len(self.diam))
        events.append("start")

    def _reset(self, p: np.ndarray, diam: list) -> None:
        self.p, self.diam = np.asarray(p, float).copy(), list(diam)
        self.chord.forget()
        self.last_step = np.zeros_like(self.p)
        self.history = [[] for _ in self.diam]

    def _warm(self, sub: ImageModel, gap: int = 1) -> bool:
        """The chord fit (:class:`~fringekit.tracking.warm.ChordFit`) from the previous
        answer moved on by its change over ``gap`` frames; whether it converged. With
        ``gap`` 0, after a search of the frame: the search's robust fits on every 2nd
        pixel stop at their tolerance (0.016 mm off on an 8-bit library frame), and the
        frame's answer is that of its own fit, as every other frame's."""
        lo, hi = fit_bounds(sub, len(self.diam))
        self.p, done = self.chord.run(
            sub, np.clip(self.p + gap * self.last_step, lo, hi), self.diam
        )
        return done

    def _check(self, sub: ImageModel, full: ImageModel, converged: bool, events: list):
        """Touch, recovery and release of this frame; returns (sd (n, 5), residual_rms
        (n,)) of the contacts left, or None when none is.

        A warm fit that did not converge is fitted again robustly. One that left a
        contact's residual far above its usual level is searched in the image itself
        (:meth:`_redetect`: a new contact spoils the fit of its neighbours, so the
        residual would point everywhere); without a detection the frame is recovered. A
        contact the release would drop though it bore a clear load a frame before is
        searched for likewise. Then the release, and a search of the residual image for
        a new contact still too light to disturb the fit (:meth:`_touch`), kept only when
        the release's rule keeps it in the same frame.
        """
        if not converged:  # the steps ran out: a robust fit from where they got
            self._keep_history(fit_indenters(sub, self.p, self.diam, self.noise).x)
        fixed, rms, r = self._evaluate(sub)
        if self._jumped(rms) and "redetect" not in events:
            if not self._redetect(fixed, full, events, self._jumps(rms)):
                self._recover(self._fine(full), events)
            fixed, rms, r = self._evaluate(sub)
        sd = self._sd(fixed, r, events)
        lost = self._lost(sd, events)
        if lost.any() and "redetect" not in events and self._redetect(fixed, full, events, lost):
            fixed, rms, r = self._evaluate(sub)
            sd = self._sd(fixed, r, events)
        if self._release(sd, events) and self.diam:
            if "redetect" in events:  # the contacts left shared fringes with one dropped
                self._keep_history(fit_indenters(self._fine(full), self.p, self.diam, self.noise).x)
            fixed, rms, r = self._evaluate(sub)
            sd = self._sd(fixed, r, events)
        quiet = not ({"start", "redetect"} & set(events))  # (those searched already)
        if self.diam and quiet and self._touch(fixed, r, rms, events, full):
            fixed, rms, r = self._evaluate(sub)
            sd = self._sd(fixed, r, events)
            if self._release(sd, events, floor=TOUCH_FRACTION) and self.diam:
                fixed, rms, r = self._evaluate(sub)
                sd = self._sd(fixed, r, events)
        if not self.diam:
            return None
        for h, v in zip(self.history, rms, strict=True):
            h.append(float(v))
            del h[:-HISTORY]
        return sd, rms

    def _floor(self, rms: np.ndarray) -> float:
        """The noise level a new contact's residual must stand out of: the camera's, or
        the fit's own misfit near the contacts (residual_rms times the fringe amplitude),
        whichever is larger."""
        last = self.chord.last
        amp = float(np.mean(np.abs(last[2]))) if last is not None else 0.0
        finite = rms[np.isfinite(rms)]
        misfit = float(np.median(finite)) * amp if len(finite) else 0.0
        return max(self.noise, misfit)

    def _axes(self) -> np.ndarray:
        return self.p.reshape(-1, N_PARAMS)[:, :2]

    def _evaluate(self, sub: ImageModel):
        """(the model with the pixels outside the contacts kept, residual near each
        contact (n,), residuals) at the present parameters."""
        fixed = replace(sub, keep=sub.outside_contacts(unpack(self.p, self.diam)))
        last = self.chord.last
        if last is not None and len(last[0]) == len(self.p) and np.array_equal(last[0], self.p):
            r, gains = last[1], last[2]
        else:
            r, gains = self.chord.residual(fixed, self.p, self.diam)
        return fixed, near_residual(fixed, self.p, r, gains), r

    def _jumps(self, rms: np.ndarray) -> np.ndarray:
        """(n,) bool: the contacts whose residual is far above its running median (JUMP
        times it, and above invert's warning level), or above JUMP times that level at
        all."""
        out = np.zeros(len(rms), bool)
        for k, (v, h) in enumerate(zip(rms, self.history, strict=True)):
            usual = JUMP * float(np.median(h)) if len(h) >= 3 else np.inf
            out[k] = v > max(min(usual, JUMP * WARN_RESIDUAL), WARN_RESIDUAL)
        return out

    def _jumped(self, rms: np.ndarray) -> bool:
        return bool(self._jumps(rms).any())

    def _lost(self, sd: np.ndarray, events: list) -> np.ndarray:
        """(n,) bool: the contacts the release would drop (normal load not significant,
        or the axis within a sphere of a stronger one's) that bore more than twice the
        release level in the frame before: moved faster than the warm fit can follow,
        more likely than lifted that fast."""
        out = np.zeros(len(self.diam), bool)
        _, _, kept = prune(self.p, sd.ravel(), self.diam, self.blank.lib, self._held(events))
        gone = np.setdiff1d(np.arange(len(self.diam)), kept)
        was = previous_params(self.p_before, self.ids_before, self.ids)[gone, 2]  # NaN: new
        out[gone] = was > 2 * MIN_LOAD_FRACTION * self.blank.lib.load_N[1]
        return out

    def _redetect(
        self, fixed: ImageModel, full: ImageModel, events: list, suspect, gate: float = GATE_MM
    ) -> bool:
        """Detection in the frame itself (every 2nd pixel): each ``suspect`` contact
        ((n,) bool) moves to the candidate within ``gate`` (mm) of it (one-to-one, the
        least total distance: linear assignment) and is started there from the library's
        scan; the strongest candidate that no contact took and that lies farther than
        GATE_MM from every contact is a new one (touched); all are fitted jointly and
        their basins searched. Whether detection found anything."""
        fine = self._fine(full)
        cand = detect(subsample(full, 2), self.noise)
        if not len(cand):
            return False
        axes = self._axes()
        dist = np.hypot(*(axes[:, None, :] - cand[None, :, :]).transpose(2, 0, 1))
        rows, cols = assign(axes, cand, gate, allowed=suspect)
        p = self.p.copy().reshape(-1, N_PARAMS)
        if len(cols):
            start, _ = start_params(fine, cand[cols])
            p[rows] = start.reshape(-1, N_PARAMS)
        free = np.setdiff1d(np.arange(len(cand)), cols)
        far = [k for k in free if np.all(np.delete(dist[:, k], rows) > GATE_MM)][:1]
        pn, dn = start_params(fine, cand[far]) if far else (np.zeros(0), [])
        events.append("redetect")
        self._append(fine, np.concatenate([p.ravel(), pn]), dn, events)
        _, rms, _ = self._evaluate(replace(subsample(full, self.stride), exact=fine.exact))
        if np.any(rms > WARN_RESIDUAL):  # still not explained: the whole inverse
            self._cold(full, events)
        return True

    def _cold(self, full: ImageModel, events: list) -> None:
        """The whole inverse of this frame (as ``invert``), its contacts given the ids of
        the present ones they lie nearest to (linear assignment; new ids for the rest,
        which are touched; present ones left without a match are released)."""
        try:
            res = invert_image(full, noise=self.noise)
        except InvertError:
            return
        q = res.params
        old = self._axes()
        rows, cols = assign(old, q[:, :2])
        ids = np.zeros(len(q), int)
        ids[cols] = self.ids[rows]
        new = np.setdiff1d(np.arange(len(q)), cols)
        ids[new] = self._new_ids(len(new))
        gone = np.setdiff1d(np.arange(len(old)), rows)
        for i in self.ids[gone]:
            t = f"touch {int(i)}"
            events.remove(t) if t in events else events.append(f"release {int(i)}")
        events.extend(f"touch {int(i)}" for i in ids[new])
        hist = [self.history[r] for r in rows] + [[] for _ in new]
        order = np.concatenate([np.asarray(cols, int), new])
        self.ids = ids[order]
        self._reset(q[order].ravel(), [res.diameters[k] for k in order])
        self.history = hist
        events.append("restart")

    def _fine(self, full: ImageModel) -> ImageModel:
        """The model the robust fits of events run on: every 2nd pixel (as ``invert``'s
        last stage), the Jones integration near the axes."""
        return replace(subsample(full, min(2, self.stride)), exact=EXACT_MM * 1e-3)

    def _recover(self, sub: ImageModel, events: list) -> None:
        """Each contact's tangential basin searched, then a robust joint fit."""
        p, _ = hop(sub, self.p, self.diam, self.noise)
        res = fit_indenters(sub, p, self.diam, self.noise)
        self._keep_history(res.x)
        events.append("recover")

    def _keep_history(self, p: np.ndarray) -> None:
        """New parameters for the same contacts: their history and Jacobian kept (its
        columns are made again where they moved, :meth:`_stale`)."""
        self.p = np.asarray(p, float).copy()
        self.chord.last = None

    def _sd(self, fixed: ImageModel, r: np.ndarray, events: list) -> np.ndarray:
        """The stated 1-sigma (n, 5), the correlation areas measured every AREA_EVERY
        frames and after every event."""
        lib = fixed.lib
        self.chord.refresh(fixed, self.p, self.diam, self.chord.stale(self.p, self.diam, lib))
        shape = (*fixed.grid.shape, fixed.measured.shape[1])
        q = self.p.reshape(-1, N_PARAMS)
        fresh = events or self.area is None or self.area.shape != q.shape
        fresh = fresh or self.area_age >= AREA_EVERY
        J = self.chord.full_jacobian(self.p, lib)
        sd, area = stated_sd(
            J, r, shape, q, model_sd(fixed.lib.shear_ratio), None if fresh else self.area
        )
        self.area, self.area_age = area, 0 if fresh else self.area_age + 1
        return sd

    def _release(self, sd: np.ndarray, events: list, floor: float = MIN_LOAD_FRACTION) -> bool:
        """Contacts whose normal load is no longer significant (or that met a stronger
        one) are released, their ids retired. A contact found in this frame that a
        contact already tracked met keeps the tracked one's id and history: they are one
        contact, seen twice by a search after dropped frames. Of two tracked contacts
        that met, the one kept takes the other's id when the other was nearer to where
        it is now (:func:`~fringekit.tracking.ids.heirs`: a lifted contact's fit that slid
        onto a neighbour's rings is the neighbour). A contact found in this frame is kept
        from ``floor`` of the library's first load (the rule of
        :func:`~fringekit.inversion.selection.prune`): a touch's check in its own frame
        takes TOUCH_FRACTION. Below it the library interpolates between no load and its
        first load, and a light contact's rings cannot be told from a misfit of the model
        of the same size: an intensity bump of 0.1 (0.6 mm wide) beside a contact fits
        as a 0.08 N contact at 7 sd on a library whose first load is 2 N, and removes
        93 % of the residual's sum of squares near it."""
        new = ~self._held(events)
        p, diam, kept = prune(self.p, sd.ravel(), self.diam, self.blank.lib, ~new, floor)
        if len(kept) == len(self.diam):
            return False
        dropped = np.setdiff1d(np.arange(len(self.diam)), kept)
        gaps = sphere_gaps(self.p, self.diam)
        pairs = twins(gaps, dropped, kept, new)
        was = previous_params(self.p_before, self.ids_before, self.ids)[:, :2]  # NaN: new
        met = heirs(gaps, [i for i in dropped if i not in pairs.values()], kept, was, self._axes())
        ids, hist, gone = self.ids.copy(), list(self.history), self.ids.copy()
        for j, i in pairs.items():  # the tracked contact lives on in its twin
            events.remove(f"touch {int(ids[j])}")
            ids[j], hist[j] = self.ids[i], hist[i]
        for j, i in met.items():  # the contact kept is the one that was there
            ids[j], hist[j], gone[i] = self.ids[i], hist[i], self.ids[j]
        for i in dropped:
            if new[i]:  # found and dropped in one frame: never a contact
                events.remove(f"touch {int(self.ids[i])}")
                x, y = self.p[i * N_PARAMS : i * N_PARAMS + 2]
                self.rejected.append([int(self.index or 0), x, y, None])
            elif i not in pairs.values():
                events.append(f"release {int(gone[i])}")
        self.ids = ids[kept]
        self._reset(p, diam)
        self.history = [hist[i] for i in kept]
        return True

    def _held(self, events: list) -> np.ndarray:
        """(n,) bool: the contacts tracked before this frame (not touched in it)."""
        return np.array([f"touch {int(i)}" not in events for i in self.ids], bool)

    def _touch(self, fixed: ImageModel, r: np.ndarray, rms: np.ndarray, events: list, full) -> bool:
        """The strongest new contact in the residual image, at least BORDER_MM inside the
        frame and a sphere from the others, added (one a frame: a new contact's rings
        can make several residual peaks, and a second one is found in the next frame).
        A place where a touch was rejected is not searched for REJECTED_FRAMES frames
        unless the residual within WINDOW_MM of it grows GROWN times above its level in
        the frame after: a contact pressed on through the touch level (a misfit's stays;
        the 3 N touch of ``bench/track.py``, rejected at 0.2 N, was read 3 frames late)."""
        img = r[: fixed.measured.size].reshape(fixed.measured.shape)
        floor = self._floor(rms)
        new = detect(
            replace(fixed, measured=img, keep=None, censored=None), floor, exclude=self._axes()
        )
        xy = fixed.xy * 1e3
        lo, hi = xy.min(axis=0) + BORDER_MM, xy.max(axis=0) - BORDER_MM
        new = new[np.all((new >= lo) & (new <= hi), axis=1)] if len(new) else new
        now, kept = int(self.index or 0), []
        for v in self.rejected:  # a handful of places
            there = window_rms(img, fixed.usable, xy, np.array([v[1:3]]), 1.0, WINDOW_MM)[0]
            v[3] = there if v[3] is None else v[3]
            if now - v[0] <= REJECTED_FRAMES and not there > GROWN * v[3]:
                kept.append(v)
                new = new[np.hypot(*(new - v[1:3]).T) > GATE_MM] if len(new) else new
        self.rejected = kept
        return bool(len(new)) and self._add(self._fine(full), new[:1], events, fixed)

    def _add(self, fine: ImageModel, new: np.ndarray, events: list, sub: ImageModel) -> bool:
        """A new contact at ``new`` (1, 2) (mm), beside contacts tracked already: started
        from the library's scan and fitted alone on ``sub`` (the others held; robust
        loss), its basin searched on its window of ``fine``
        (:func:`~fringekit.inversion.hop.hop`), then all fitted jointly on ``sub`` (robust
        loss). Whether it was added (touched)."""
        pn, dn = start_params(fine, new)
        if not dn:
            return False
        diam = self.diam + dn
        k = np.arange(len(self.diam), len(diam))
        p = fit_indenters(sub, np.concatenate([self.p, pn]), diam, self.noise, free=k).x
        p, _ = hop(fine, p, diam, self.noise, which=k)
        self._adopt(fit_indenters(sub, p, diam, self.noise).x, diam, events)
        return True

    def _append(self, model: ImageModel, p: np.ndarray, new_diam: list, events: list) -> None:
        """The present contacts and new ones (their parameters last in ``p``, their
        diameters ``new_diam``) fitted jointly on ``model`` (robust loss), each one's basin
        searched and the fit repeated when one moved; the new ones get ids (touched)."""
        diam = self.diam + new_diam
        p, moved = hop(model, fit_indenters(model, p, diam, self.noise).x, diam, self.noise)
        moved += settle_new(model, p, diam, len(self.diam), self.noise)
        if moved:
            p = fit_indenters(model, p, diam, self.noise).x
        self._adopt(p, diam, events)

    def _adopt(self, p: np.ndarray, diam: list, events: list) -> None:
        """The contacts ``p``, ``diam``: the present ones first, then new ones, which get
        new ids (touched)."""
        n_new = len(diam) - len(self.diam)
        ids, hist = self._new_ids(n_new), self.history + [[] for _ in range(n_new)]
        self.ids = np.concatenate([self.ids, ids])
        self._reset(p, diam)
        self.history = hist
        events.extend(f"touch {int(i)}" for i in ids)

    def _new_ids(self, n: int) -> np.ndarray:
        """``n`` ids never given before."""
        ids = np.arange(self.next_id, self.next_id + n)
        self.next_id += n
        return ids
