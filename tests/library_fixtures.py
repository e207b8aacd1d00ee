"""The coarse test sensor and its library, shared by the library and invert tests.

The sensor of examples/coarse_sensor.toml (a 20 x 20 mm, 3 mm sheet on 4 mm PC with the
small block's coarse mesh sizes); a library of 3 normal loads (2, 2.8, 4 N) x 3 tangential
ratios (0, 0.4, 0.8), built once per session in the test process (about 30 s); and a
tiny library of the same sensor on a coarser mesh for the fast tier.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from fringekit.config.files import apply_overrides, load_config
from fringekit.config.inputs import optics_setup
from fringekit.prediction.render import mono_map

#: The coarse sensor of examples/coarse_sensor.toml (also bench/invert.py's coarse preset).
SENSOR = Path(__file__).resolve().parents[1] / "examples" / "coarse_sensor.toml"
LOADS = (2.0, 2.8, 4.0)
RATIOS = (0.0, 0.4, 0.8)
#: The tiny library of the fast tier: the same sensor on a mesh of 1 mm under the
#: indenter (three elements through the sheet), 48 x 48 px, 2 loads x 2 ratios (about 2 s).
TINY = {"mesh.h_contact_mm": 1.0, "mesh.h_sheet_mm": 3.0, "mesh.h_far_mm": 6.0, "optics.pixels": 48}
TINY_LOADS = (2.0, 4.0)
TINY_RATIOS = (0.0, 0.4)


def sensor_config(**extra) -> dict:
    return apply_overrides(load_config(SENSOR), extra)


def fem_config(indenters: list[dict], **extra) -> dict:
    """The test sensor with these indenters (x_mm, y_mm, load_N, shear_N), full stick."""
    cfg = sensor_config(**extra)
    cfg["contact"]["friction"] = "stick"
    base = copy.deepcopy(cfg["indenter"][0])
    cfg["indenter"] = []
    for d in indenters:
        ind = dict(base, **d)
        ind["load_N"] = list(ind["load_N"])
        cfg["indenter"].append(ind)
    return cfg


def fem_order(cfg: dict, cache_dir):
    """(fringe order map, OpticalMap, the last solution) of a config solved by FEM."""
    from fringekit.prediction.pipeline import solve_config

    _, sols, _, failure = solve_config(cfg, cache_dir=cache_dir, progress=False)
    assert failure is None, failure
    omap, _ = mono_map(sols[-1], cfg, optics_setup(cfg))
    return omap.fringe_order(), omap, sols[-1]


def outside(grid, centres_mm, radius_mm) -> np.ndarray:
    """(rows, cols) pixels farther than radius_mm from every centre."""
    xy = grid.xy().reshape(*grid.shape, 2) * 1e3
    keep = np.ones(grid.shape, bool)
    for x, y in centres_mm:
        keep &= np.hypot(xy[..., 0] - x, xy[..., 1] - y) > radius_mm
    return keep


def four_heads_frame(lib):
    """The track bench's frame 120 on ``lib`` (the coarse sensor's): four 3.5 mm heads,
    two of them 4.4 mm apart, 128 x 128 px over 16 mm, 8-bit with noise 0.005 (seeded):
    (ImageModel with the frame measured, the heads as LoadedIndenters)."""
    from dataclasses import replace

    from fringekit.inversion.model import ImageModel
    from fringekit.library.store import LoadedIndenter
    from fringekit.optics import PixelGrid

    heads = [
        LoadedIndenter(-4.19e-3, 5.5e-3, 3.5e-3, 0.5, 0.0, 2.5),
        LoadedIndenter(-2.2e-3, -1.08e-3, 3.5e-3, 0.0, 0.4, 3.0),
        LoadedIndenter(2.2e-3, -1.22e-3, 3.5e-3, -0.3, 0.0, 2.0),
        LoadedIndenter(5.5e-3, 4.5e-3, 3.5e-3, 0.0, 0.0, 3.0),
    ]
    grid = PixelGrid((128, 128), 0.125e-3)
    n = grid.n_pixels
    opt = optics_setup(sensor_config())
    blank = ImageModel.build(lib, grid, "mono", np.zeros((n, 1)), np.ones(n, bool), opt)
    img, _ = blank.linear(heads)
    noisy = 0.8 * img + 0.02 + np.random.default_rng(120).normal(0.0, 0.005, img.shape)
    return replace(blank, measured=np.round(np.clip(noisy, 0, 1) * 255) / 255), heads


def frozen_stress(model, top_fringe: float = 0.3):
    """A smooth residual (frozen) stress across a 16 x 16 mm frame of ``model`` (an
    :class:`~fringekit.inversion.model.ImageModel`), as a retardation d (P,) (rad, the
    double pass; at most ``top_fringe`` fringes), an axis t (P,) (rad) and the summed
    slab pair (P, 2) the model takes for it (d (cos 2t, sin 2t) / 2k)."""
    xy = model.xy / 8e-3  # -1..1 across the frame
    d = 2 * np.pi * top_fringe * (0.3 + 0.7 * np.exp(-((xy[:, 0] - 0.3) ** 2 + xy[:, 1] ** 2)))
    t = 0.4 + 0.6 * xy[:, 0] - 0.3 * xy[:, 1]
    k = model.law.retardation_per_stress_length(np.array([model.law.wavelength_ref]))[0]
    return d, t, d[:, None] * np.stack([np.cos(2 * t), np.sin(2 * t)], 1) / (2 * k)
