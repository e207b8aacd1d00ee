"""fringekit track: library-synthesised streams tracked back to their loads, contact ids
through a touch, a release and two contacts passing each other, a video against the same
frames as files, a live camera through a stand-in capture, and the bad streams."""

from __future__ import annotations

import csv
import json
import os
import signal
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from library_fixtures import TINY, frozen_stress, sensor_config

import fringekit
from fringekit.analysis import read_pixels
from fringekit.cli.main import main
from fringekit.config.files import load_config, to_toml
from fringekit.config.inputs import optics_setup
from fringekit.errors import ConfigError, InputError, LibraryError
from fringekit.inversion.verdict import InvertError
from fringekit.library.calibrated import CalibratedSensor, coarse_map, fine_map
from fringekit.optics import write_image
from fringekit.tracking import TRACK_COLUMNS, library_frames, open_source, track, write_video
from fringekit.tracking.figure import OverlayPainter
from fringekit.tracking.ids import heirs
from fringekit.tracking.run import FrameSpool
from fringekit.tracking.synthetic import blank_model
from fringekit.tracking.tracker import Tracker

PX, PIXEL_MM = 64, 0.25  # 16 x 16 mm frames of the tiny library's sensor


def _moving(k: int):
    """Two contacts: one sliding 0.2 mm a frame while its load rises, one moving 0.5 mm a
    frame (x, y mm, Fz, Fx, Fy N)."""
    return [(-4.0 + 0.2 * k, 3.5, 2.5 + 0.1 * k, 0.3, 0.0), (3.0, -4.0 + 0.5 * k, 3.0, 0.0, 0.3)]


def _matched(frame, truth) -> np.ndarray:
    """The truth rows (n, 5) nearest to each tracked contact of ``frame``."""
    t = np.asarray(truth, float)
    j = [int(np.argmin(np.hypot(*(t[:, :2] - row[:2]).T))) for row in frame.params]
    return t[j]


@pytest.mark.slow
def test_a_library_stream_is_tracked_back_to_its_loads(tiny_library, tmp_path):
    """16-bit frames of the library's own model: every warm-started frame gives back
    positions to 1e-3 mm and loads to 1e-3 of Fz, with the ids of the first frame."""
    frames = [_moving(k) for k in range(6)]
    library_frames(tiny_library, frames, tmp_path, pixels=PX, pixel_mm=PIXEL_MM, bit_depth=16)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    assert [f.index for f in t.frames] == list(range(6))
    assert t.frames[0].events == ("start",)
    assert all(f.events == () for f in t.frames[1:])  # warm fits only
    first = {int(i): row[:2] for i, row in zip(t.frames[0].ids, t.frames[0].params, strict=True)}
    for f, truth in zip(t.frames, frames, strict=True):
        want = _matched(f, truth)
        scale = np.array([1.0, 1.0, 1.0, 1.0, 1.0]) * np.array([1, 1, *[want[0, 2]] * 3])
        assert np.all(np.abs(f.params - want) <= 1e-3 * scale), (f.index, f.params - want)
        for i, row in zip(f.ids, f.params, strict=True):  # each id stays on its contact
            assert np.hypot(*(row[:2] - first[int(i)])) < 3.0
    assert t.summary["frames_solved"] == 6 and t.summary["contacts"] == [1, 2]


#: The contact of the still streams (x, y mm, Fz, Fx, Fy N).
STILL = (-1.0, 0.5, 2.5, 0.3, 0.0)


def _still_stream(library, folder, monkeypatch, method: str, n: int, **frames):
    """``n`` frames of one contact that does not move, tracked with the chord fit's
    ``method`` wrapped to count its calls: (the track, the index of the frame being solved
    at each call; with a list of the contacts refreshed, one entry per contact)."""
    from fringekit.tracking import warm

    calls, frame = [], [0]
    keep = getattr(warm.ChordFit, method)

    def counted(self, fixed, p, diam, *which):
        calls.extend([frame[0]] * (len(np.atleast_1d(which[0])) if which else 1))
        return keep(self, fixed, p, diam, *which)

    monkeypatch.setattr(warm.ChordFit, method, counted)
    library_frames(library, [[STILL]] * n, folder, pixels=PX, pixel_mm=PIXEL_MM, **frames)
    t = track(
        folder,
        library,
        pixel_mm=PIXEL_MM,
        on_frame=lambda f, img: frame.__setitem__(0, f.index + 1),
    )
    return t, calls


def test_a_still_contact_under_noise_keeps_its_jacobian(tiny_library, tmp_path, monkeypatch):
    """Frames of a contact that does not move, each with its own camera noise: once the
    first warm frame has made the Jacobian, no frame makes it again (a step that changes
    the cost by less than a noise variance ends the fit; remaking every column for such
    a rise took the track bench's warm frame from 46 to 133 ms)."""
    t, made = _still_stream(tiny_library, tmp_path, monkeypatch, "refresh", 7, noise=0.01)
    assert all(f.events == () for f in t.frames[1:])  # warm fits only
    assert [k for k in made if k > 1] == []
    for f in t.frames:  # what the noise leaves: within two stated sd
        assert np.all(np.abs(f.params[0] - STILL) <= 2 * f.sd[0]), f.index


def test_a_frame_already_at_its_minimum_costs_one_evaluation(tiny_library, tmp_path, monkeypatch):
    """The same 16-bit frame four times: from the second warm frame on, the fit starts at
    the minimum, and the fall of the cost its linear model predicts for the next step is
    below GAIN_TOL noise variances, so the frame takes one evaluation of the image (the
    step is not evaluated only to confirm it: that took every frame's second)."""
    t, calls = _still_stream(tiny_library, tmp_path, monkeypatch, "residual", 4, bit_depth=16)
    assert all(f.events == () for f in t.frames[1:])
    assert [calls.count(k) for k in (2, 3)] == [1, 1]
    assert np.all(np.abs(t.frames[-1].params[0] - STILL) <= 1e-3 * np.array([1, 1, 2.5, 2.5, 2.5]))


def test_a_fit_whose_misfit_is_the_models_stops_at_the_model_error(tiny_library, tmp_path):
    """One contact in a sheet with a frozen stress of up to 0.1 fringe that the library
    does not hold (no ``--residual-steps``): the misfit, not the noise, makes the cost
    (hundreds of noise variances a pixel), and it falls by a fraction of a percent a
    step for many steps. With the frame before misfit-dominated too and every Jacobian
    column made in this frame, a Gauss-Newton step within SETTLE of the model-error
    floor ends the fit: 4 evaluations, where the noise's tests alone ran out of steps
    (11 evaluations; 20 to converge over two runs, measured). A large residual makes
    Gauss-Newton's steps short of the least-squares minimum; here the fit stopped 3
    floors short of it in x and in y (0.44 and 0.62 mm from the truth: the misfit's
    bias, which only ``--residual-steps`` removes)."""
    from fringekit.inversion.fit import EXACT_MM, subsample
    from fringekit.inversion.rest import frame_linear
    from fringekit.tracking import warm

    cfg = load_config(tiny_library.folder / "config.toml")
    blank = blank_model(tiny_library, cfg, (PX, PX), PIXEL_MM, "mono", None, optics_setup(cfg))
    ab = frozen_stress(blank, top_fringe=0.1)[2]
    kw = {"pixels": PX, "pixel_mm": PIXEL_MM, "noise": 0.003, "bit_depth": 16}
    library_frames(tiny_library, [[STILL]], tmp_path, residual_ab=ab, **kw)
    raw = read_pixels(tmp_path / "frame_0000.png")
    m, usable, nodata, _ = frame_linear(raw, "mono", cfg["optics"]["camera"], "frame")
    full = replace(blank, measured=m, usable=usable, nodata=nodata)
    sub = replace(subsample(full, 4), exact=EXACT_MM * 1e-3)
    diam = [tiny_library.diameters_mm[0] * 1e-3]

    def fit(steady: bool):
        chord, evaluations = warm.ChordFit(0.003), []
        chord.misfit = steady
        keep = chord.residual
        chord.residual = lambda *a: evaluations.append(1) or keep(*a)
        p, done = chord.run(sub, np.array(STILL, float), diam)
        return done, len(evaluations), chord.misfit

    assert fit(steady=True) == (True, 4, True)
    assert fit(steady=False) == (False, 11, True)  # (the steps ran out)


@pytest.mark.slow
def test_a_warm_jacobian_reuses_the_fields_of_its_point(tiny_library, tmp_path, monkeypatch):
    """The chord fit's Jacobian, made at a point it has just evaluated, takes the
    contacts' fields of that evaluation (five interpolations fewer a refresh): the same
    table, bit for bit, as fields made again."""
    from fringekit.inversion.model import ImageModel
    from fringekit.tracking import warm

    library_frames(
        tiny_library, [_moving(k) for k in range(4)], tmp_path, pixels=PX, pixel_mm=PIXEL_MM
    )
    given, jacobian = [], ImageModel.jacobian

    def spy(self, p, diameters, step=1e-3, which=None, own=None):
        given.append(own is not None)
        return jacobian(self, p, diameters, step, which, own)

    monkeypatch.setattr(ImageModel, "jacobian", spy)
    reused = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM).table()
    assert any(given)
    refresh = warm.ChordFit.refresh

    def afresh(self, fixed, p, diam, which):
        self.fields.clear()
        return refresh(self, fixed, p, diam, which)

    monkeypatch.setattr(warm.ChordFit, "refresh", afresh)
    made = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM).table()
    for k in ("frame", "id", "x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N", "sFz_N", "residual_rms"):
        np.testing.assert_array_equal(reused[k], made[k], err_msg=k)


@pytest.mark.slow
def test_a_light_touch_keeps_one_id_through_the_release_level(tiny_library, tmp_path):
    """A contact pressed from 0.6 N up through the release level (1 N, half the tiny
    library's first load) and lifted to zero: one touch, one id, one release, in the
    frame its load is gone (it was found, dropped and found again under a new id in
    every frame below that level)."""
    ramp = [0.0, 0.6, 0.7, 0.8, 0.9, 1.1, 1.3, 0.8, 0.4, 0.0]
    frames = [
        [(-3.0, 3.0, 3.0, 0.3, 0.0)] + ([(3.5, -3.0, f, 0.0, 0.0)] if f else []) for f in ramp
    ]
    library_frames(tiny_library, frames, tmp_path, pixels=PX, pixel_mm=PIXEL_MM, noise=0.003)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    light = [
        (f.index, int(i))
        for f in t.frames
        for i, row in zip(f.ids, f.params, strict=True)
        if row[0] > 0
    ]
    assert [k for k, _ in light] == list(range(1, 9)) and len({i for _, i in light}) == 1
    events = [e for f in t.frames for e in f.events]
    assert events == ["start", f"touch {light[0][1]}", f"release {light[0][1]}"]
    assert t.frames[9].events == (f"release {light[0][1]}",)
    for f in t.frames:  # the steady contact is not disturbed by the light one
        assert np.hypot(*(f.params[0, :2] - [-3.0, 3.0])) < 0.03, f.index


@pytest.mark.parametrize("grown", [None, np.inf])
def test_a_rejected_touch_place_is_searched_again_once_its_residual_grows(
    tiny_library, tmp_path, monkeypatch, grown
):
    """A contact pressed on from 0.3 N (below the touch level: a quarter of the tiny
    library's 2 N first load) is rejected while light, and its place kept from the
    search; it is searched again as soon as the residual there has grown GROWN times
    (frame 3, at 0.7 N), not only after REJECTED_FRAMES frames (``grown`` inf). On
    ``bench/track.py``'s stream the touch was otherwise read 3 frames late. (Here the
    search of the residual, on this frame's 1 mm fitted grid, finds the contact only
    from 1.6 N: the touch itself is read late either way.)"""
    from fringekit.tracking import tracker

    if grown is not None:
        monkeypatch.setattr(tracker, "GROWN", grown)
    looked = []  # the residual read at a rejected place, once a frame while it is kept
    read = tracker.window_rms
    monkeypatch.setattr(tracker, "window_rms", lambda *a: looked.append(1) or read(*a))
    ramp = [0.0, 0.3, 0.45, 0.7, 1.0, 1.3]
    frames = [
        [(-3.0, 3.0, 3.0, 0.3, 0.0)] + ([(3.5, -3.0, f, 0.0, 0.0)] if f else []) for f in ramp
    ]
    library_frames(tiny_library, frames, tmp_path, pixels=PX, pixel_mm=PIXEL_MM, noise=0.003)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    assert [f.events for f in t.frames[:3]] == [("start",), (), ()]
    # rejected in frame 1; read in frames 2 and 3, released there (grown), or read in
    # every frame to the stream's end (frames 2-5)
    assert len(looked) == (2 if grown is None else 4), len(looked)


def _events(t) -> dict:
    return {f.index: f.events for f in t.frames if f.events}


@pytest.mark.slow
def test_a_touch_a_release_and_a_crossing_keep_their_ids(tiny_library, tmp_path):
    """C and D slide 0.75 mm a frame past each other 4.4 mm apart, A touches at frame 3,
    B is lifted at frame 5: each contact keeps one id, and the touch and the release are
    read in their own frame."""

    def frame(k):
        out = [(-2.2, -3.0 + 0.75 * k, 2.5, 0.0, 0.2), (2.2, 3.0 - 0.75 * k, 3.0, 0.2, 0.0)]
        if k >= 3:
            out.append((5.0, -5.0, 3.0, 0.0, 0.0))  # A touches
        if k < 5:
            out.append((-5.0, 5.0, 2.5, 0.0, -0.2))  # B is lifted
        return out

    frames = [frame(k) for k in range(8)]
    library_frames(tiny_library, frames, tmp_path, pixels=80, pixel_mm=PIXEL_MM, noise=0.003)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    names = {(-2.2, 2.5): "C", (2.2, 3.0): "D", (5.0, 3.0): "A", (-5.0, 2.5): "B"}
    owner: dict[int, str] = {}
    seen: dict[str, set] = {}
    for f, truth in zip(t.frames, frames, strict=True):
        assert len(f.ids) == len(truth), (f.index, f.ids, f.events)
        want = _matched(f, truth)
        assert np.all(np.hypot(*(f.params[:, :2] - want[:, :2]).T) < 0.05), f.index
        for i, w in zip(f.ids, want, strict=True):
            name = names[(w[0], w[2])]
            seen.setdefault(name, set()).add(int(i))
            assert owner.setdefault(int(i), name) == name, f"id {i}: {owner[int(i)]} -> {name}"
    assert all(len(ids) == 1 for ids in seen.values()), seen
    touched = [e for f in t.frames for e in f.events if e.startswith("touch")]
    released = [(f.index, e) for f in t.frames for e in f.events if e.startswith("release")]
    assert touched == [f"touch {next(iter(seen['A']))}"]
    assert "touch" in " ".join(t.frames[3].events)
    assert released == [(5, f"release {next(iter(seen['B']))}")]


def test_where_two_tracked_contacts_meet_the_one_kept_takes_the_id_of_the_one_there():
    """A lifted contact whose fit slid 5.8 mm onto a sliding neighbour's rings, and was
    kept as the stronger of the two, takes the neighbour's id (a stepping of the tests'
    stick library gave the lifted contact's id to the sliding one, and the sliding one a
    new id a frame later); two contacts that met where each was stay as they were, a
    contact found in this frame gives no id, and each dropped one's id goes once."""
    clash = np.array([[np.inf, -3.4, -3.0], [-3.4, np.inf, -3.1], [-3.0, -3.1, np.inf]])
    before = [[-2.2, 0.0], [-5.0, 5.0], [np.nan, np.nan]]
    now = [[-2.2, 0.8], [-2.2, 0.75], [-2.0, 0.7]]
    assert heirs(clash[:2, :2], [0], [1], before[:2], now[:2]) == {1: 0}
    # the one kept stayed and the other came to it: no one's id changes
    assert heirs(clash[:2, :2], [1], [0], before[:2], now[:2]) == {}
    # a dropped contact found in this frame has no id to give
    assert heirs(clash, [2], [0, 1], before, now) == {}
    # one id, given once: to the nearest of two kept that met it
    kept_two = [[-2.2, 0.0], [-5.0, 5.0], [-4.0, 4.0]]
    assert heirs(clash, [0], [1, 2], kept_two, [[-2.2, 0.8], [-2.2, 0.75], [-2.2, 0.2]]) == {2: 0}
    # contacts apart do not meet
    apart = np.array([[np.inf, 2.0], [2.0, np.inf]])
    assert heirs(apart, [0], [1], before[:2], now[:2]) == {}


def test_a_contact_about_to_be_dropped_is_judged_by_its_own_load_a_frame_before(monkeypatch):
    """Whether a contact the release would drop bore a clear load a frame before (then it
    moved too fast, and is searched for) is read by its id: the frame before may hold
    its contacts in another order (it read the row, and so another contact's load)."""
    from types import SimpleNamespace

    from fringekit.tracking import tracker as tracker_module

    lib = SimpleNamespace(load_N=np.array([0.0, 1.0, 2.0]))
    t = Tracker(SimpleNamespace(lib=lib))
    t.diam, t.ids = [3.5e-3] * 3, np.array([3, 5, 9])
    t.p = np.array([[0, 0, 1.0, 0, 0], [4, 0, 0.01, 0, 0], [8, 0, 0.01, 0, 0]], float).ravel()
    # a frame before: 5 bore 3 N, 3 bore 0.1 N, and 7 (released since) 3 N; 9 is new
    t.p_before = np.array([[4, 0, 3.0, 0, 0], [0, 0, 0.1, 0, 0], [9, 0, 3.0, 0, 0]]).ravel()
    t.ids_before = np.array([5, 3, 7])
    monkeypatch.setattr(tracker_module, "prune", lambda p, sd, diam, lib, held: (p, diam, [0]))
    assert t._lost(np.zeros((3, 5)), []).tolist() == [False, True, False]


@pytest.mark.slow
def test_a_frame_is_solved_on_one_blas_thread(tiny_library, tmp_path, monkeypatch):
    """The warm fit runs on one BLAS thread: OpenBLAS's threads, spinning while
    they wait, took the cores from the ``--show`` window (the track bench: 4.42 frames a
    second with 28 redraws, 5.07 with 84 on one thread)."""
    from threadpoolctl import threadpool_info

    from fringekit.tracking import warm

    seen, keep = [], warm.ChordFit.run

    def run(self, *args):
        seen.append({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})
        return keep(self, *args)

    monkeypatch.setattr(warm.ChordFit, "run", run)
    library_frames(
        tiny_library, [_moving(k) for k in range(3)], tmp_path, pixels=PX, pixel_mm=PIXEL_MM
    )
    track(tmp_path, tiny_library, pixel_mm=PIXEL_MM, progress=False)
    assert seen and all(s <= {1} for s in seen), seen


@pytest.mark.slow
def test_the_quick_start_finds_a_contact_detection_missed_in_the_residual(tiny_library):
    """A first frame of two contacts 10 mm apart whose detection gave one candidate: the
    quick start looks for fringes in the residual of the contact it fitted, and comes
    back with both (it used to give up, leaving the frame to the whole inverse: 215-461 s
    a frame on the track bench, where two contacts' fringes merge and detection gives
    them one candidate)."""
    from fringekit.inversion.model import unpack
    from fringekit.inversion.quick import quick_start
    from fringekit.tracking.synthetic import blank_model

    truth = np.array([[-4.0, 3.0, 2.5, 0.3, 0.0], [4.0, -3.0, 3.0, 0.0, 0.3]])
    diam = [3.5e-3] * 2
    blank = blank_model(tiny_library, sensor_config(**TINY), (80, 80), PIXEL_MM, "mono")
    img, _ = blank.linear(unpack(truth.ravel(), diam))
    noise = 0.003
    measured = img + noise * np.random.default_rng(5).standard_normal(img.shape)
    full = replace(blank, measured=measured)
    p, got = quick_start(full, truth[:1, :2] + 0.2, 2, noise)
    assert got is not None and len(got) == 2
    q = p.reshape(-1, 5)[np.argsort(p.reshape(-1, 5)[:, 0])]
    assert np.all(np.hypot(*(q[:, :2] - truth[:, :2]).T) < 0.01), q
    np.testing.assert_allclose(q[:, 2], truth[:, 2], rtol=0.01)


@pytest.mark.parametrize("off_mm", [pytest.param(0.9, marks=pytest.mark.slow), 0.0])
def test_a_touch_fitted_off_its_axis_is_moved_onto_it(tiny_library, off_mm):
    """The touch of the crossing stream above, as one machine's arithmetic fitted it: its
    axis 0.9 mm off, a tangential load it does not bear standing in for the offset. The
    search about it (``settle_new``) moves it into its axis' basin and leaves the held
    contacts as they were, and the joint fit after it reads every contact; a touch on
    its axis is not searched. (On this image the joint fit alone also finds the axis,
    from 0.7-1.1 mm off in 8 directions: the minimum that held the stream's touch off
    its axis came from that machine's path through the fits, and is not made here.)"""
    from dataclasses import replace

    from fringekit.inversion.fit import EXACT_MM, fit_indenters, subsample
    from fringekit.inversion.model import unpack
    from fringekit.tracking.settle import settle_new
    from fringekit.tracking.synthetic import blank_model

    truth = np.array(
        [
            [-2.2, -0.75, 2.5, 0.0, 0.2],
            [2.2, 0.75, 3.0, 0.2, 0.0],
            [-5.0, 5.0, 2.5, 0.0, -0.2],
            [5.0, -5.0, 3.0, 0.0, 0.0],  # the touch
        ]
    )
    diam = [3.5e-3] * 4
    blank = blank_model(tiny_library, sensor_config(**TINY), (80, 80), PIXEL_MM, "mono")
    img, _ = blank.linear(unpack(truth.ravel(), diam))
    noise = 0.003
    measured = img + noise * np.random.default_rng(3).standard_normal(img.shape)
    model = replace(subsample(replace(blank, measured=measured), 2), exact=EXACT_MM * 1e-3)
    p = truth.copy()
    p[3] += [off_mm, 0.0, 0.0, -0.68 * off_mm / 0.9, 0.0]
    p = p.ravel()
    moved = settle_new(model, p, diam, 3, noise)
    q = p.reshape(-1, 5)
    np.testing.assert_array_equal(q[:3], truth[:3])  # the held contacts: not fitted here
    if off_mm == 0:
        assert moved == 0 and np.array_equal(q[3], truth[3])
        return
    assert moved == 1
    assert np.hypot(*(q[3, :2] - truth[3, :2])) < 0.1, q[3]  # into the axis' basin
    q = fit_indenters(model, p, diam, noise).x.reshape(-1, 5)  # as the tracker goes on
    assert np.all(np.hypot(*(q[:, :2] - truth[:, :2]).T) < 0.005), q
    assert np.all(np.abs(q[:, 2:] - truth[:, 2:]) < 0.005 * truth[:, 2:3]), q


@pytest.mark.slow
def test_a_video_gives_the_loads_of_its_frames(tiny_library, tmp_path):
    """The same frames as PNG files and as a lossless video: the same table."""
    frames = [_moving(k) for k in range(4)]
    folder = tmp_path / "frames"
    library_frames(tiny_library, frames, folder, pixels=PX, pixel_mm=PIXEL_MM, noise=0.003)
    video = tmp_path / "stream.mkv"
    write_video(
        video, (read_pixels(p) for p in sorted(folder.glob("frame_*"))), 10.0, lossless=True
    )
    a = track(folder, tiny_library, pixel_mm=PIXEL_MM).table()
    b = track(video, tiny_library, pixel_mm=PIXEL_MM).table()
    for k in ("frame", "id", "x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N", "sFz_N"):
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


class _Capture:
    """A camera at OpenCV's seam that drops frames on a fixed schedule: BGR frames of a
    list delivered in bursts (lists of frame indices). The first burst is read at once;
    each later one when :meth:`next_burst` is called (from the tracker's ``on_frame``,
    in the tracker's thread), which returns once the burst's last frame is in the
    source's slot, so the tracker takes that frame and the rest of the burst is dropped,
    however fast the machine."""

    def __init__(self, frames, bursts):
        self.frames, self.reads = frames, 0
        self.starts = {b[0] for b in bursts[1:]} | {len(frames)}
        self.go = threading.Semaphore(0)
        self.in_slot = threading.Semaphore(0)
        self.waiting = False

    def next_burst(self):
        if self.reads < len(self.frames):
            self.waiting = True
            self.go.release()
            assert self.in_slot.acquire(timeout=60)

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return True

    def get(self, prop):
        return 10.0 if prop == 5 else 0.0

    def read(self):
        if self.reads in self.starts:
            # the reading thread reads again only once the frame before is in its slot
            if self.waiting:
                self.waiting = False
                self.in_slot.release()
            if self.reads == len(self.frames):
                return False, None
            self.go.acquire()
        self.reads += 1
        return True, self.frames[self.reads - 1][..., ::-1].copy()

    def release(self):
        pass


@pytest.mark.slow
def test_a_camera_stream_solves_the_newest_frame_and_counts_the_dropped(tiny_library, tmp_path):
    """Frames dropped while the tracker works: it solves frames 0, 4 and 11 (gaps of 4
    and 7 frames, beyond MAX_GAP: each searched afresh) and keeps both contacts' ids
    (a gap of 4 used to make a contact found twice, the tracked one released and its
    twin given a new id, 0.3 mm off)."""
    frames = [_moving(k) for k in range(12)]
    folder = tmp_path / "frames"
    library_frames(tiny_library, frames, folder, pixels=PX, pixel_mm=PIXEL_MM)
    rgb = [np.repeat(read_pixels(p)[..., None], 3, axis=2) for p in sorted(folder.glob("frame_*"))]
    cap = _Capture(rgb, [[0], [1, 2, 3, 4], list(range(5, 12))])
    src = open_source("camera:0", capture_factory=lambda n: cap)
    t = track(
        src, tiny_library, pixel_mm=PIXEL_MM, method="mono", on_frame=lambda *a: cap.next_burst()
    )
    s = t.summary
    assert s["source"]["kind"] == "camera"
    assert [f.index for f in t.frames] == [0, 4, 11]
    assert s["frames_solved"] == 3 and s["frames_dropped"] == 9, s
    assert any(w.startswith("9 camera frame(s) were dropped") for w in s["warnings"])
    which = {}  # id -> the truth row (contact) it reads
    for f in t.frames:  # each solved frame is the frame of its index, each id its contact
        want = _matched(f, frames[f.index])
        assert np.all(np.abs(f.params[:, :2] - want[:, :2]) < 0.01), (f.index, f.params)
        truth = np.asarray(frames[f.index], float)
        for i, row in zip(f.ids, f.params, strict=True):
            j = int(np.argmin(np.hypot(*(truth[:, :2] - row[:2]).T)))
            assert which.setdefault(int(i), j) == j, (f.index, f.ids, f.events)
    assert len(which) == 2


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
@pytest.mark.parametrize("bad", ["another size", "unreadable"])
def test_the_command_writes_loads_and_keeps_what_a_bad_frame_stopped(
    tiny_library, tmp_path, capsys, bad
):
    """A frame of another size, or a file in the folder that is no image, ends the stream:
    exit 2 in one line naming the file, the frames before it in loads.csv and summary.json
    (which says where and why it stopped)."""
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(3)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    if bad == "unreadable":
        (folder / "frame_0003.png").write_bytes(b"not a png: the camera stopped mid-write")
    else:
        big = tmp_path / "big"
        library_frames(tiny_library, [_moving(3)], big, pixels=PX + 8, pixel_mm=PIXEL_MM)
        (big / "frame_0000.png").rename(folder / "frame_0003.png")
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    code = main(
        ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out), "--quiet"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1, err
    assert "stopped after 3 frame(s)" in err[0] and "frame_0003.png" in err[0]
    rows = _rows(out / "loads.csv")
    assert tuple(rows[0]) == TRACK_COLUMNS
    assert sorted({r["frame"] for r in rows}) == ["0", "1", "2"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stopped"]["after_frames"] == 3
    assert (out / "loads.png").is_file()


def _raise_in_frame(monkeypatch, index: int, exc: BaseException) -> None:
    """``Tracker.step`` raises ``exc`` in frame ``index`` and solves every other frame."""
    step = Tracker.step

    def raising(self, measured, usable, nodata, frame_index, time_s, censored=None):
        if frame_index == index:
            raise exc
        return step(self, measured, usable, nodata, frame_index, time_s, censored)

    monkeypatch.setattr(Tracker, "step", raising)


@pytest.mark.slow
def test_a_first_frame_the_whole_inverse_refuses_is_recorded_not_read_as_empty(
    tiny_library, tmp_path, monkeypatch
):
    """A first frame that the quick start leaves unexplained goes to the whole inverse;
    when that refuses it, the frame is a refused one with the inverse's reason (it used
    to come back as a frame without contacts, nothing said), and the next frame starts
    afresh. Each start's stages are timed in the frame's ``times_s``."""
    import fringekit.tracking.tracker as tracker_module

    library_frames(
        tiny_library, [_moving(k) for k in range(2)], tmp_path, pixels=PX, pixel_mm=PIXEL_MM
    )
    whole = tracker_module.invert_image
    calls = []

    def inverse(full, **kw):
        calls.append(kw)
        if len(calls) == 1:
            raise InvertError("the library cannot explain this image: stand-in")
        return whole(full, **kw)

    monkeypatch.setattr(tracker_module, "quick_start", lambda *a: (None, None))
    monkeypatch.setattr(tracker_module, "invert_image", inverse)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    assert t.summary["frames_refused"] == [
        {"frame": 0, "reason": "the library cannot explain this image: stand-in"}
    ]
    (f,) = t.frames
    assert f.index == 1 and f.events == ("start",) and len(f.ids) == 2
    assert {"quick_start_s", "inverse_s", "start_s"} <= set(f.times_s)
    assert np.allclose(_matched(f, _moving(1))[:, :2], f.params[:, :2], atol=0.05)


@pytest.mark.parametrize("left_out", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_a_frame_the_library_cannot_explain_is_drawn_without_contacts(
    tiny_library, tmp_path, monkeypatch, left_out
):
    """A frame the tracker refuses (``InvertError``) is left out of the table; the video
    shows it without contacts. The overlay used to draw the frame before's contacts on
    it, and crashed (IndexError) when the first frame was the one left out."""
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(3)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    drawn = []

    def paint(self, image, params, ids):
        drawn.append(len(params))
        return np.zeros((*image.shape[:2], 3), np.uint8)

    _raise_in_frame(monkeypatch, left_out, InvertError("the library cannot explain this frame"))
    monkeypatch.setattr(OverlayPainter, "paint", paint)
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    argv = ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out)]
    assert main([*argv, "--video", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [f["frame"] for f in summary["frames_refused"]] == [left_out]
    assert sorted({r["frame"] for r in _rows(out / "loads.csv")}) == sorted(
        {"0", "1", "2"} - {str(left_out)}
    )
    assert drawn[left_out] == 0 and all(n == 2 for k, n in enumerate(drawn) if k != left_out)
    with open_source(str(out / "track.mp4")) as video:  # every frame, from the disk spool
        assert sum(1 for _ in video) == 3
    written = {p.name for p in out.iterdir()} - {".fringekit-run.json"}  # the run's record
    assert written == {"loads.csv", "loads.png", "summary.json", "track.mp4"}  # no spool


@pytest.mark.slow
def test_the_command_writes_to_fringekit_out_track_by_default(tiny_library, tmp_path, monkeypatch):
    """``--out`` is optional, as for ``predict`` and ``analyze``: fringekit-out/track."""
    folder = tmp_path / "frames"
    library_frames(tiny_library, [_moving(0)], folder, pixels=PX, pixel_mm=PIXEL_MM)
    monkeypatch.chdir(tmp_path)
    argv = ["track", str(folder), "--library", str(tiny_library.folder), "--pixel-mm", "0.25"]
    assert main([*argv, "--quiet"]) == 0
    assert len(_rows(tmp_path / "fringekit-out" / "track" / "loads.csv")) == 2


def test_the_frame_spool_removes_a_frame_saved_but_not_yet_counted(tmp_path):
    """Ctrl-C between a frame's save and its count left a file the spool did not know,
    its folder could not be removed, and the run that Ctrl-C should have kept was lost."""
    spool = FrameSpool(tmp_path / ".frames")
    spool(None, np.zeros((4, 4), np.uint8))
    np.save(spool.folder / "0000001.npy", np.zeros((4, 4), np.uint8))  # saved, not counted
    assert len(spool) == 1
    spool.remove()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_ctrl_c_writes_the_frames_solved_before_it(tiny_library, tmp_path, monkeypatch, capsys):
    """Ctrl-C in the third frame: exit 130 in one line, the two frames before it in
    loads.csv, summary.json and the video, and summary.json says where it stopped."""
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(4)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    _raise_in_frame(monkeypatch, 2, KeyboardInterrupt())
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    argv = ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out)]
    assert main([*argv, "--video", "--quiet"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stopped after 2 frame(s)" in err[0] and "Ctrl-C" in err[0]
    assert sorted({r["frame"] for r in _rows(out / "loads.csv")}) == ["0", "1"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stopped"] == {"after_frames": 2, "reason": "interrupted (Ctrl-C)"}
    with open_source(str(out / "track.mp4")) as video:
        assert sum(1 for _ in video) == 2


@pytest.mark.slow
@pytest.mark.parametrize("trouble", ["ctrl-c", "error"])
def test_a_video_that_fails_while_painted_keeps_the_tables(
    tiny_library, tmp_path, monkeypatch, capsys, trouble
):
    """Ctrl-C or an error while track.mp4 is painted, after the stream: the tables and
    summary are kept (the whole run used to be discarded), no partial video is left,
    summary.json says why, and Ctrl-C exits 130."""
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(3)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    paint, drawn = OverlayPainter.paint, []

    def failing(self, image, params, ids):
        if len(drawn) == 1:
            raise KeyboardInterrupt() if trouble == "ctrl-c" else ValueError("bad overlay")
        drawn.append(1)
        return paint(self, image, params, ids)

    monkeypatch.setattr(OverlayPainter, "paint", failing)
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    argv = ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out)]
    assert main([*argv, "--video", "--quiet"]) == (130 if trouble == "ctrl-c" else 0)
    assert sorted({r["frame"] for r in _rows(out / "loads.csv")}) == ["0", "1", "2"]
    summary = json.loads((out / "summary.json").read_text())
    video = summary["video"]
    assert video["file"] is None and video["frames"] == 1
    assert ("Ctrl-C" if trouble == "ctrl-c" else "ValueError") in video["error"]
    assert any(w.startswith("track.mp4 was not written") for w in summary["warnings"])
    written = {p.name for p in out.iterdir()} - {".fringekit-run.json"}
    assert written == {"loads.csv", "loads.png", "summary.json"}  # no spool, no half video
    assert "track.mp4 was not written" in capsys.readouterr().err


@pytest.mark.slow
def test_a_full_disk_gives_the_video_up_not_the_run(tiny_library, tmp_path, monkeypatch):
    """The spool cannot save a frame (a full disk): the video is given up and its frames
    deleted (their space freed), every frame is still solved and written."""
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(3)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    save, saved = np.save, []

    def full(path, array, *args, **kwargs):
        if Path(path).parent.name == ".frames":
            if len(saved) == 1:
                raise OSError(28, "No space left on device")
            saved.append(path)
        return save(path, array, *args, **kwargs)

    monkeypatch.setattr(np, "save", full)
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    argv = ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out)]
    assert main([*argv, "--video", "--quiet"]) == 0
    assert sorted({r["frame"] for r in _rows(out / "loads.csv")}) == ["0", "1", "2"]
    video = json.loads((out / "summary.json").read_text())["video"]
    assert video["file"] is None and "frame 1" in video["error"]
    assert "No space left" in video["error"]
    written = {p.name for p in out.iterdir()} - {".fringekit-run.json"}
    assert written == {"loads.csv", "loads.png", "summary.json"}


#: A stand-in for the ``--show`` window, imported by the display's own process: its
#: first draw waits for a ``release`` file beside it (or 120 s, then fails); every draw
#: ends by writing what it was given to ``drawn.json``.
STUCK_WINDOW = """
import json, time
from pathlib import Path
HERE = Path(__file__).parent
class Window:
    def __init__(self):
        self.draws = 0
    def is_open(self):
        return True
    def wait(self, seconds):
        time.sleep(seconds)
    def draw(self, rgb, loads):
        if self.draws == 0:
            (HERE / "started").touch()
            t0 = time.monotonic()
            while not (HERE / "release").exists():
                if time.monotonic() - t0 > 120:
                    raise RuntimeError("never released")
                time.sleep(0.01)
        self.draws += 1
        rows = {str(i): [t.tolist(), fz.tolist()] for i, (t, fz, ft) in loads.items()}
        (HERE / "drawn.json").write_text(json.dumps({"shape": rgb.shape, "loads": rows}))
"""


@pytest.mark.slow
def test_the_live_window_never_holds_the_solver_and_plots_every_frame(
    tiny_library, tmp_path, monkeypatch
):
    """``--show``: the window draws in a process of its own. With its first draw stuck,
    the stream is still solved to its end (the window has finished no draw when it
    is); released, the window's rolling plot holds every frame's Fz, though it drew at
    most a few of the frames. The window used to draw between two frames, in the
    solver's loop."""
    from fringekit.tracking.display import LiveDisplay

    helpers = tmp_path / "helpers"
    helpers.mkdir()
    (helpers / "stuck_window.py").write_text(STUCK_WINDOW)
    monkeypatch.syspath_prepend(str(helpers))  # the display's process imports it
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(4)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    with LiveDisplay(PIXEL_MM, None, window="stuck_window:Window") as view:
        t = track(folder, tiny_library, pixel_mm=PIXEL_MM, on_frame=view, progress=False)
        assert [f.index for f in t.frames] == [0, 1, 2, 3]
        assert not (helpers / "drawn.json").exists()  # solved while no draw had ended
        (helpers / "release").touch()
    assert view.error is None and view.sent + view.skipped == 4
    drawn = json.loads((helpers / "drawn.json").read_text())
    assert drawn["shape"] == [PX, PX, 3]
    want: dict = {}
    for f in t.frames:
        for i, row in zip(f.ids, f.params, strict=True):
            want.setdefault(str(int(i)), []).append([f.time_s, row[2]])
    assert sorted(drawn["loads"]) == sorted(want) and len(want) == 2
    for i, rows in want.items():
        np.testing.assert_array_equal(np.array(drawn["loads"][i]).T, rows)


@pytest.mark.slow
def test_a_stuck_window_is_ended_and_the_run_told(tmp_path, monkeypatch):
    """A window that never finishes its draw holds up the end of a run by the close's
    waits only (here shortened), and is ended; the run is told why."""
    from fringekit.tracking import display
    from fringekit.tracking.frame import TrackedFrame

    monkeypatch.setattr(display, "CLOSE_S", 0.5)
    helpers = tmp_path / "helpers"
    helpers.mkdir()
    (helpers / "stuck_window.py").write_text(STUCK_WINDOW)
    monkeypatch.syspath_prepend(str(helpers))
    params = np.array([[0.0, 0.0, 2.0, 0.0, 0.0]])
    frame = TrackedFrame(0, 0.0, np.array([1]), params, params, np.zeros(1), np.ones(1, bool))
    view = display.LiveDisplay(PIXEL_MM, None, window="stuck_window:Window", interval_s=0.0)
    view(frame, np.zeros((8, 8), np.uint8))
    for _ in range(6000):  # the process starts (a second or two) and its draw sticks
        if (helpers / "started").exists():
            break
        time.sleep(0.01)
    view(frame, np.zeros((8, 8), np.uint8))  # the slot: full from here on
    view(frame, np.zeros((8, 8), np.uint8))
    assert view.sent == 2 and view.skipped == 1
    assert view.close() == "it did not close within 0.5 s and was ended"
    assert not view.process.is_alive()


#: A script that opens the ``--show`` window where matplotlib can open none, after
#: handing it two 256 x 256 frames (each more than a pipe holds), and closes it; the
#: window's process records how it found Ctrl-C as it started (it imports the script).
NO_WINDOW_SCRIPT = """
import signal, sys
from pathlib import Path
import numpy as np
from fringekit.tracking.display import LiveDisplay
if __name__ == "__mp_main__":
    Path(sys.argv[1]).write_text(str(signal.getsignal(signal.SIGINT)))
if __name__ == "__main__":
    view = LiveDisplay(0.25, None, interval_s=0.0)
    for _ in range(2):
        view(None, np.zeros((256, 256), np.uint8))
    print(view.close())
"""


@pytest.mark.slow
def test_a_window_that_never_reads_lets_the_run_exit(tmp_path):
    """No window could open (matplotlib's file backend): the frames handed to it are
    dropped and the run's interpreter exits (it used to wait forever on writing them into
    a pipe nobody read); a Ctrl-C while the window's process starts is not its."""
    import subprocess
    import sys

    script = tmp_path / "no_window.py"
    script.write_text(NO_WINDOW_SCRIPT)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    mark = tmp_path / "sigint.txt"
    done = subprocess.run(
        [sys.executable, str(script), str(mark)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "which opens no window" in done.stdout
    assert mark.read_text() == str(signal.SIG_IGN)


@pytest.mark.slow
def test_a_show_without_a_display_warns_and_tracks_the_stream(tiny_library, tmp_path, monkeypatch):
    """``--show`` where matplotlib opens no window (here its file backend, as on a
    machine without a display): the stream is tracked as without it, and the summary
    says why there was no window."""
    monkeypatch.setenv("MPLBACKEND", "Agg")  # the display's process inherits it
    folder = tmp_path / "frames"
    library_frames(
        tiny_library, [_moving(k) for k in range(2)], folder, pixels=PX, pixel_mm=PIXEL_MM
    )
    out = tmp_path / "out"
    lib = str(tiny_library.folder)
    argv = ["track", str(folder), "--library", lib, "--pixel-mm", "0.25", "--out", str(out)]
    assert main([*argv, "--show", "--quiet"]) == 0
    assert sorted({r["frame"] for r in _rows(out / "loads.csv")}) == ["0", "1"]
    summary = json.loads((out / "summary.json").read_text())
    assert "backend is Agg, which opens no window" in summary["show"]["error"]
    assert any(w.startswith("--show: the window failed") for w in summary["warnings"])


def test_a_residual_bump_is_not_a_contact_nor_searched_every_frame(
    tiny_library, tmp_path, monkeypatch
):
    """A model misfit that looks like a light new contact (an intensity bump of 0.1 beside
    a steady contact, as FEM frames show near 4 N contacts): the touch search finds it,
    the fit finds no significant load there, and it is dropped in the same frame, with
    no touch and no release; the place is searched again only after REJECTED_FRAMES. The
    old rule reported a new contact in every frame, released the next."""
    from fringekit.tracking import tracker

    library_frames(
        tiny_library,
        [[(-3.0, 3.0, 3.0, 0.3, 0.0)]] * 8,
        tmp_path,
        pixels=PX,
        pixel_mm=PIXEL_MM,
        noise=0.003,
    )
    r, c = np.mgrid[:PX, :PX]
    x, y = (c - (PX - 1) / 2) * PIXEL_MM, ((PX - 1) / 2 - r) * PIXEL_MM
    bump = 0.1 * np.exp(-((x - 3.0) ** 2 + (y + 3.0) ** 2) / (2 * 0.6**2))
    for p in sorted(tmp_path.glob("frame_*.png")):
        img = read_pixels(p).astype(float) / 255 + bump
        write_image(p, np.round(np.clip(img, 0, 1) * 255).astype(np.uint8))
    searched = []
    start = tracker.start_params  # a touch's fit begins with the library's start scan
    monkeypatch.setattr(tracker, "start_params", lambda *a: searched.append(1) or start(*a))
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    assert [f.events for f in t.frames] == [("start",)] + [()] * 7
    assert all(len(f.ids) == 1 for f in t.frames)
    assert len(searched) == 2  # frames 1 and 1 + REJECTED_FRAMES + 1 (the old rule: 6)
    assert tracker.REJECTED_FRAMES == 5


@pytest.mark.slow
def test_a_contact_at_the_library_s_largest_load_is_not_reliable(tiny_library, tmp_path):
    """A contact pressed on to the library's largest load (4 N) is fitted there, held at
    the bound: ``invert`` would refuse it, so the tracker flags it, residual or not; its
    neighbour at 2.5 N stays reliable."""
    frames = [[(-3.0, 3.0, 2.5, 0.3, 0.0), (3.0, -3.0, f, 0.0, 0.0)] for f in (3.0, 3.5, 4.0)]
    library_frames(tiny_library, frames, tmp_path, pixels=PX, pixel_mm=PIXEL_MM, noise=0.003)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    assert [len(f.ids) for f in t.frames] == [2, 2, 2]
    assert all(np.all(f.residual_rms < 0.05) for f in t.frames)
    # by position, not by id: which contact gets the lower id is the detection's order
    pressed = [f.reliable[np.argmax(f.params[:, 0])] for f in t.frames]
    other = [f.reliable[np.argmin(f.params[:, 0])] for f in t.frames]
    assert pressed == [True, True, False] and other == [True] * 3


def test_frames_replace_their_own_earlier_stream_and_refuse_a_user_s_folder(tiny_library, tmp_path):
    """A shorter stream written over a longer one leaves only its own frames (a stale
    frame would be tracked as part of it); a folder with a file fringekit did not write is
    refused, the file kept, before a frame is written."""
    folder = tmp_path / "frames"
    moving = [_moving(k) for k in range(3)]
    library_frames(tiny_library, moving, folder, pixels=PX, pixel_mm=PIXEL_MM)
    assert library_frames(tiny_library, moving[:1], folder, pixels=PX, pixel_mm=PIXEL_MM) == 1
    assert sorted(p.name for p in folder.glob("frame_*")) == ["frame_0000.png"]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(
        InputError, match=r"folder .*mine holds files fringekit did not write \(notes.txt\)"
    ):
        library_frames(tiny_library, moving, mine, pixels=PX, pixel_mm=PIXEL_MM)
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["camera:abc"], ["camera:abc"]),
        (["nowhere"], ["nowhere"]),
        (["FRAMES", "--pixel-mm", "0"], ["--pixel-mm", "0"]),
        (["FRAMES", "--method", "dark"], ["--method", "dark"]),
    ],
)
def test_bad_streams_are_one_line_and_write_nothing(tiny_library, tmp_path, capsys, args, words):
    folder = tmp_path / "frames"
    library_frames(tiny_library, [_moving(0)], folder, pixels=PX, pixel_mm=PIXEL_MM)
    args = [str(folder) if a == "FRAMES" else a for a in args]
    if "--pixel-mm" not in args:
        args += ["--pixel-mm", "0.25"]
    out = tmp_path / "out"
    code = main(["track", *args, "--library", str(tiny_library.folder), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert not out.exists()


def test_a_zero_length_video_and_another_sensor_are_refused(tiny_library, tmp_path, capsys):
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    out = tmp_path / "out"
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", "0.25", "--out", str(out)]
    assert main(["track", str(empty), *lib]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "empty.mp4" in err[0], err
    assert not out.exists()
    other = tmp_path / "other.toml"
    other.write_text(to_toml(sensor_config(**TINY, **{"sheet.thickness_mm": 2.0})))
    with pytest.raises(ConfigError, match="give a sensor file"):
        track(tmp_path, tiny_library, pixel_mm=0.25, sensor=other)
    cfg = sensor_config(**TINY, **{"sheet.thickness_mm": 2.0})
    s = CalibratedSensor.uncalibrated(cfg, tiny_library, (PX, PX), "mono", 0.25)
    with pytest.raises(LibraryError, match="thickness_mm"):
        track(tmp_path, tiny_library, sensor=s)
    # the same through the command: one line naming the key that differs, nothing written
    folder = tmp_path / "frames"
    library_frames(tiny_library, [_moving(0)], folder, pixels=PX, pixel_mm=PIXEL_MM)
    sensor_file = s.save(tmp_path / "other.json")
    assert main(["track", str(folder), *lib, "--sensor", str(sensor_file)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "thickness_mm" in err[0] and "--library" in err[0], err
    assert not out.exists()


@pytest.mark.slow
def test_invert_agrees_with_the_first_frame_of_track(tiny_library, tmp_path):
    """The tracker's first frame is its quick start, or invert's whole inverse when that
    does not explain the frame: the same answer (to 1e-9) in the second case, and within
    half their stated 1-sigma in the first (with a stick library stepped otherwise, the
    quick start was kept 9 um and 8 mN from invert, whose sd were 43 um and 0.13 N)."""
    library_frames(tiny_library, [_moving(0)], tmp_path, pixels=PX, pixel_mm=PIXEL_MM, noise=0.003)
    inv = fringekit.invert(tmp_path / "frame_0000.png", tiny_library, pixel_mm=PIXEL_MM)
    t = track(tmp_path, tiny_library, pixel_mm=PIXEL_MM)
    a, b = inv.result.params, t.frames[0].params
    order_a, order_b = np.argsort(a[:, 0]), np.argsort(b[:, 0])
    sd = inv.result.sd[order_a]
    whole = "inverse_s" in t.frames[0].times_s  # the quick start was not kept
    assert np.all(np.abs(a[order_a] - b[order_b]) <= (1e-9 if whole else 0.5 * sd))
    assert np.all(np.abs(t.frames[0].sd[order_b] - sd) <= 0.05 * sd)


@pytest.mark.slow
def test_four_contacts_start_without_the_whole_inverse(test_library, tmp_path, monkeypatch):
    """The quick start holds on a 256 x 256 frame of four contacts: its scan puts a fifth
    candidate beside one of them, and the four left after dropping it are fitted again
    (without that fit one read 1 mm off, and the frame went to the whole inverse, 5x
    longer). Every load within 5 mN and position within 5 um (this noise moves them by
    1.5 at most; the fit without the fifth candidate's refit was 1 mm off)."""

    def whole_inverse(*args, **kwargs):
        raise AssertionError("the first frame ran the whole inverse")

    monkeypatch.setattr("fringekit.tracking.tracker.invert_image", whole_inverse)
    rows = [(-6.0, 5.5, 2.5, 0.5, 0.0), (-2.2, -5.0, 3.0, 0.0, 0.4)]
    rows += [(2.2, 3.0, 2.0, -0.3, 0.0), (-6.5, -1.5, 3.0, 0.0, 0.0)]
    library_frames(test_library, [rows], tmp_path, pixels=256, pixel_mm=16 / 256, noise=0.005)
    f = track(tmp_path, test_library, pixel_mm=16 / 256).frames[0]
    assert f.events == ("start",) and len(f.ids) == 4
    err = f.params - _matched(f, rows)
    assert np.all(np.abs(err) <= 5e-3), err


def _glare(shape) -> np.ndarray:
    """A smooth rest light (linear 0-1): an even glare and a patch of residual stress."""
    r, c = np.mgrid[: shape[0], : shape[1]] / shape[0]
    return 0.05 + 0.12 * np.exp(-((r - 0.4) ** 2 + (c - 0.65) ** 2) / (2 * 0.2**2))


@pytest.mark.slow
def test_a_rest_frame_s_light_is_taken_off_every_frame(tiny_library, tmp_path):
    """Frames of the library's model with a rest light added (glare and residual stress,
    up to 0.17 of full scale): tracked with ``--reference`` (a frame of that light
    alone), every contact is read back to 2e-3 mm and 2e-3 of its Fz; without it, a load
    is more than 0.1 N off (and, today, still flagged reliable)."""
    clean = tmp_path / "clean"
    truth = [_moving(k) for k in range(3)]
    library_frames(tiny_library, truth, clean, pixels=PX, pixel_mm=PIXEL_MM, bit_depth=16)
    glare = _glare((PX, PX))
    lit = tmp_path / "lit"
    lit.mkdir()
    for k in range(3):
        img = read_pixels(clean / f"frame_{k:04d}.png") / 65535.0
        assert img.max() + glare.max() < 1.0  # nothing saturates
        write_image(lit / f"frame_{k:04d}.png", np.round((img + glare) * 65535).astype(np.uint16))
    rest = tmp_path / "rest.png"
    write_image(rest, np.round(glare * 65535).astype(np.uint16))
    out = tmp_path / "out"
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", str(PIXEL_MM), "--quiet"]
    assert main(["track", str(lit), *lib, "--reference", str(rest), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reference"]["frames"] == [str(rest)]
    assert summary["reference"]["light_max"][0] == pytest.approx(glare.max(), abs=2e-3)
    rows = list(csv.DictReader((out / "loads.csv").open()))
    assert len(rows) == 6
    for row in rows:
        got = np.array([float(row[k]) for k in ("x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N")])
        want = _nearest(truth[int(row["frame"])], got)
        assert np.all(np.abs(got[:2] - want[:2]) <= 2e-3), (row, want)
        assert np.all(np.abs(got[2:] - want[2:]) <= 2e-3 * want[2]), (row, want)
        assert row["reliable"] == "true"
    blind = track(lit, tiny_library, pixel_mm=PIXEL_MM)
    worst = max(
        np.max(np.abs(row[2:] - _nearest(truth[f.index], row)[2:]))
        for f in blind.frames
        for row in f.params
    )
    assert len(blind.frames) == 3 and worst > 0.1, worst  # 0.13 N, the tangential 0.3 read 0.43


def _nearest(truth, row) -> np.ndarray:
    t = np.asarray(truth, float)
    return t[int(np.argmin(np.hypot(*(t[:, :2] - row[:2]).T)))]


def test_a_rest_frame_of_another_size_or_unreadable_is_one_line(tiny_library, tmp_path, capsys):
    folder = tmp_path / "frames"
    library_frames(tiny_library, [_moving(0)], folder, pixels=PX, pixel_mm=PIXEL_MM)
    small = tmp_path / "small.png"
    write_image(small, np.zeros((PX, PX - 2), np.uint8))
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a png")
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", "0.25"]
    for rest, words in (
        (small, ["--reference", "small.png", f"{PX} x {PX - 2}", f"{PX} x {PX} px"]),
        (broken, ["--reference", "broken.png"]),
        (tmp_path / "missing.png", ["--reference", "missing.png", "does not exist"]),
    ):
        out = tmp_path / "out"
        code = main(["track", str(folder), *lib, "--reference", str(rest), "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2
        assert len(err) == 1 and all(w in err[0] for w in words), err
        assert not out.exists()


@pytest.mark.slow
def test_a_phase_stream_is_tracked_six_steps_a_state(tiny_library, tmp_path):
    """Six phase-stepped 16-bit frames per load state, in a folder: each state is solved
    as one (positions to 2e-3 mm, loads to 2e-3 of Fz, the ids kept); three steps left at
    the end make no state and are reported, not solved."""
    folder = tmp_path / "frames"
    truth = [_moving(k) for k in range(3)]
    n = library_frames(
        tiny_library, truth, folder, pixels=PX, pixel_mm=PIXEL_MM, method="phase", bit_depth=16
    )
    assert n == 3 and len(list(folder.glob("*.png"))) == 18
    for k in (1, 2, 3):  # a fourth state cut short
        (folder / f"frame_0003_step{k}.png").write_bytes(
            (folder / f"frame_0002_step{k}.png").read_bytes()
        )
    out = tmp_path / "out"
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", str(PIXEL_MM), "--quiet"]
    assert main(["track", str(folder), *lib, "--method", "phase", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["frames_read"], summary["frames_solved"]) == (21, 3)
    assert summary["method"] == "phase" and summary["frames_per_state"] == 6
    assert any("last 3 frame(s)" in w for w in summary["warnings"])
    rows = list(csv.DictReader((out / "loads.csv").open()))
    assert [int(r["frame"]) for r in rows] == [0, 0, 1, 1, 2, 2]
    ids = {}  # each contact (its truth row's place in the list) keeps one id
    for row in rows:
        got = np.array([float(row[k]) for k in ("x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N")])
        t = np.asarray(truth[int(row["frame"])], float)
        j = int(np.argmin(np.hypot(*(t[:, :2] - got[:2]).T)))
        assert np.all(np.abs(got[:2] - t[j, :2]) <= 2e-3), (row, t[j])
        assert np.all(np.abs(got[2:] - t[j, 2:]) <= 2e-3 * t[j, 2]), (row, t[j])
        assert ids.setdefault(j, row["id"]) == row["id"], (row, ids)
    assert len(set(ids.values())) == 2
    two = track(folder, tiny_library, pixel_mm=PIXEL_MM, method="phase", max_frames=2)
    assert [f.index for f in two.frames] == [0, 1] and two.summary["frames_read"] == 12
    assert not any("no whole six-step" in w for w in two.summary["warnings"])


def test_a_phase_stream_from_a_camera_or_with_a_rest_but_not_six_steps_is_one_line(
    tiny_library, tmp_path, capsys
):
    folder = tmp_path / "frames"
    library_frames(tiny_library, [_moving(0)], folder, pixels=PX, pixel_mm=PIXEL_MM)
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", "0.25", "--method", "phase"]
    rest = folder / "frame_0000.png"
    for args, words in (
        (["camera:0"], ["--method phase", "camera:0", "folder or a video"]),
        (["CAMERA:1"], ["--method phase", "CAMERA:1", "folder or a video"]),
        ([str(folder), "--reference", str(rest)], ["--reference", "--method phase", "got 1"]),
    ):
        out = tmp_path / "out"
        assert main(["track", *args, *lib, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and all(w in err[0] for w in words), err
        assert not out.exists()
    with pytest.raises(
        ConfigError, match="--method 'dark' is not allowed; give rgb, mono or phase"
    ):
        track(folder, tiny_library, pixel_mm=PIXEL_MM, method="dark")


#: A green LED seen by a colour camera: each channel's share of the light (a Bayer
#: sensor's green filter passes it, its red and blue ones a little).
GREEN_LED = np.array([0.15, 1.0, 0.3])


def _colour_camera(grey: np.ndarray, rng) -> np.ndarray:
    """A grey frame (linear 0-1) as a colour camera under green light records it: each
    channel its share of it plus its own noise (sd 2e-3), 16-bit."""
    rgb = grey[..., None] * GREEN_LED + rng.normal(0.0, 2e-3, (*grey.shape, 3))
    return np.round(np.clip(rgb, 0.0, 1.0) * 65535).astype(np.uint16)


@pytest.mark.slow
@pytest.mark.parametrize("rest_light", ["flat", "glare"])
def test_a_colour_camera_s_mono_stream_reads_one_channel_at_rest_and_loaded(
    tiny_library, tmp_path, rest_light
):
    """A mono stream from a colour camera in green light that starts at rest: the rest
    frame and the stream's first frame carry only the rest light (an even 2 %, whose
    channels are each their own noise; or the glare) and the noise. Both are read in the
    channel that carries the light (green), said once and held for the whole stream; the
    contacts of the later frames come back within three stated sd, 5 um and 0.5 % of Fz
    (the noise's share: up to 2.3 um)."""
    truth = [[], _moving(0), _moving(1)]
    clean = tmp_path / "clean"
    library_frames(tiny_library, truth, clean, pixels=PX, pixel_mm=PIXEL_MM, bit_depth=16)
    glare = _glare((PX, PX)) if rest_light == "glare" else np.full((PX, PX), 0.02)
    rng = np.random.default_rng(7)
    lit = tmp_path / "lit"
    lit.mkdir()
    for k in range(len(truth)):
        img = read_pixels(clean / f"frame_{k:04d}.png") / 65535.0
        write_image(lit / f"frame_{k:04d}.tif", _colour_camera(img + glare, rng))
    rest = tmp_path / "rest.tif"
    write_image(rest, _colour_camera(glare, rng))
    out = tmp_path / "out"
    lib = ["--library", str(tiny_library.folder), "--pixel-mm", str(PIXEL_MM), "--quiet"]
    args = ["track", str(lit), *lib, "--method", "mono", "--reference", str(rest)]
    assert main([*args, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames_solved"] == 3
    assert sum("green channel" in w for w in summary["warnings"]) == 1, summary["warnings"]
    rows = list(csv.DictReader((out / "loads.csv").open()))
    assert sorted({int(r["frame"]) for r in rows}) == [1, 2]
    for row in rows:
        got = np.array([float(row[k]) for k in ("x_mm", "y_mm", "Fz_N", "Fx_N", "Fy_N")])
        sd = np.array([float(row[k]) for k in ("sx_mm", "sy_mm", "sFz_N", "sFx_N", "sFy_N")])
        want = _nearest(truth[int(row["frame"])], got)
        assert np.all(np.abs(got - want) <= 3 * sd), (row, want)
        assert np.all(np.abs(got[:2] - want[:2]) <= 5e-3), (row, want)
        assert np.all(np.abs(got[2:] - want[2:]) <= 5e-3 * want[2]), (row, want)
        assert row["reliable"] == "true"


def test_a_rest_frame_s_saturated_pixels_are_left_out_where_its_light_is_not_known(tmp_path):
    """A rest frame with a glare spot past full scale: the light about the spot is not
    known (clipped, then smoothed into its neighbours), so the pixels within two map
    cells of a saturated one are marked unknown; beyond them the light is the one an
    unclipped frame gives (the same smoothing) to 2e-3 of full scale."""
    shape = (96, 128)
    r, c = np.mgrid[: shape[0], : shape[1]]
    spot = 3.0 * np.exp(-((r - 30.0) ** 2 + (c - 90.0) ** 2) / (2 * 3.0**2))
    true = _glare(shape) + spot
    path = tmp_path / "rest.png"
    write_image(path, np.round(np.clip(true, 0.0, 1.0) * 65535).astype(np.uint16))
    light, unknown = fringekit.tracking.RestFrames.read([path]).light(shape, "mono", "CIE1931")
    sat = (true >= 1.0).ravel()
    assert sat.sum() > 10 and np.all(unknown[sat])
    reach = 2 * 2 + 1  # two 2-px map cells and the saturated pixel's own ring
    assert reach**2 < unknown.sum() < (2 * reach + 1) ** 2 + sat.sum() * 4
    err = np.abs(light[:, 0] - fine_map(coarse_map(true), shape).ravel())
    assert np.max(err[~unknown]) < 2e-3, np.max(err[~unknown])
    assert np.max(err[unknown]) > 0.1  # the clipped light, where it is left out


def test_a_stream_s_channel_is_decided_by_its_first_strong_frame_and_said_once():
    """At rest with the red channel's black level highest, the brightest channel is red;
    a light touch (its pattern 0.1 of full scale, the faint channels mostly noise, which
    the channels' agreement used to refuse as white light) is read there too; the first
    strong frame decides green once and for all, says the earlier frames were read in
    red, and marks the switch (the stream's noise is then measured again). White light
    is refused at its first strong frame."""
    from fringekit.errors import InputError
    from fringekit.tracking.channel import MonoChannel

    rng = np.random.default_rng(3)
    shape = (48, 48)
    black = np.array([0.03, 0.01, 0.01])
    r, c = np.mgrid[: shape[0], : shape[1]]
    bump = np.exp(-((r - 24.0) ** 2 + (c - 20.0) ** 2) / (2 * 4.0**2))
    fringes = np.sin(np.linspace(0, 9, shape[1]))[None, :] ** 2 * np.ones((shape[0], 1))

    def frame(grey):
        return black + grey[..., None] * GREEN_LED + rng.normal(0, 2e-3, (*shape, 3))

    pick = MonoChannel()
    assert pick(frame(np.zeros(shape)), "rest") == 0
    assert pick(frame(0.1 * bump), "touch") == 0 and not pick.decided
    assert pick(frame(fringes), "loaded") == 1 and pick.decided and pick.switched
    assert "green channel; the frames before it in their brightest, red" in pick.note
    assert pick(frame(0.1 * bump), "touch again") == 1
    lam = np.array([620.0, 550.0, 460.0])
    order = np.linspace(0, 4, shape[1])[None, :, None] * np.ones((shape[0], 1, 1))
    white = np.sin(np.pi * order * 550 / lam) ** 2
    with pytest.raises(InputError, match="--method mono: white is a colour image whose"):
        MonoChannel()(white, "white")
