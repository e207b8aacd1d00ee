"""Frames a calibrated sensor would record: the library's image of known loads through the
sensor's sheet, light, camera and geometry (the forward model
:func:`~fringekit.sensor.calibrate.calibrate_sensor` inverts; the test data of the
calibration, and ``bench/sensor.py``'s library-rendered frames).

A frame's stored value in [0, 1] is b + (1 - b) (g L(x) M(x) + R(x)) ** (1 / gamma), with
M the library's linear image (modulus and fringe-value scales applied), L the
illumination, R the rest frame's linear intensity, g the exposure gain and b the black
level (:mod:`fringekit.library.calibrated`): the frame ``predict --library --sensor``
writes (:func:`~fringekit.prediction.from_library.camera_linear`), with the exposure and
noise given here. For the phase method M is the six steps' image with the sensor's
residual retarder in the sheet, and R is none.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fringekit.config.inputs import optics_setup
from fringekit.inversion.model import ImageModel
from fringekit.inversion.read import pixel_grid
from fringekit.library.calibrated import CalibratedSensor
from fringekit.library.store import LoadedIndenter
from fringekit.prediction.from_library import camera_linear, file_values

__all__ = ["image_model", "sensor_frame"]


def image_model(lib, sensor: CalibratedSensor) -> ImageModel:
    """The image model of ``sensor``'s frames: its library (modulus scale), optics (fringe
    value scale), pixel grid and residual retarder (phase), fitted in the image's axes; no
    measured image."""
    cfg = sensor.config
    optics = sensor.optics(optics_setup(cfg))
    rows, cols = sensor.shape
    C = {"rgb": 3, "phase": 6}.get(sensor.method, 1)
    model = ImageModel.build(
        sensor.library(lib),
        pixel_grid(sensor.shape, sensor.pixel_mm, sensor.origin_px),
        sensor.method,
        np.zeros((rows * cols, C)),
        np.ones(rows * cols, bool),
        optics,
        light=cfg["optics"]["light"],
        white_light_wavelengths=cfg["optics"]["white_light_wavelengths"],
    )
    return replace(model, residual_ab=sensor.residual_ab(sensor.shape))


def sensor_frame(
    lib, sensor: CalibratedSensor, contacts, *, gain=0.8, noise=0.0, rng=None, bit_depth=None
):
    """One frame (rows, cols, C) of stored values in [0, 1] (or, at ``bit_depth`` 8 or 16,
    the image file's integers: (rows, cols) grey, (rows, cols, 3) colour).

    Parameters
    ----------
    lib : Library
        The library ``sensor`` was calibrated with.
    sensor : CalibratedSensor
        The sensor (its maps, interpolated to the image, are the truth).
    contacts : sequence of (x_mm, y_mm, Fx_N, Fy_N, Fz_N)
        Loads in the sheet's axes, on spheres of the library's first diameter.
    gain : float
        The exposure gain g.
    noise : float
        Gaussian noise sd added to the stored values (before clipping).
    rng : numpy Generator, optional
    bit_depth : {None, 8, 16}
        None: floats; 8 or 16: uint8 or uint16 values, rounded, for an image file.

    Examples
    --------
    See :func:`~fringekit.sensor.calibrate.calibrate_sensor`.
    """
    d = lib.diameters_mm[0] * 1e-3
    inds = [LoadedIndenter(x * 1e-3, y * 1e-3, d, fx, fy, fz) for x, y, fx, fy, fz in contacts]
    raw = sensor.encode(gain * camera_linear(sensor.config, sensor.library(lib), inds, sensor))
    if noise > 0:
        raw = raw + (rng or np.random.default_rng(0)).normal(0.0, noise, raw.shape)
    raw = np.clip(raw, 0.0, 1.0)
    return raw if bit_depth is None else file_values(raw, bit_depth)
