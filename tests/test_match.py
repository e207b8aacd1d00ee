"""Candidates moved onto the indenters' axes by matching the library's one-indenter
images (fringekit.inversion.match): the masked correlation against its definition, and
candidates off their contacts brought back."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from library_fixtures import TINY, four_heads_frame, sensor_config

from fringekit.config.inputs import optics_setup
from fringekit.inversion.detect import detect, noise_sd
from fringekit.inversion.fit import subsample
from fringekit.inversion.match import MIN_OVERLAP, masked_ncc, match_candidates
from fringekit.inversion.model import ImageModel
from fringekit.library.store import LoadedIndenter
from fringekit.optics import PixelGrid


def test_the_masked_correlation_is_pearson_s_over_the_valid_pixels():
    rng = np.random.default_rng(3)
    img = rng.normal(size=(24, 30))
    valid = rng.random((24, 30)) > 0.3
    valid[:, :4] = False  # a border strip without data
    t = rng.normal(size=(5, 7))
    c, n = masked_ncc(img, valid, t)
    for i, j in [(12, 15), (2, 3), (20, 28), (0, 10), (6, 6)]:
        win = np.zeros((24 + 4, 30 + 6), bool)  # the template's footprint, padded
        vals = np.zeros_like(win, float)
        win[2:-2, 3:-3], vals[2:-2, 3:-3] = valid, img
        w, v = win[i : i + 5, j : j + 7], vals[i : i + 5, j : j + 7]
        if w.sum() < MIN_OVERLAP * t.size:
            assert np.isnan(c[i, j]) and n[i, j] == 0
            continue
        assert n[i, j] == w.sum()
        assert abs(c[i, j] - np.corrcoef(v[w], t[w])[0, 1]) < 1e-10


def _image(lib, inds, grid):
    opt = optics_setup(sensor_config(**TINY))
    n = grid.n_pixels
    blank = ImageModel.build(lib, grid, "mono", np.zeros((n, 1)), np.ones(n, bool), opt)
    img, _ = blank.linear(inds)
    return replace(blank, measured=0.8 * img + 0.02)


def test_candidates_off_their_contacts_move_onto_the_axes(tiny_library):
    """The detections the tracker's merge test starts from: a 3 N contact split 1.7 mm
    either side (and a sheared 2.5 N one found 1.1 mm off) become two candidates on the
    axes, to a pixel; with the one-indenter templates the sheared one is not pulled
    along its shear."""
    inds = [
        LoadedIndenter(-3.0e-3, 3.0e-3, 3.5e-3, 0.3, 0.0, 2.5),
        LoadedIndenter(3.0e-3, -3.0e-3, 3.5e-3, 0.0, 0.0, 3.0),
    ]
    model = _image(tiny_library, inds, PixelGrid((64, 64), 0.25e-3))
    pos = np.array([[-3.8, 3.8], [2.07, -4.55], [4.0, -1.39]])
    got = match_candidates(model, pos)
    assert got.shape == (2, 2), got
    truth = np.array([[-3.0, 3.0], [3.0, -3.0]])
    d = np.hypot(*(got[:, None] - truth[None]).transpose(2, 0, 1)).min(axis=1)
    assert np.all(d <= 0.25 * 1.5), (got, d)


def test_a_candidate_at_the_border_keeps_to_its_contact(tiny_library):
    """A contact 1 mm inside the image's edge: its templates reach out of the image, and
    are judged on the half they have; a match of less at the corner does not win."""
    ind = [LoadedIndenter(-7.0e-3, 1.0e-3, 3.5e-3, 0.0, 0.5, 3.0)]
    model = _image(tiny_library, ind, PixelGrid((64, 64), 0.25e-3))
    got = match_candidates(model, np.array([[-6.0, 2.5]]))
    assert np.hypot(got[0, 0] + 7.0, got[0, 1] - 1.0) <= 0.4, got


@pytest.mark.slow
def test_the_track_bench_s_frame_120_candidates(test_library):
    """Four heads, two of them 4.4 mm apart (the track bench's frame 120, 128 px over
    16 mm, 8-bit with noise): the gradient energy puts every candidate 1.7-2.3 mm off an
    axis and none on the fourth head; matched, three candidates are on three heads (the
    fourth is for the fit's residual to find)."""
    model, heads = four_heads_frame(test_library)
    fine = subsample(model, 2)
    noise = noise_sd(fine)
    axes = np.array([[h.x, h.y] for h in heads]) * 1e3

    def off(c):
        return np.hypot(*(c[:, None] - axes[None]).transpose(2, 0, 1)).min(axis=1)

    energy = detect(fine, noise)
    assert np.all(off(energy) > 1.5), energy
    matched = match_candidates(fine, energy)
    assert len(matched) == 3 and np.all(off(matched) < 0.15), matched
