"""fringekit: contact stress and photoelastic fringes of soft tactile sensors.

The API computes and returns objects; each result has a ``write(folder)`` that gives the
files of the matching ``fringekit`` command.

- :class:`Config` - a checked sensor and load configuration (units in the key names);
- :func:`predict` -> :class:`Prediction` - mesh, contact solution, fringe maps and
  camera images of a config;
- :func:`analyze` -> :class:`Analysis` - the fringe order of six phase-stepped images,
  one white-light colour image or one monochrome photograph;
- :func:`build_library`, :meth:`Library.open` - response libraries;
- :func:`invert` -> :class:`Inversion` - every indenter's position and load vector read
  off one image;
- :func:`track` -> :class:`Track` - every contact's position and load vector through a
  video, a folder of frames or a live camera;
- :func:`calibrate_disc` -> :class:`DiscCalibration` - the material fringe value from
  disc photographs;
- :func:`calibrate_sensor` -> :class:`SensorCalibration` - a library calibrated to one
  physical sensor (its :class:`CalibratedSensor` is what ``invert`` and ``track`` take
  as ``sensor``).

The pipeline stages are sub-packages: :mod:`fringekit.meshes`, :mod:`fringekit.fea`,
:mod:`fringekit.optics` and :mod:`fringekit.analysis`. Every error is a
:class:`FringekitError`.

Examples
--------
>>> import fringekit
>>> cfg = fringekit.Config.reference().replace({"indenter.load_N": [4.0]})
>>> cfg["indenter.load_N"]
[4.0]
>>> sorted(name for name in fringekit.__all__ if name[0].islower() and name[0] != "_")
['analyze', 'build_library', 'calibrate_disc', 'calibrate_sensor', 'invert', 'predict', 'track']
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as _np

# colour-science switches numpy's printing to its 1.13 legacy mode when it is imported
# (the stages use it for light sources and camera sensitivities); importing fringekit must
# not change how a user's arrays print, so the options are put back.
_PRINT_OPTIONS = _np.get_printoptions()
import colour  # noqa: E402, F401

_np.set_printoptions(**_PRINT_OPTIONS)

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

from fringekit.calibrate import DiscCalibration, calibrate_disc  # noqa: E402
from fringekit.config import Config  # noqa: E402
from fringekit.errors import (  # noqa: E402
    ComputeError,
    ConfigError,
    FringekitError,
    InputError,
    Interrupted,
    LibraryError,
    RefusedError,
    SourceError,
)
from fringekit.inversion import Inversion, InvertError, invert  # noqa: E402
from fringekit.library import Library, build_library  # noqa: E402
from fringekit.measurement import (  # noqa: E402
    Analysis,
    MonoOptions,
    PhaseOptions,
    Region,
    RGBOptions,
    analyze,
)
from fringekit.prediction import PredictError, Prediction, predict  # noqa: E402
from fringekit.sensor import CalibratedSensor, SensorCalibration, calibrate_sensor  # noqa: E402
from fringekit.tracking import Track, track  # noqa: E402

__all__ = [
    "Analysis",
    "CalibratedSensor",
    "ComputeError",
    "Config",
    "ConfigError",
    "DiscCalibration",
    "FringekitError",
    "InputError",
    "Interrupted",
    "Inversion",
    "InvertError",
    "Library",
    "LibraryError",
    "MonoOptions",
    "PhaseOptions",
    "PredictError",
    "Prediction",
    "RGBOptions",
    "RefusedError",
    "Region",
    "SensorCalibration",
    "SourceError",
    "Track",
    "__version__",
    "analyze",
    "build_library",
    "calibrate_disc",
    "calibrate_sensor",
    "invert",
    "predict",
    "track",
]
