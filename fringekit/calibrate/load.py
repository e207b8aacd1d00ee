"""``fringekit calibrate``: load-to-fringe relations on disk.

``run_calibrate`` solves one continuation run over the config's load path (through the
solution cache), renders the monochrome fringe-order map of every state, extracts the
features of :func:`analysis.fringe_features` about the first indenter and fits them against the
load. It writes ``calibration.json`` (the fits, the per-state features, the effective
config), ``features.csv`` and ``calibration.png``.

The inverse (``estimate``) and the disc fit are in :mod:`fringekit.calibrate.estimate`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from fringekit.analysis import (
    calibrate_from_maps,
    fringe_features,
    radial_profile,
    save_calibration,
)
from fringekit.config.files import ConfigError, effective_config, normal_path, to_toml
from fringekit.config.inputs import optics_setup
from fringekit.output.figures import calibration_figure
from fringekit.output.folders import claim_output
from fringekit.prediction.pipeline import PredictError, solve_config
from fringekit.prediction.render import fringe_order_map

__all__ = ["default_calibration_config", "run_calibrate"]


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
    inputs=(),
) -> dict:
    """Calibrate features against the load along ``cfg``'s load path; see module doc.
    ``inputs``: the files the config came from (never inside ``out``)."""
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
    with claim_output(out, command="calibrate", inputs=inputs) as work:
        cal, n_states = _calibrate(cfg, work, optics, cache_dir, use_cache, progress, say)
    if cal["error"]:
        raise PredictError(
            f"{cal['error']}; calibrated on the {n_states} converged states in {out}"
        )
    return cal


def _calibrate(cfg, out: Path, optics, cache_dir, use_cache, progress, say) -> tuple[dict, int]:
    """Solve, render and fit into the empty folder ``out``: the calibration, the states."""
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
    # six significant digits (fringekit.output.numbers.SIGNIFICANT_DIGITS); nan where undefined
    np.savetxt(
        out / "features.csv",
        np.array(rows, float),
        delimiter=",",
        header=head,
        comments="",
        fmt="%.6g",
    )
    calibration_figure(out / "calibration.png", cal, profiles)
    return cal, len(sols)
