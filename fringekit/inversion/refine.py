"""``invert --refine fem``: the superposition error removed by defect correction.

The library's image of several indenters is a superposition of single-indenter fields of
a half model; the sensor's is one full-model state of all of them. After the library fit,
each round

1. solves the full FEM of every fitted indenter together (the library's sensor config,
   full model, the loads applied as the library's chain applies them: the normal load in
   steps of about 1.4x, then the tangential load in steps of at most 0.2 of it; a
   calibrated sensor's modulus and fringe value),
2. renders it on the image's pixels through the method's optics,
3. takes the difference between that image and the library's synthesis at the same loads
   as a fixed correction added to the library's model (:attr:`ImageModel.correction`),
4. fits again from the answer before,

until no position or load moves by more than its stated 1-sigma (at most
:data:`MAX_ROUNDS` rounds). At the fixed point the corrected model at the answer is the
full-FEM image of the answer (the correction cancels the library's own image there), so
the answer is the full FEM model's, not the superposition's: defect correction (H. J.
Stetter, "The defect correction principle and discretization methods", Numer. Math. 29,
1978). Its cost is one FEM solve per round.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import replace

import numpy as np
from scipy import ndimage

from fringekit.inversion.fit import EXACT_MM, InvertResult, refit
from fringekit.inversion.model import ImageModel, unpack
from fringekit.optics import PixelGrid
from fringekit.prediction.pipeline import solve_config
from fringekit.prediction.render import path_quaternions

__all__ = ["MAX_ROUNDS", "fem_config", "fem_image", "refine_fem"]

#: Refinement rounds (FEM solves) at most.
MAX_ROUNDS = 4
#: The normal-load fractions of the load path (steps of about 1.4x, as the library's).
NORMAL_STEPS = (0.125, 0.18, 0.25, 0.35, 0.5, 0.7, 1.0)
#: The largest step of the tangential ratio along the path.
SHEAR_STEP = 0.2


def fem_config(cfg: dict, params: np.ndarray, diameters, friction: str) -> dict:
    """The full-model config of indenters (n, 5) x, y (mm, the sheet's axes), Fz, Fx, Fy
    (N) with sphere diameters (m) on the sensor ``cfg``, loaded along the library's path
    under ``friction``.

    Examples
    --------
    >>> from fringekit.config.files import load_config
    >>> import fringekit
    >>> cfg = fringekit.Config.builtin("small").data
    >>> c = fem_config(cfg, np.array([[1.0, 0.0, 4.0, 1.0, 0.0]]), [3.5e-3], "stick")
    >>> c["indenter"][0]["load_N"][-1], c["indenter"][0]["shear_N"][-1], c["mesh"]["symmetry"]
    (4.0, [1.0, 0.0], 'full')
    """
    out = copy.deepcopy(cfg)
    out["contact"]["friction"] = friction
    out["mesh"]["symmetry"] = "full"
    q = np.asarray(params, float).reshape(-1, 5)
    ratio = max([math.hypot(v[3], v[4]) / v[2] for v in q if v[2] > 0] + [0.0])
    n_shear = max(1, math.ceil(ratio / SHEAR_STEP - 1e-9))
    normal = list(NORMAL_STEPS) + [1.0] * n_shear
    shear = [0.0] * len(NORMAL_STEPS) + [(k + 1) / n_shear for k in range(n_shear)]
    proto = out["indenter"][0]
    out["indenter"] = [
        dict(
            copy.deepcopy(proto),
            x_mm=float(v[0]),
            y_mm=float(v[1]),
            diameter_mm=float(d) * 1e3,
            load_N=[f * float(v[2]) for f in normal],
            shear_N=[[t * float(v[3]), t * float(v[4])] for t in shear],
        )
        for v, d in zip(q, diameters, strict=True)
    ]
    return out


def _turned(x: np.ndarray, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (x, y) turned by ``t`` (rad, counter-clockwise) about the origin."""
    c, s = math.cos(t), math.sin(t)
    return c * x - s * y, s * x + c * y


def _sheet_grid(model: ImageModel, rotation_deg: float) -> tuple[PixelGrid, np.ndarray]:
    """The grid the FEM is rendered on (the model's, or for a turned image one in the
    sheet's axes covering it) and the model's pixels in its (row, col) (2, P)."""
    if rotation_deg == 0.0:
        return model.grid, None
    sx, sy = _turned(*model.xy.T, -math.radians(rotation_deg))
    p = model.grid.pixel_size
    lo, hi = np.array([sx.min(), sy.min()]) - 2 * p, np.array([sx.max(), sy.max()]) + 2 * p
    n = np.ceil((hi - lo) / p).astype(int) + 1
    grid = PixelGrid((int(n[1]), int(n[0])), p, tuple((lo + hi) / 2))
    rows, cols = grid.xy_to_pixel(sx, sy)
    return grid, np.array([rows, cols])


def _residual_on(model: ImageModel, grid: PixelGrid, where, turn: float):
    """The model's residual retarder (:attr:`ImageModel.residual_ab`, the image's axes)
    on the render ``grid``'s pixels (P_g, 2) (its own pixels when ``where`` is None; else
    the grid lies in the sheet's axes, turned by ``turn`` rad, and each of its pixels
    takes the residual where it lies in the image, bilinear, the edge's beyond); None
    without a residual."""
    if model.residual_ab is None:
        return None
    if where is None:
        return np.asarray(model.residual_ab, float)
    at = np.array(model.grid.xy_to_pixel(*_turned(*grid.xy().T, turn)))
    cube = np.asarray(model.residual_ab, float).reshape(*model.grid.shape, 2)
    return np.stack(
        [ndimage.map_coordinates(cube[..., k], at, order=1, mode="nearest") for k in (0, 1)], -1
    )


def fem_image(model: ImageModel, cfg: dict, params, diameters, friction, optics, sensor=None):
    """(intensities (P, C) before gain and offset, valid (P,)) of the full-FEM state of
    ``params`` (n, 5) (the image's axes) on ``model``'s pixels through its optics;
    ``sensor``: the calibrated sensor (its rotation turns the indenters into the sheet's
    axes, its scales set the sheet's modulus and fringe value), ``optics`` the sensor's
    optics (fringe value scaled). The FEM's stresses are taken in the image's axes (a
    phase-stepped polariscope turns with the camera), and the model's residual retarder
    (a rest's or a sensor file's) is frozen into the sheet as the library's model holds
    it. Invalid pixels (contact zones, off the sheet) are 0.

    Raises
    ------
    RuntimeError
        When the solver does not reach the loads (its message).
    """
    rot = 0.0 if sensor is None else sensor.rotation_deg
    turn = math.radians(rot)
    sheet = np.asarray(params, float).reshape(-1, 5)
    fcfg = copy.deepcopy(cfg)
    if sensor is not None:
        sheet = sensor.to_sheet(sheet)
        fcfg["sheet"]["E_MPa"] *= sensor.modulus_scale
        fcfg["optics"]["f_sigma_N_per_m"] *= sensor.fringe_scale
    _, sols, _, failure = solve_config(fem_config(fcfg, sheet, diameters, friction), progress=False)
    if failure:
        raise RuntimeError(failure)
    grid, where = _sheet_grid(model, rot)
    frozen = _residual_on(model, grid, where, turn)
    q, valid = path_quaternions(
        sols[-1], fcfg, replace(optics, grid=grid), model.wavelengths, frozen=frozen, turn=turn
    )
    img = np.where(valid[:, None], model.polariscope(q), 0.0)
    if where is None:
        return img, valid
    rows, cols = grid.shape
    cube = img.reshape(rows, cols, -1)
    out = np.stack(
        [ndimage.map_coordinates(cube[..., c], where, order=1) for c in range(cube.shape[-1])], -1
    )
    ok = ndimage.map_coordinates(valid.reshape(rows, cols).astype(float), where, order=1) > 0.999
    return np.where(ok[:, None], out, 0.0), ok


def refine_fem(model, res: InvertResult, cfg, friction, optics, *, sensor=None, say=print):
    """Defect-correction rounds after a library fit (module docstring): (the refined
    result, a report: rounds with their FEM seconds and largest change in 1-sigma,
    ``converged``)."""
    report = {"rounds": [], "converged": False}
    for k in range(MAX_ROUNDS):
        t0 = time.perf_counter()
        p, diam = res.params, list(res.diameters)
        fem, valid = fem_image(model, cfg, p, diam, friction, optics, sensor)
        plain = replace(model, correction=None, exact=EXACT_MM * 1e-3)  # as refit's model
        lib_img, _ = plain.linear(unpack(p.ravel(), diam))
        corr = np.where(valid[:, None], fem - lib_img, 0.0)
        t_fem = time.perf_counter() - t0
        new = refit(replace(model, correction=corr), p.ravel(), diam, res.noise)
        change = np.abs(new.params - p) / np.where(new.sd > 0, new.sd, np.inf)
        worst = float(np.nanmax(change)) if change.size else 0.0
        report["rounds"].append({"round": k + 1, "fem_s": t_fem, "max_change_sd": worst})
        say(f"invert: refine round {k + 1}: FEM {t_fem:.0f} s, largest change {worst:.2f} sd")
        res = new
        if worst < 1.0:
            report["converged"] = True
            break
    return res, report
