"""Load-to-fringe calibration and inverse load estimates from fringe-order maps.

The features of a map are :mod:`analysis.features`'s (:func:`fringe_features`).

A calibration (:func:`calibrate_from_maps`) fits, for each feature that grows with the
normal load, ``F = a feature^b`` by least squares in log-log (a power law: Hertz gives
b = 3/2 for order-like features and b = 3 for radii); its uncertainty is the residual
scatter in log F, which :func:`estimate_load` turns into a relative standard uncertainty
of each per-feature estimate, then combines them by inverse-variance weighting (the
features are correlated, so the combined uncertainty is reported as the smallest
per-feature one, not the weighted-mean formula). Where the load path carries shear,
``shear_x = c0 + c1 centroid_x`` (and y) are fitted linearly.

The fringe value from a diametral disc, which needs the disc's stress field, is fitted by
the application layer (:func:`fringekit.calibrate.disc_map.fringe_value_from_disc`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

__all__ = [
    "calibrate_from_maps",
    "estimate_load",
    "save_calibration",
    "load_calibration",
]

#: An estimate needs this many features in the calibrated range (fewer when fewer fits).
MIN_FEATURES = 3
#: Reduced chi-square of the per-feature loads above which the map is refused. Each
#: feature's load counts as known to its calibrated scatter, but never better than
#: CHI2_FLOOR of the load (radii and annuli are quantised by the pixels; an exact
#: synthetic calibration has no scatter at all). Measured on the reference 8 N map
#: (0.078 mm pixels): 0.6 at the right centre, 5.8 with the centre 0.27 mm off (load still
#: right to 0.1 %), 1100 with it 1 mm off and 1.5e4 off the indenter (95, 95 px).
MAX_CHI2 = 25.0
CHI2_FLOOR = 2e-3
#: ... and above which the uncertainty is widened and a warning given.
WARN_CHI2 = 4.0

CAL_VERSION = 2  # 2: feature names carry their units (radius_mm_fringe_k, ...)
#: The exponents b of F = a feature^b a calibration may hold: Hertz gives 3/2 (orders)
#: and 3 (radii). Near 0 the load no longer depends on the feature (b = 1e-300 gave the
#: load a from any map, one with no fringes too); a fit outside is not kept, a file
#: holding one is refused.
EXPONENT_RANGE = (0.2, 10.0)


def _power_fit(loads, values):
    """F = a v^b by least squares on log F vs log v; returns dict or None."""
    loads, values = np.asarray(loads, float), np.asarray(values, float)
    ok = np.isfinite(values) & (values > 0) & (loads > 0)
    if ok.sum() < 3 or np.ptp(np.log(values[ok])) < 1e-6 or np.ptp(np.log(loads[ok])) < 1e-9:
        return None  # nothing to fit: fewer than 3 states, or feature or load constant
    x, y = np.log(values[ok]), np.log(loads[ok])
    (b, loga), cov = np.polyfit(x, y, 1, cov="unscaled")
    if not EXPONENT_RANGE[0] <= b <= EXPONENT_RANGE[1]:
        return None  # the load does not follow the feature as a power law does
    resid = y - (loga + b * x)
    dof = max(ok.sum() - 2, 1)
    s2 = float(resid @ resid / dof)
    return {
        "model": "F = a * v**b",
        "a": float(np.exp(loga)),
        "b": float(b),
        "cov_b_loga": (np.asarray(cov) * s2).tolist(),
        "sigma_logF": float(np.sqrt(s2)),
        "n": int(ok.sum()),
        "range": [float(values[ok].min()), float(values[ok].max())],
    }


def _linear_fit(y, x):
    y, x = np.asarray(y, float), np.asarray(x, float)
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or np.ptp(y[ok]) == 0:
        return None
    (c1, c0), cov = np.polyfit(x[ok], y[ok], 1, cov="unscaled")
    resid = y[ok] - (c0 + c1 * x[ok])
    s2 = float(resid @ resid / max(ok.sum() - 2, 1))
    return {
        "model": "y = c0 + c1 * v",
        "c0": float(c0),
        "c1": float(c1),
        "sigma": float(np.sqrt(s2)),
        "n": int(ok.sum()),
    }


def calibrate_from_maps(loads_N, shears_N, features: list[dict]) -> dict:
    """Fit load-to-feature relations: F = a feature^b per feature (module docstring).

    Parameters
    ----------
    loads_N : (S,) float array
        Normal load at each state (N).
    shears_N : (S, 2) float array
        Shear at each state (N).
    features : list of S dict
        From :func:`fringe_features`.

    Returns
    -------
    dict
        ``version``, ``loads_N``, ``shears_N``, the ``features`` table, and the fits
        ``normal_fits`` (feature -> power law with its scatter and range) and
        ``shear_fits`` (axis -> linear fit on the centroid).

    Raises
    ------
    ValueError
        No feature changes with the load along the path.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import calibrate_from_maps, fringe_features
    >>> r_mm = np.hypot(*np.mgrid[-60:61, -60:61]) * 0.1  # 0.1 mm pixels, axis at (60, 60)
    >>> def order_map(load):  # Hertz-like: order ~ load^(2/3)
    ...     return (load / 8) ** (2 / 3) * 3.0 * np.exp(-((r_mm / 2.5) ** 2))
    >>> loads = [2.0, 4.0, 8.0, 12.0]
    >>> features = [fringe_features(order_map(f), 1e-4, (60, 60)) for f in loads]
    >>> cal = calibrate_from_maps(loads, np.zeros((4, 2)), features)
    >>> round(cal["normal_fits"]["order_at_2mm"]["b"], 3)  # F ~ order^(3/2)
    1.5
    """
    names = sorted(features[0])
    table = {n: [f[n] for f in features] for n in names}
    loads = np.asarray(loads_N, float)
    shears = np.asarray(shears_N, float).reshape(len(loads), 2)
    normal = {}
    for n in names:
        if n.startswith("centroid"):
            continue
        fit = _power_fit(loads, table[n])
        if fit is not None:
            normal[n] = fit
    shear = {}
    for axis, n in ((0, "centroid_x_mm"), (1, "centroid_y_mm")):
        fit = _linear_fit(shears[:, axis], table[n])
        if fit is not None:
            shear[f"shear_{'xy'[axis]}_N"] = {**fit, "feature": n}
    if not normal and not shear:
        raise ValueError(
            "no feature changes with the load along this path: give at least 3 load states "
            "with different normal loads (or shear forces)"
        )
    return {
        "version": CAL_VERSION,
        "loads_N": loads.tolist(),
        "shears_N": shears.tolist(),
        "features": table,
        "normal_fits": normal,
        "shear_fits": shear,
    }


def estimate_load(cal: dict, features: dict, *, extrapolate: float = 0.1) -> dict:
    """Invert a calibration: the normal load (and shear, where calibrated) from features.

    Parameters
    ----------
    cal : dict
        From :func:`calibrate_from_maps` or :func:`load_calibration`.
    features : dict
        Of the map to estimate, from :func:`fringe_features`.
    extrapolate : float
        Features outside the calibrated range by more than this (relative) are not used.

    Returns
    -------
    dict
        ``normal_N``, ``normal_sigma_N`` (N), ``spread_N``, ``per_feature`` estimates,
        ``consistency_chi2``; ``shear_N`` where calibrated; a ``warning`` when the
        features disagree.

    Raises
    ------
    ValueError
        Too few features in the calibrated range, or features inconsistent with the
        calibration.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import calibrate_from_maps, fringe_features
    >>> r_mm = np.hypot(*np.mgrid[-60:61, -60:61]) * 0.1  # 0.1 mm pixels, axis at (60, 60)
    >>> def order_map(load):  # Hertz-like: order ~ load^(2/3)
    ...     return (load / 8) ** (2 / 3) * 3.0 * np.exp(-((r_mm / 2.5) ** 2))
    >>> loads = [2.0, 4.0, 8.0, 12.0]
    >>> features = [fringe_features(order_map(f), 1e-4, (60, 60)) for f in loads]
    >>> cal = calibrate_from_maps(loads, np.zeros((4, 2)), features)
    >>> from fringekit.analysis import estimate_load
    >>> est = estimate_load(cal, fringe_features(order_map(6.0), 1e-4, (60, 60)))
    >>> round(est["normal_N"], 3), len(est["per_feature"])
    (6.0, 7)
    """
    per = {}
    if not cal["normal_fits"]:  # a shear-only calibration at one normal load
        loads = np.asarray(cal["loads_N"], float)
        out = {
            "normal_N": float(loads.mean()),
            "normal_sigma_N": float("nan"),
            "spread_N": 0.0,
            "per_feature": {},
            "note": "calibrated at a single normal load; the normal load is that load",
        }
        out["shear_N"] = _shear(cal, features)
        return out
    for n, fit in cal["normal_fits"].items():
        v = features.get(n, np.nan)
        lo, hi = fit["range"]
        if (
            not (np.isfinite(v) and v > 0)
            or v < lo * (1 - extrapolate)
            or v > hi * (1 + extrapolate)
        ):
            continue
        F = fit["a"] * v ** fit["b"]
        per[n] = {"value": float(v), "load_N": float(F), "sigma_N": float(F * fit["sigma_logF"])}
    need = min(MIN_FEATURES, len(cal["normal_fits"]))
    if len(per) < need:
        raise ValueError(
            f"{len(per)} of the map's features lie in the calibrated range (at least {need} "
            "needed); the load is outside the calibration or the map does not show the "
            "indenter there (check the centre and the pixel size)"
        )
    sig = np.array([max(p["sigma_N"], 1e-9 * p["load_N"]) for p in per.values()])
    F = np.array([p["load_N"] for p in per.values()])
    w = 1 / sig**2
    mean = float((w * F).sum() / w.sum())
    sig_c = np.maximum(sig, CHI2_FLOOR * F)  # for the consistency test only
    chi2 = float((((F - mean) / sig_c) ** 2).sum() / max(len(F) - 1, 1))
    if chi2 > MAX_CHI2:
        raise ValueError(
            f"the map is not consistent with the calibration: its {len(F)} features give "
            f"{F.min():.3g}-{F.max():.3g} N, {np.sqrt(chi2):.0f} times their calibrated "
            "scatter; check the centre, the pixel size and that the calibration is for this "
            "sensor"
        )
    out = {
        "normal_N": mean,
        # the smallest per-feature uncertainty (the features are correlated), widened by
        # the features' excess scatter when they disagree more than calibrated
        "normal_sigma_N": float(sig.min() * max(1.0, np.sqrt(chi2))),
        "spread_N": float(F.max() - F.min()),
        "consistency_chi2": chi2,
        "per_feature": per,
    }
    if chi2 > WARN_CHI2:
        out["warning"] = (
            f"the features disagree {np.sqrt(chi2):.1f} times more than calibrated; the "
            "uncertainty is widened by that factor (is the centre off?)"
        )
    if cal.get("shear_fits"):
        out["shear_N"] = _shear(cal, features)
    return out


def _shear(cal: dict, features: dict) -> list[float]:
    """Shear (fx, fy) from the centroid fits; an axis without a fit gets 0 (not calibrated)."""
    sh = []
    for axis in "xy":
        fit = cal["shear_fits"].get(f"shear_{axis}_N")
        v = features.get(fit["feature"], np.nan) if fit else np.nan
        sh.append(float(fit["c0"] + fit["c1"] * v) if fit and np.isfinite(v) else 0.0)
    return sh


def save_calibration(cal: dict, path: str | os.PathLike) -> Path:
    """Write a calibration as JSON, atomically.

    Parameters
    ----------
    cal : dict
        From :func:`calibrate_from_maps`.
    path : str or os.PathLike
        File to write; missing folders are made.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.analysis import calibrate_from_maps, fringe_features
    >>> r_mm = np.hypot(*np.mgrid[-60:61, -60:61]) * 0.1  # 0.1 mm pixels, axis at (60, 60)
    >>> def order_map(load):  # Hertz-like: order ~ load^(2/3)
    ...     return (load / 8) ** (2 / 3) * 3.0 * np.exp(-((r_mm / 2.5) ** 2))
    >>> loads = [2.0, 4.0, 8.0, 12.0]
    >>> features = [fringe_features(order_map(f), 1e-4, (60, 60)) for f in loads]
    >>> cal = calibrate_from_maps(loads, np.zeros((4, 2)), features)
    >>> import tempfile
    >>> from fringekit.analysis import load_calibration, save_calibration
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = load_calibration(save_calibration(cal, f"{d}/calibration.json"))
    >>> back["normal_fits"] == cal["normal_fits"]
    True
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps(cal, indent=2, default=float))
    os.replace(tmp, path)
    return path


def load_calibration(path: str | os.PathLike) -> dict:
    """Read a calibration written by :func:`save_calibration`, checking it.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    dict

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not a calibration of this version (invalid JSON, an older version, or a fit
        coefficient that is not a finite number).

    Examples
    --------
    >>> import tempfile
    >>> from fringekit.analysis import load_calibration
    >>> with tempfile.TemporaryDirectory() as d:
    ...     with open(f"{d}/old.json", "w") as fh:
    ...         _ = fh.write('{"version": 1}')
    ...     load_calibration(f"{d}/old.json")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: ...old.json: a calibration of an earlier fringekit (version 1, ...
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"calibration file {str(path)!r} does not exist")
    try:
        cal = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a fringekit calibration (invalid JSON: {exc})") from None
    if isinstance(cal, dict) and cal.get("version") == 1:
        raise ValueError(
            f"{path}: a calibration of an earlier fringekit (version 1, feature names without "
            f"units); run fringekit calibrate again to write version {CAL_VERSION}"
        )
    if not isinstance(cal, dict) or cal.get("version") != CAL_VERSION or "normal_fits" not in cal:
        raise ValueError(f"{path}: not a fringekit calibration file (version {CAL_VERSION})")
    _check_fits(cal, path)
    return cal


def _check_fits(cal: dict, path) -> None:
    """Every fit coefficient a finite number; at least one normal-load fit."""
    fits, shear = cal.get("normal_fits"), cal.get("shear_fits")
    if not isinstance(fits, dict) or not (fits or shear):
        raise ValueError(f"{path}: the calibration has no fit (normal_fits and shear_fits empty)")
    groups = (("normal_fits", ("a", "b", "sigma_logF")), ("shear_fits", ("c0", "c1")))
    for group, keys in groups:
        for name, fit in (cal.get(group) or {}).items():
            for k in keys:
                v = fit.get(k) if isinstance(fit, dict) else None
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                    raise ValueError(
                        f"{path}: {group}.{name}.{k} = {v!r} is not allowed; a calibration "
                        "coefficient must be a finite number"
                    )
            if group == "normal_fits":
                _check_power_law(fit, f"{path}: {group}.{name}")


def _check_power_law(fit: dict, where: str) -> None:
    """A fitted F = a v^b that gives a load from a feature: a > 0, b in EXPONENT_RANGE,
    sigma_logF >= 0."""
    lo, hi = EXPONENT_RANGE
    if not lo <= fit["b"] <= hi:
        raise ValueError(
            f"{where}.b = {fit['b']:g} is not allowed; allowed range [{lo:g}, {hi:g}] (an "
            "exponent near 0 gives the same load from any map; run fringekit calibrate again)"
        )
    for k, ok in (("a", fit["a"] > 0), ("sigma_logF", fit["sigma_logF"] >= 0)):
        if not ok:
            raise ValueError(
                f"{where}.{k} = {fit[k]:g} is not allowed; allowed range "
                f"{'(0' if k == 'a' else '[0'}, inf) (run fringekit calibrate again)"
            )
