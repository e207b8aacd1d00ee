"""Installed versions of fringekit and the packages whose versions a result depends on."""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version

__all__ = ["package_version", "run_versions"]


def package_version(name: str, missing: str = "unknown") -> str:
    """Installed version of a distribution, ``missing`` when it is not installed."""
    try:
        return version(name)
    except PackageNotFoundError:  # e.g. fringekit run from a source tree
        return missing


def run_versions() -> dict:
    """Versions recorded in every ``summary.json``: fringekit, Python and the numerics."""
    return {
        "fringekit": package_version("fringekit"),
        "python": platform.python_version(),
        **{
            p: package_version(p)
            for p in ("numpy", "scipy", "pytetwild", "pyvista", "colour-science")
        },
    }
