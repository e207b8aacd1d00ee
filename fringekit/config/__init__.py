"""Configurations: the schema of every key, TOML files, the typed :class:`Config`, and the
conversion of a config into the stages' SI inputs (the one place where mm become m)."""

from fringekit.config.model import Config, as_config

__all__ = ["Config", "as_config"]
