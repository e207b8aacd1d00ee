"""fringekit: contact stress and photoelastic fringes of soft tactile sensors."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

# The pipeline stages live in the repository's top-level folders (meshes/, fea/, optics/,
# analysis/) and pyproject.toml maps them into this package when it is installed. Run from
# a source checkout (``python -m pytest`` in the repository puts it first on sys.path), this
# folder is found before the installed package: the checkout's root then serves the stages.
_CHECKOUT = Path(__file__).resolve().parent.parent
if not (Path(__file__).parent / "meshes").is_dir() and (_CHECKOUT / "meshes" / "spec.py").is_file():
    __path__.append(str(_CHECKOUT))  # noqa: F821 (a package's __path__)

try:
    __version__ = version("fringekit")
except PackageNotFoundError:  # pragma: no cover (a checkout that was never installed)
    __version__ = "0+unknown"

from fringekit.config import Config  # noqa: E402
from fringekit.errors import (  # noqa: E402
    ComputeError,
    ConfigError,
    FringekitError,
    InputError,
    Interrupted,
    LibraryError,
    RefusedError,
)
from fringekit.predict import Prediction, PredictError, predict  # noqa: E402

__all__ = [
    "ComputeError",
    "Config",
    "ConfigError",
    "FringekitError",
    "InputError",
    "Interrupted",
    "LibraryError",
    "PredictError",
    "Prediction",
    "RefusedError",
    "__version__",
    "predict",
]
