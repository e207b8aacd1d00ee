"""Run configuration: TOML files with the unit in every key, defaults, checks, built-in cases.

A config is a TOML document with the tables ``[sheet]``, ``[substrate]``, ``[mesh]``,
``[contact]``, ``[solver]``, ``[optics]`` and an array of ``[[indenter]]`` tables. Every
key is optional; :func:`effective_config` fills the defaults and checks types, ranges and
names, so an unknown key or an out-of-range value is an error naming the key, the value
and what is allowed (field units at the edges, SI inside: ``docs/theory.md``,
"Conventions"). ``fringekit config show`` prints the result with units and a line of help per key.

The keys, their defaults, units and ranges are in :mod:`fringekit.config.schema`.
"""

from __future__ import annotations

import copy
import math
import numbers
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import tomlkit

from fringekit.config.schema import BUILTIN_CASES, INDENTER_SCHEMA, SCHEMA, ConfigError, Key

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
    "check_number",
    "effective_config",
    "load_config",
    "normal_path",
    "to_toml",
]


def _shown(value) -> str:
    """A value as a user wrote it: TOML-like, no Python or numpy repr."""
    if isinstance(value, numbers.Number) and not isinstance(value, bool):
        return f"{value.item() if hasattr(value, 'item') else value!r}"
    return repr(value) if isinstance(value, str) else str(value)


def _bad(key: str, value, allowed: str) -> ConfigError:
    return ConfigError(f"{key} = {_shown(value)} is not allowed; {allowed}")


def _number(name: str, v, k: Key, integer: bool = False) -> float | int:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise _bad(name, v, f"give a number{' (integer)' if integer else ''}")
    if integer and not float(v).is_integer():
        raise _bad(name, v, "give an integer")
    if not math.isfinite(v):
        raise _bad(name, v, "give a finite number")
    if k.choices is not None and v not in k.choices:
        raise _bad(name, v, f"allowed values {list(k.choices)}")
    if k.lo is not None and (v < k.lo or (k.lo_open and v == k.lo) or v > k.hi):
        raise _bad(name, v, k.allowed())
    return int(v) if integer else float(v)


def check_number(name: str, value, key: Key) -> float | int:
    """``value`` checked against the type and range of ``key`` (a :class:`Key` of the
    schema, or one made for an option); a :class:`ConfigError` naming ``name``."""
    return _number(name, value, key, integer=key.kind == "int")


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
    _check_shear_friction(cfg)
    _check_field_of_view(cfg)
    o = cfg["optics"]
    if o["read_noise_e"] > 0 and o["full_well_e"] == 0:
        raise ConfigError(
            f"optics.read_noise_e = {o['read_noise_e']} needs optics.full_well_e > 0 "
            "(electrons at full scale)"
        )
    return cfg


def _check_shear_friction(cfg: dict) -> None:
    """Shear needs friction: a frictionless sphere carries no tangential load."""
    if cfg["contact"]["friction"] != 0.0:
        return
    for i, d in enumerate(cfg["indenter"]):
        if d["shear_N"] is not None and any(v != 0.0 for p in d["shear_N"] for v in p):
            raise ConfigError(
                f"indenter[{i}].shear_N = {d['shear_N']} needs friction, but contact.friction "
                '= 0; allowed: contact.friction > 0 (Coulomb) or "stick" (full stick)'
            )


def _check_field_of_view(cfg: dict) -> None:
    """The field of view must overlap the sheet (centred at the origin)."""
    o, sh = cfg["optics"], cfg["sheet"]
    half = o["field_of_view_mm"] / 2
    for c, size, axis in zip(o["center_mm"], (sh["width_mm"], sh["length_mm"]), "xy", strict=True):
        if abs(c) - half >= size / 2:
            raise ConfigError(
                f"optics.center_mm = {o['center_mm']} puts the field of view "
                f"({o['field_of_view_mm']:g} mm wide) off the sheet along {axis}; allowed: "
                f"|{axis}| < {size / 2 + half:g} mm (half the sheet plus half the field)"
            )


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
        given = tomllib.loads(path.read_text(encoding="utf-8-sig"))  # an editor's BOM is fine
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


def _toml_table(schema: dict, d: dict):
    """A tomlkit table of ``d``, each key commented with its help, unit and choices."""
    table = tomlkit.table()
    for key, k in schema.items():
        v = d.get(key)
        unit = f" [{k.unit}]" if k.unit else ""
        choices = f" {list(k.choices)}" if k.choices and k.kind == "str" else ""
        if v is None:
            table.add(tomlkit.comment(f"{key} = (unset)  # {k.help}{unit}{choices}"))
        else:
            item = tomlkit.item(v)
            item.comment(f"{k.help}{unit}{choices}")
            table.add(key, item)
    return table


def to_toml(cfg: dict) -> str:
    """The effective config as commented TOML (re-readable by :func:`load_config`)."""
    doc = tomlkit.document()
    case = tomlkit.item(cfg["case"])
    case.comment(SCHEMA["case"].help)
    doc.add("case", case)
    for table, schema in SCHEMA.items():
        if isinstance(schema, dict):
            doc.add(table, _toml_table(schema, cfg[table]))
    indenters = tomlkit.aot()
    for d in cfg["indenter"]:
        indenters.append(_toml_table(INDENTER_SCHEMA, d))
    doc.add("indenter", indenters)
    return tomlkit.dumps(doc)
