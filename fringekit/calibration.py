"""``fringekit calibrate`` and ``fringekit estimate``: load-to-fringe relations on disk.

``run_calibrate`` solves one continuation run over the config's load path (through the
solution cache), renders the monochrome fringe-order map of every state, extracts the
features of :func:`analysis.fringe_features` about the first indenter and fits them against the
load. It writes ``calibration.json`` (the fits, the per-state features, the effective
config), ``features.csv`` and ``calibration.png``.

``run_estimate`` computes the same features from a fringe-order map (``fringekit
analyze`` or ``predict`` output) and inverts the calibration.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from analysis import (
    calibrate_from_maps,
    estimate_load,
    fringe_features,
    load_calibration,
    radial_profile,
    save_calibration,
)

from .analyze import read_order_map
from .config import ConfigError, effective_config, normal_path, to_toml
from .disc import fringe_value_from_disc
from .figures import calibration_figure
from .inputs import optics_setup
from .pipeline import PredictError, solve_config
from .render import fringe_order_map

__all__ = ["default_calibration_config", "run_calibrate", "run_estimate", "run_disc"]


def default_calibration_config() -> dict:
    """The reference case over the load path 1, 2, ..., 10 N (seed paper's range)."""
    return effective_config(
        {"case": "calibration", "indenter": [{"load_N": [float(k) for k in range(1, 11)]}]}
    )


def run_calibrate(
    cfg: dict,
    out: str | os.PathLike,
    *,
    cache_dir=None,
    use_cache: bool = True,
    progress: bool = True,
    echo=print,
) -> dict:
    """Calibrate features against the load along ``cfg``'s load path; see module doc."""
    say = echo if progress else (lambda s: None)
    ind0 = cfg["indenter"][0]
    path = normal_path(ind0)
    if len(path) < 3 or len(set(path)) < 3:
        raise ConfigError(
            f"calibrate needs a load path with at least 3 different loads on indenter[0]; got "
            f"{path!r} (e.g. --set 'indenter.load_N=[1, 2, 4, 6, 8, 10]')"
        )
    optics = optics_setup(cfg)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.toml").write_text(to_toml(cfg))
    t0 = time.perf_counter()
    mesh, sols, stats, failure = solve_config(
        cfg, cache_dir=cache_dir, use_cache=use_cache, progress=progress
    )
    t_solve = time.perf_counter() - t0
    say(f"solve: {len(sols)} load state(s) in {t_solve:.1f} s")
    if len(sols) < 3:
        raise PredictError(f"{failure}; only {len(sols)} state(s) converged, calibration needs 3")
    feats, profiles, loads, shears = [], [], [], []
    pixel = optics.grid.pixel_size
    for sol in tqdm(sols, desc="fringe maps", unit="state", disable=not progress):
        order, grid, centres = fringe_order_map(sol, cfg, optics)
        feats.append(fringe_features(order, pixel, tuple(centres[0])))
        profiles.append(radial_profile(order, pixel, tuple(centres[0])))
        f = sol.indenters[0].force
        loads.append(float(-f[2]))
        shears.append([float(f[0]), float(f[1])])
    cal = calibrate_from_maps(loads, shears, feats)
    cal.update(
        pixel_size_mm=pixel * 1e3,
        wavelength_nm=cfg["optics"]["wavelength_nm"],
        f_sigma_N_per_m=cfg["optics"]["f_sigma_N_per_m"],
        config=cfg,
        status="failed" if failure else "ok",
        error=failure,
        time_solve_s=t_solve,
        time_total_s=time.perf_counter() - t0,
    )
    save_calibration(cal, out / "calibration.json")
    names = sorted(feats[0])
    rows = [[loads[k], *shears[k], *(feats[k][n] for n in names)] for k in range(len(feats))]
    head = ",".join(["load_N", "shear_x_N", "shear_y_N", *names])
    np.savetxt(out / "features.csv", np.array(rows, float), delimiter=",", header=head, comments="")
    calibration_figure(out / "calibration.png", cal, profiles)
    if failure:
        raise PredictError(f"{failure}; calibrated on the {len(sols)} converged states in {out}")
    return cal


def _read_map(maps, pixel_mm, centre):
    m = read_order_map(maps, pixel_size=pixel_mm * 1e-3 if pixel_mm else None)
    rc = centre if centre is not None else m.indenter_rc
    if rc is None:
        raise ValueError(f"{m.path} stores no indenter position; give --centre ROW COL (pixels)")
    rows, cols = m.order.shape
    if not (0 <= rc[0] <= rows - 1 and 0 <= rc[1] <= cols - 1):
        raise ValueError(
            f"--centre {rc[0]:g} {rc[1]:g} is outside the map; allowed rows 0..{rows - 1}, "
            f"columns 0..{cols - 1}"
        )
    return m.path, m.order, m.pixel_size, (float(rc[0]), float(rc[1]))


def run_estimate(maps, calibration, *, pixel_mm=None, centre=None, out=None) -> dict:
    """Normal load (and shear) from a fringe-order map and a calibration file."""
    cal = load_calibration(calibration)
    f, order, px, rc = _read_map(maps, pixel_mm, centre)
    feats = fringe_features(order, px, rc)
    est = estimate_load(cal, feats)
    est.update(maps=str(f), calibration=str(calibration), features=feats, centre_rc=list(rc))
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "estimate.json").write_text(json.dumps(est, indent=2, default=float))
    return est


def run_disc(maps, *, load_N, diameter_mm, thickness_mm, pixel_mm=None, centre=None) -> dict:
    """Fringe value from a diametral-disc fringe-order map at a known load."""
    m = read_order_map(maps, pixel_size=pixel_mm * 1e-3 if pixel_mm else None)
    f, order, px = m.path, m.order, m.pixel_size
    rc = centre if centre is not None else ((order.shape[0] - 1) / 2, (order.shape[1] - 1) / 2)
    res = fringe_value_from_disc(
        order, px, rc, load_N=load_N, diameter=diameter_mm * 1e-3, thickness=thickness_mm * 1e-3
    )
    return {**res, "maps": str(f), "centre_rc": list(rc)}
