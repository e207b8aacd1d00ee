"""A config as a typed Python object: :class:`Config`.

A :class:`Config` holds one checked, effective configuration (every default filled in,
every value within its range: :func:`fringekit.config.files.effective_config`). It is
built from a built-in case, a TOML file or a dict, and changed only by :meth:`Config.replace`,
which checks the whole config again: every key, type, range and the checks between keys
that need no mesh (what needs the geometry, such as an indenter off the sheet, is
checked when a run starts, before anything is computed).
Keys keep their units in their names (``sheet.E_MPa``, ``indenter.load_N``).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fringekit.config.files import apply_overrides, effective_config, load_config, to_toml
from fringekit.config.schema import BUILTIN_CASES
from fringekit.errors import ConfigError

__all__ = ["Config", "as_config"]


@dataclass(frozen=True)
class Config:
    """One checked fringekit configuration (units in the key names).

    Build it with :meth:`reference`, :meth:`builtin`, :meth:`from_toml` or
    :meth:`from_dict`; change it with :meth:`replace`. Read a value with
    ``config["table.key"]`` (``config["indenter.load_N"]`` is the first indenter's,
    ``config["indenter[1].x_mm"]`` the second's).

    Attributes
    ----------
    data : dict
        The effective config: ``case``, one dict per table (``sheet``, ``substrate``,
        ``mesh``, ``contact``, ``solver``, ``optics``) and a list of ``indenter`` dicts.
        Treat it as read-only; :meth:`to_dict` gives a copy to edit.

    Examples
    --------
    >>> from fringekit import Config
    >>> cfg = Config.reference()
    >>> cfg["sheet.E_MPa"], cfg["indenter.load_N"]
    (4.0, [8.0])
    >>> softer = cfg.replace({"sheet.E_MPa": 3.0, "indenter.load_N": [2.0, 4.0]})
    >>> softer["sheet.E_MPa"], cfg["sheet.E_MPa"]
    (3.0, 4.0)
    >>> Config.reference().replace({"sheet.E_MPa": -1})
    Traceback (most recent call last):
    ...
    fringekit.errors.ConfigError: sheet.E_MPa = -1 is not allowed; ...
    """

    data: dict = field(repr=False)

    def __post_init__(self):
        object.__setattr__(self, "data", effective_config(_given(self.data)))

    @classmethod
    def reference(cls) -> Config:
        """The built-in reference case: a 3 mm PSM-4-class sheet on 15 mm polycarbonate,
        one 3.5 mm hemispherical indenter, 8 N vertical."""
        return cls.builtin("reference")

    @classmethod
    def builtin(cls, name: str) -> Config:
        """A built-in case by name: ``"reference"``, ``"shear"`` or ``"small"`` (see
        :data:`fringekit.config.schema.BUILTIN_CASES`)."""
        if name not in BUILTIN_CASES:
            raise ConfigError(
                f"case {name!r} is not built in; built-in cases: {sorted(BUILTIN_CASES)}"
            )
        return cls(BUILTIN_CASES[name])

    @classmethod
    def from_toml(cls, path: str | os.PathLike) -> Config:
        """A config file (TOML, units in the key names); the case is named after the file
        unless it sets ``case``."""
        return cls(load_config(os.fspath(path)))

    @classmethod
    def from_dict(cls, given: Mapping) -> Config:
        """A config from nested dicts shaped like the TOML file; missing keys take their
        defaults."""
        return cls(dict(given))

    def replace(self, overrides: Mapping[str, Any]) -> Config:
        """A new config with dotted keys set (``{"sheet.E_MPa": 3.0}``), checked again."""
        return Config(apply_overrides(self.data, dict(overrides)))

    def __getitem__(self, key: str) -> Any:
        if key == "case":
            return self.data["case"]
        table, _, name = key.partition(".")
        node: Any = None
        if table.startswith("indenter"):
            k = int(table[len("indenter[") : -1]) if table != "indenter" else 0
            if k < len(self.data["indenter"]):
                node = self.data["indenter"][k]
        else:
            node = self.data.get(table) if isinstance(self.data.get(table), dict) else None
        if node is None or name not in node:
            raise KeyError(key)
        return copy.deepcopy(node[name])

    @property
    def case(self) -> str:
        """The case name (names the output folder)."""
        return self.data["case"]

    def to_dict(self) -> dict:
        """A deep copy of the effective config."""
        return copy.deepcopy(self.data)

    def to_toml(self) -> str:
        """The config as commented TOML, re-readable by :meth:`from_toml`."""
        return to_toml(self.data)


def _given(data: Mapping) -> dict:
    """A deep copy of ``data`` without its unset (None) keys: what a user would have
    written, so that an effective config is checked again as given."""

    def strip(d):
        return {k: v for k, v in d.items() if v is not None}

    given = {k: strip(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    inds = given.get("indenter")
    if isinstance(inds, list):
        given["indenter"] = [strip(d) if isinstance(d, Mapping) else d for d in inds]
    return copy.deepcopy(given)


def as_config(config: Config | Mapping | str | os.PathLike | None) -> Config:
    """A :class:`Config` from a Config, a dict, a TOML path or built-in case name, or
    None (the reference case)."""
    if isinstance(config, Config):
        return config
    if isinstance(config, Mapping):
        return Config.from_dict(config)
    return Config(load_config(config))
