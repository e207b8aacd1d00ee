"""Colour pixels clipped at black: a dark-field colour outside the camera's gamut has a
channel below zero in the model, which the camera stores as 0. ``invert`` and a stream's
frames compare the model with such a channel as the camera clips it (a censored
observation); ``sensor calibrate`` leaves the pixel out of its known-load frames; a rest
frame, whose light is subtracted, keeps it."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
from library_fixtures import TINY, sensor_config

from fringekit.analysis import read_pixels
from fringekit.inversion.model import unpack
from fringekit.inversion.quick import near_residual
from fringekit.inversion.read import censored_channels, read_measurement
from fringekit.inversion.rest import frame_linear
from fringekit.optics import write_image
from fringekit.sensor.frames import read_frames, read_known
from fringekit.tracking import library_frames
from fringekit.tracking.synthetic import blank_model
from fringekit.tracking.warm import ChordFit

PX, PIXEL_MM, NOISE = 64, 0.25, 0.005
TRUTH = [(-4.0, 3.5, 2.5, 0.3, 0.0), (3.0, -4.0, 3.0, 0.0, 0.3)]  # x, y mm, Fz, Fx, Fy N


def test_a_colour_channel_at_zero_is_censored_a_grey_zero_is_measured(tmp_path):
    rgb = np.full((4, 5, 3), 120, np.uint8)
    rgb[1, 2, 0] = 0  # red clipped at black
    rgb[3, 4, 2] = 0  # blue clipped at black
    write_image(tmp_path / "colour.png", rgb)
    m = read_measurement([tmp_path / "colour.png"], "rgb", "CIE1931")
    assert m.usable.all()
    assert np.argwhere(m.censored).tolist() == [[1 * 5 + 2, 0], [3 * 5 + 4, 2]]
    grey = np.full((4, 5), 120, np.uint8)
    grey[1, 2] = 0  # a dark fringe's minimum: the model's own 0
    write_image(tmp_path / "grey.png", grey)
    m = read_measurement([tmp_path / "grey.png"], "mono", "CIE1931")
    assert m.usable.all() and m.censored is None


def test_sensor_calibrate_leaves_clipped_colour_pixels_out_of_its_known_frames(tmp_path):
    """Each known-load frame leaves its clipped pixel out of the fit; one frame averaged
    from both files leaves out a pixel clipped in either (their mean, 60, is not a
    measurement); the same files read as a rest frame keep both."""
    a = np.full((4, 5, 3), 120, np.uint8)
    b = a.copy()
    a[1, 2, 0] = 0  # red clipped in the first file only
    b[3, 4, 2] = 0  # blue clipped in the second only
    write_image(tmp_path / "a.png", a)
    write_image(tmp_path / "b.png", b)
    (tmp_path / "KNOWN.csv").write_text(
        "image,x_mm,y_mm,Fx_N,Fy_N,Fz_N\na.png,0,0,0,0,2\nb.png,0,0,0,0,2\n"
    )
    lib = SimpleNamespace(diameters_mm=[3.5], max_load_N=8.0, max_ratio=0.4)
    known = read_known(tmp_path / "KNOWN.csv", "rgb", lib, (4, 5))
    assert [np.flatnonzero(~k.usable).tolist() for k in known] == [[1 * 5 + 2], [3 * 5 + 4]]
    both = [tmp_path / "a.png", tmp_path / "b.png"]
    _, bad = read_frames(both, "rgb", "--known image", fitted=True)
    assert np.flatnonzero(bad).tolist() == [1 * 5 + 2, 3 * 5 + 4]
    _, bad = read_frames(both, "rgb", "--reference")
    assert not bad.any()


def test_a_black_rest_frame_stays_known():
    black = np.zeros((4, 5, 3), np.uint8)  # a colour sensor at rest in the dark,
    black[..., 1:] = (8, 12)  # its red at black
    _, usable, _, _ = frame_linear(black, "rgb", "CIE1931", "rest")
    assert usable.all()
    assert censored_channels(black, "rgb")[:, 0].all()  # (a fitted frame's red is censored)


def test_the_true_loads_explain_a_clipped_colour_frame_to_its_noise(tiny_library, tmp_path):
    """An 8-bit colour frame of two contacts (64 x 64 px), 77 of its pixels with red or
    blue at 0 where the model is below zero: at the true loads the residual near each
    contact is within 1.25 times the noise's share with those channels censored, and
    above it (1.3 and 1.55 times) when they are taken as measured zeros, so a quick start
    that found these loads is kept."""
    library_frames(
        tiny_library, [TRUTH], tmp_path, pixels=PX, pixel_mm=PIXEL_MM, method="rgb", noise=NOISE
    )
    img = read_pixels(tmp_path / "frame_0000.png")
    blank = blank_model(tiny_library, sensor_config(**TINY), (PX, PX), PIXEL_MM, "rgb")
    p = np.array(TRUTH, float).ravel()
    diam = [tiny_library.diameters_mm[0] * 1e-3] * len(TRUTH)
    m, usable, nodata, _ = frame_linear(img, "rgb", "CIE1931", "frame")
    censored = censored_channels(img, "rgb")
    assert 50 < np.count_nonzero(censored.any(axis=1)) < 0.05 * usable.size
    near = []
    for c in (censored, None):
        model = replace(blank, measured=m, usable=usable, nodata=nodata, censored=c)
        fixed = replace(model, keep=model.outside_contacts(unpack(p, diam)))
        r, gains = ChordFit(NOISE).residual(fixed, p, diam)
        near.append(near_residual(fixed, p, r, gains) / (NOISE / float(np.mean(np.abs(gains)))))
    assert np.all(near[0] < 1.25), near
    assert np.all(near[1] > 1.25), near
