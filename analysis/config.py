"""Run configuration: TOML files with the unit in every key, defaults, checks, built-in cases.

A config is a TOML document with the tables ``[sheet]``, ``[substrate]``, ``[mesh]``,
``[contact]``, ``[solver]``, ``[optics]`` and an array of ``[[indenter]]`` tables. Every
key is optional; :func:`effective_config` fills the defaults and checks types, ranges and
names, so an unknown key or an out-of-range value is an error naming the key, the value
and what is allowed (../shared/DESIGN.md "Conventions": field units at the edges, SI
inside). ``fringekit config show`` prints the result with units and a line of help per key.

Built-in cases (:data:`BUILTIN_CASES`): ``reference`` (3 mm PSM-4-class sheet on 15 mm
polycarbonate, one 3.5 mm indenter, 8 N vertical; seed paper Fig. 3a) and ``shear``
(the same, then 8 N shear along x with full stick; Fig. 3b).
"""

from __future__ import annotations

import copy
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "BUILTIN_CASES",
    "ConfigError",
    "Key",
    "SCHEMA",
    "INDENTER_SCHEMA",
    "apply_overrides",
    "effective_config",
    "load_config",
    "normal_path",
    "to_toml",
]


class ConfigError(ValueError):
    """A config value that is not allowed; the message names key, value and what is allowed."""


@dataclass(frozen=True)
class Key:
    """One config key: default, unit, allowed values and a line of help."""

    default: Any
    help: str
    unit: str = ""
    kind: str = "float"  # float | int | str | bool | floats | pairs | friction | point
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple | None = None


def _f(default, help, unit="", lo=None, hi=None, lo_open=False):
    return Key(default, help, unit, "float", lo, hi, lo_open)


#: Per-indenter keys (``[[indenter]]`` tables).
INDENTER_SCHEMA: dict[str, Key] = {
    "x_mm": _f(0.0, "indenter axis x on the undeformed contact face", "mm", -1e3, 1e3),
    "y_mm": _f(0.0, "indenter axis y", "mm", -1e3, 1e3),
    "diameter_mm": _f(3.5, "sphere diameter (seed paper: 3.5 mm head)", "mm", 0, 100, True),
    "load_N": Key(
        [8.0],
        "normal force per load state (a number or a list; force control)",
        "N",
        "floats",
        0,
        1e4,
    ),
    "depth_mm": Key(
        None,
        "prescribed depth per load state instead of load_N (displacement control)",
        "mm",
        "floats",
        0,
        100,
    ),
    "shear_N": Key(
        None,
        "tangential force [fx, fy] per load state (needs friction); one pair = every state",
        "N",
        "pairs",
        -1e4,
        1e4,
    ),
}

#: Table -> key -> Key. ``case`` is top level.
SCHEMA: dict[str, Any] = {
    "case": Key("reference", "case name: the output folder is <out>/<case>", kind="str"),
    "sheet": {
        "thickness_mm": _f(
            3.0, "photoelastic sheet thickness (seed paper: 3 mm)", "mm", 0, 100, True
        ),
        "width_mm": _f(40.0, "sheet size along x (assumed 40 mm)", "mm", 1, 2000),
        "length_mm": _f(40.0, "sheet size along y", "mm", 1, 2000),
        "model": Key(
            "neo-hookean",
            "hyperelastic model",
            kind="str",
            choices=("neo-hookean", "mooney-rivlin"),
        ),
        "E_MPa": _f(4.0, "Young's modulus (PSM-4 class, assumed)", "MPa", 0, 1e6, True),
        "nu": _f(0.49, "Poisson's ratio (neo-hookean)", "", 0, 0.4999),
        "C10_MPa": _f(0.6, "Mooney-Rivlin C10 (mooney-rivlin only)", "MPa", 0, 1e5),
        "C01_MPa": _f(0.07, "Mooney-Rivlin C01 (mooney-rivlin only)", "MPa", 0, 1e5),
        "K_MPa": _f(66.7, "bulk modulus (mooney-rivlin only)", "MPa", 0, 1e7, True),
    },
    "substrate": {
        "thickness_mm": _f(
            15.0, "polycarbonate thickness; 0 = sheet on a rigid base", "mm", 0, 500
        ),
        "E_MPa": _f(
            2300.0, "polycarbonate Young's modulus (datasheet, assumed)", "MPa", 0, 1e6, True
        ),
        "nu": _f(0.37, "polycarbonate Poisson's ratio", "", 0, 0.4999),
    },
    "mesh": {
        "symmetry": Key(
            "auto",
            "model part: auto picks the smallest part the indenters and loads allow",
            kind="str",
            choices=("auto", "full", "half", "quarter"),
        ),
        "h_contact_mm": _f(
            0.6,
            "edge length under each indenter (0.6 converges the depth; 0.4 for the fringe "
            "order within 0.5 mm of the contact edge, bench/convergence.py)",
            "mm",
            0,
            50,
            True,
        ),
        "refine_radius_mm": _f(
            2.0, "radius of the refined zone about each axis", "mm", 0, 500, True
        ),
        "h_sheet_mm": _f(2.0, "largest edge in the sheet", "mm", 0, 100, True),
        "h_far_mm": _f(8.0, "largest edge anywhere", "mm", 0, 500, True),
        "growth": _f(0.4, "size grading per unit distance", "", 0, 10, True),
    },
    "contact": {
        "friction": Key(
            0.0,
            'Coulomb coefficient >= 0, or "stick" for full stick',
            kind="friction",
            lo=0,
            hi=100,
        ),
        "penalty_factor": _f(100.0, "normal penalty / (E_sheet / h)", "", 0, 1e6, True),
    },
    "solver": {
        "backend": Key(
            "auto", "sparse direct solver", kind="str", choices=("auto", "pardiso", "scipy")
        ),
        "force_tol": _f(1e-8, "residual tolerance relative to the applied force", "", 0, 0.1, True),
        "max_iterations": Key(30, "Newton iterations per attempt", kind="int", lo=2, hi=500),
        "max_cutbacks": Key(8, "load-increment halvings before giving up", kind="int", lo=0, hi=30),
    },
    "optics": {
        "f_sigma_N_per_m": _f(
            386.0,
            "material fringe value at wavelength_nm (PSM-4 class, assumed)",
            "N/m",
            0,
            1e8,
            True,
        ),
        "wavelength_nm": _f(575.0, "reference and monochrome wavelength", "nm", 360, 830),
        "dispersion": Key(
            "none",
            "dispersion of the stress-optic coefficient",
            kind="str",
            choices=("none", "cauchy", "power"),
        ),  # fmt: skip
        "dispersion_coefficient": _f(0.0, "Cauchy B (m^2) or power-law exponent", "", -1e3, 1e3),
        "field_of_view_mm": _f(20.0, "square field of view", "mm", 0, 2000, True),
        "center_mm": Key([0.0, 0.0], "field-of-view centre [x, y]", "mm", "point", -1e3, 1e3),
        "pixels": Key(256, "image size (pixels x pixels)", kind="int", lo=8, hi=4096),
        "samples_per_ray": Key(64, "slabs per ray through the sheet", kind="int", lo=4, hi=4096),
        "lateral_step_mm": _f(
            0.4,
            "pitch of the ray lattice the stress is sampled on and interpolated from, halved "
            "where its error check fails (0 = sample every pixel's ray)",
            "mm",
            0,
            100,
        ),
        "include_substrate": Key(
            False,
            "also integrate through the polycarbonate (light enters from the PC side)",
            kind="bool",
        ),
        "substrate_f_sigma_N_per_m": _f(
            7000.0,
            "polycarbonate fringe value at wavelength_nm (handbook, assumed)",
            "N/m",
            0,
            1e9,
            True,
        ),  # fmt: skip
        "substrate_samples_per_ray": Key(
            32, "slabs per ray through the polycarbonate", kind="int", lo=2, hi=4096
        ),
        "light": Key("LED", "white-light source", kind="str", choices=("LED", "A", "D65")),
        "white_light_wavelengths": Key(
            31,
            "wavelengths 400-700 nm for white light (even steps of the sheet's 2 pi C / lam)",
            kind="int",
            lo=4,
            hi=301,
        ),
        "camera": Key("CIE1931", "observer or colour-science camera name", kind="str"),
        "bit_depth": Key(8, "image bit depth", kind="int", choices=(8, 16)),
        "exposure": _f(
            0.9,
            "grey level of a fully transmitting pixel / full scale (< 1 keeps the brightest "
            "fringes unsaturated, as an experimenter exposes)",
            "",
            0,
            1e3,
            True,
        ),
        "full_well_e": _f(0.0, "electrons at full scale (shot noise; 0 = none)", "e-", 0, 1e7),
        "read_noise_e": _f(0.0, "read noise (needs full_well_e)", "e-", 0, 1e4),
        "seed": Key(0, "noise seed", kind="int", lo=0, hi=2**32 - 1),
        "qwp_error_deg": _f(0.0, "quarter-wave plate retardance error", "deg", -45, 45),
        "qwp_in_error_deg": _f(0.0, "input quarter-wave plate angle error", "deg", -45, 45),
        "qwp_out_error_deg": _f(0.0, "output quarter-wave plate angle error", "deg", -45, 45),
        "analyser_error_deg": _f(0.0, "analyser angle error", "deg", -45, 45),
        "render": Key(
            "last", "which load states get maps and images", kind="str", choices=("last", "all")
        ),
    },
}

_REFERENCE: dict[str, Any] = {"case": "reference"}
_SHEAR: dict[str, Any] = {
    "case": "shear",
    "contact": {"friction": "stick"},
    "indenter": [{"load_N": [8.0, 8.0], "shear_N": [[0.0, 0.0], [8.0, 0.0]]}],
}
#: Built-in cases by name (partial configs; defaults fill the rest).
BUILTIN_CASES: dict[str, dict] = {"reference": _REFERENCE, "shear": _SHEAR}


def _bad(key: str, value, allowed: str) -> ConfigError:
    return ConfigError(f"{key} = {value!r} is not allowed; {allowed}")


def _range_text(k: Key) -> str:
    lo = "(" if k.lo_open else "["
    return f"allowed range {lo}{k.lo:g}, {k.hi:g}]" + (f" {k.unit}" if k.unit else "")


def _number(name: str, v, k: Key, integer: bool = False) -> float | int:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _bad(name, v, f"give a number{' (integer)' if integer else ''}")
    if integer and not float(v).is_integer():
        raise _bad(name, v, "give an integer")
    if not math.isfinite(v):
        raise _bad(name, v, "give a finite number")
    if k.choices is not None and v not in k.choices:
        raise _bad(name, v, f"allowed values {list(k.choices)}")
    if k.lo is not None and (v < k.lo or (k.lo_open and v == k.lo) or v > k.hi):
        raise _bad(name, v, _range_text(k))
    return int(v) if integer else float(v)


def _check(name: str, v, k: Key):
    """Return the checked, normalised value of key ``name``."""
    if k.kind == "float":
        return _number(name, v, k)
    if k.kind == "int":
        return _number(name, v, k, integer=True)
    if k.kind == "str":
        if not isinstance(v, str) or not v:
            raise _bad(name, v, "give a non-empty string")
        if k.choices is not None and v not in k.choices:
            raise _bad(name, v, f"allowed values {list(k.choices)}")
        return v
    if k.kind == "bool":
        if not isinstance(v, bool):
            raise _bad(name, v, "give true or false")
        return v
    if k.kind == "friction":
        if v == "stick":
            return v
        if isinstance(v, str):
            raise _bad(name, v, 'give a coefficient >= 0 or "stick"')
        return _number(name, v, k)
    if k.kind == "floats":
        vals = v if isinstance(v, list) else [v]
        if not vals:
            raise _bad(name, v, "give at least one value (one per load state)")
        return [_number(f"{name}[{i}]", x, k) for i, x in enumerate(vals)]
    if k.kind in ("pairs", "point"):
        vals = v if (isinstance(v, list) and v and isinstance(v[0], list)) else [v]
        if k.kind == "point" and len(vals) != 1:
            raise _bad(name, v, "give one [x, y] pair")
        out = []
        for i, p in enumerate(vals):
            if not isinstance(p, list) or len(p) != 2:
                raise _bad(f"{name}[{i}]", p, "give an [x, y] pair")
            out.append([_number(f"{name}[{i}]", x, k) for x in p])
        return out[0] if k.kind == "point" else out
    raise AssertionError(k.kind)  # pragma: no cover


def _merge_table(name: str, given: dict, schema: dict) -> dict:
    if not isinstance(given, dict):
        raise _bad(name, given, "it must be a table")
    unknown = sorted(set(given) - set(schema))
    if unknown:
        raise ConfigError(
            f"unknown key {name}.{unknown[0]}; allowed keys in [{name}]: {sorted(schema)}"
        )
    return {
        key: _check(f"{name}.{key}", given[key], k) if key in given else copy.deepcopy(k.default)
        for key, k in schema.items()
    }


def normal_path(indenter: dict) -> list:
    """An effective ``[[indenter]]``'s normal load path: ``load_N`` (N) or ``depth_mm``."""
    return indenter["load_N"] if indenter["load_N"] is not None else indenter["depth_mm"]


def _indenter(i: int, given: dict) -> dict:
    name = f"indenter[{i}]"
    d = _merge_table(name, given, INDENTER_SCHEMA)
    if "depth_mm" in given and d["depth_mm"] is not None:
        if "load_N" in given:
            raise ConfigError(
                f"{name}: give load_N (force control) or depth_mm (displacement control), not both"
            )
        d["load_N"] = None
    n = len(normal_path(d))
    if d["shear_N"] is not None:
        if len(d["shear_N"]) == 1 and n > 1:
            d["shear_N"] = d["shear_N"] * n
        if len(d["shear_N"]) != n:
            raise ConfigError(
                f"{name}.shear_N has {len(d['shear_N'])} load states but the normal load has "
                f"{n}; give one [fx, fy] per load state (or one pair for all)"
            )
    return d


def effective_config(given: dict | None = None) -> dict:
    """Defaults filled in and every value checked; raises :class:`ConfigError`."""
    given = dict(given or {})
    top = {"case", "indenter", *(k for k, v in SCHEMA.items() if isinstance(v, dict))}
    unknown = sorted(set(given) - top)
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r}; allowed top-level keys: {sorted(top)}")
    cfg: dict[str, Any] = {"case": _check("case", given.get("case", "reference"), SCHEMA["case"])}
    if any(c in cfg["case"] for c in "/\\") or cfg["case"] in (".", ".."):
        raise _bad("case", cfg["case"], "give a plain folder name (no path separators)")
    for table, schema in SCHEMA.items():
        if isinstance(schema, dict):
            cfg[table] = _merge_table(table, given.get(table, {}), schema)
    inds = given.get("indenter", [{}])
    if isinstance(inds, dict):
        inds = [inds]
    if not isinstance(inds, list) or not inds:
        raise _bad("indenter", inds, "give one or more [[indenter]] tables")
    cfg["indenter"] = [_indenter(i, d) for i, d in enumerate(inds)]
    counts = {len(normal_path(d)) for d in cfg["indenter"]}
    if len(counts) != 1:
        raise ConfigError(
            f"indenters have different numbers of load states {sorted(counts)}; every indenter "
            "needs one target per load state"
        )
    m = cfg["mesh"]
    if not m["h_contact_mm"] <= m["h_sheet_mm"] <= m["h_far_mm"]:
        raise ConfigError(
            f"mesh sizes h_contact_mm = {m['h_contact_mm']}, h_sheet_mm = {m['h_sheet_mm']}, "
            f"h_far_mm = {m['h_far_mm']} are not allowed; need h_contact <= h_sheet <= h_far"
        )
    if m["h_contact_mm"] > cfg["sheet"]["thickness_mm"]:
        raise ConfigError(
            f"mesh.h_contact_mm = {m['h_contact_mm']} is larger than sheet.thickness_mm = "
            f"{cfg['sheet']['thickness_mm']}; allowed: h_contact_mm <= thickness_mm"
        )
    o = cfg["optics"]
    if o["read_noise_e"] > 0 and o["full_well_e"] == 0:
        raise ConfigError(
            f"optics.read_noise_e = {o['read_noise_e']} needs optics.full_well_e > 0 "
            "(electrons at full scale)"
        )
    return cfg


def load_config(source: str | os.PathLike | None = None) -> dict:
    """Effective config from a TOML file, a built-in case name, or None (reference case)."""
    if source is None:
        return effective_config(BUILTIN_CASES["reference"])
    s = str(source)
    path = Path(s)
    if s in BUILTIN_CASES and not path.exists():
        return effective_config(copy.deepcopy(BUILTIN_CASES[s]))
    if not path.is_file():
        raise ConfigError(
            f"config {s!r} is neither a file nor a built-in case; built-in cases: "
            f"{sorted(BUILTIN_CASES)}"
        )
    try:
        given = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    given.setdefault("case", path.stem)
    return effective_config(given)


def apply_overrides(cfg: dict, overrides: dict[str, Any]) -> dict:
    """``cfg`` with dotted-key values replaced, checked again as a whole.

    Keys are ``"table.key"`` (``"sheet.E_MPa"``), ``"case"``, or ``"indenter.key"`` /
    ``"indenter[k].key"`` (indenter 0 / k). Setting ``load_N`` replaces ``depth_mm`` and
    the other way round.
    """
    import re

    given = copy.deepcopy(cfg)
    for key, value in overrides.items():
        parts = key.split(".")
        if key == "case":
            given["case"] = value
            continue
        if len(parts) != 2 or not all(parts):
            raise ConfigError(f"override key {key!r} is not allowed; use table.key")
        table, name = parts
        m = re.fullmatch(r"indenter(?:\[(\d+)\])?", table)
        if m:
            k = int(m.group(1) or 0)
            if k >= len(given["indenter"]):
                raise ConfigError(
                    f"override {key!r}: there are {len(given['indenter'])} indenters (0-based)"
                )
            node = given["indenter"][k]
            other = {"depth_mm": "load_N", "load_N": "depth_mm"}.get(name)
            if other:
                node.pop(other, None)  # setting one control mode replaces the other
        elif isinstance(SCHEMA.get(table), dict):
            node = given[table]
        else:
            raise ConfigError(f"override {key!r}: unknown table {table!r}")
        node[name] = value
    for d in given["indenter"]:  # only given or set keys, so the checks see the user's keys
        for k in ("load_N", "depth_mm", "shear_N"):
            if d.get(k) is None:
                d.pop(k, None)
    return effective_config(given)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return str(v)


def _toml_table(lines: list[str], d: dict, schema: dict) -> None:
    for key, k in schema.items():
        v = d.get(key)
        unit = f" [{k.unit}]" if k.unit else ""
        choices = f" {list(k.choices)}" if k.choices and k.kind == "str" else ""
        if v is None:
            lines.append(f"# {key} =  (unset){'':8}# {k.help}{unit}{choices}")
        else:
            lines.append(f"{key} = {_toml_value(v)}{'':4}# {k.help}{unit}{choices}")


def to_toml(cfg: dict) -> str:
    """The effective config as commented TOML (re-readable by :func:`load_config`)."""
    lines = [f"case = {_toml_value(cfg['case'])}    # {SCHEMA['case'].help}"]
    for table, schema in SCHEMA.items():
        if isinstance(schema, dict):
            lines += ["", f"[{table}]"]
            _toml_table(lines, cfg[table], schema)
    for d in cfg["indenter"]:
        lines += ["", "[[indenter]]"]
        _toml_table(lines, d, INDENTER_SCHEMA)
    return "\n".join(lines) + "\n"
