"""The errors fringekit raises, under one base class.

Every error a user can meet derives from :class:`FringekitError`, so one ``except`` catches
them all, and the command line maps each family to one exit status:

- :class:`InputError` (exit 2): an input that is not allowed, found before work starts: a
  config key, an option, a file, an output folder. :class:`ConfigError` (a config key),
  :class:`LibraryError` (a library folder) and :class:`SourceError` (a frame source) are
  input errors.
- :class:`RefusedError` (exit 2): inputs that are each valid but that the method cannot
  stand behind together, such as an image the response library cannot explain.
- :class:`ComputeError` (exit 1): a computation that did not finish (the contact solver did
  not reach a load, a mesh did not reach its quality). :class:`Interrupted` (exit 130) is
  the user stopping it.

This module imports nothing of fringekit, so the pipeline stages derive their own errors
from it without depending on the application.

Examples
--------
>>> from fringekit.errors import ConfigError, FringekitError, InputError
>>> issubclass(ConfigError, InputError) and issubclass(InputError, FringekitError)
True
>>> issubclass(ConfigError, ValueError)  # code that caught ValueError still does
True
"""

from __future__ import annotations

__all__ = [
    "ComputeError",
    "ConfigError",
    "FringekitError",
    "InputError",
    "Interrupted",
    "LibraryError",
    "RefusedError",
    "SourceError",
]


class FringekitError(Exception):
    """The base of every error fringekit raises on purpose.

    Examples
    --------
    >>> import fringekit
    >>> try:
    ...     fringekit.Config.builtin("no-such-case")
    ... except fringekit.FringekitError as exc:
    ...     print(type(exc).__name__)
    ConfigError
    """


class InputError(FringekitError, ValueError):
    """An input that is not allowed; the message names the option or key, the value and
    what is allowed.

    Examples
    --------
    >>> import fringekit
    >>> fringekit.analyze([])
    Traceback (most recent call last):
    ...
    fringekit.errors.InputError: analyze needs at least one image
    """


class ConfigError(InputError):
    """A config value that is not allowed; the message names key, value and what is allowed.

    Examples
    --------
    >>> import fringekit
    >>> fringekit.Config.reference().replace({"optics.wavelength_nm": 1000})
    Traceback (most recent call last):
    ...
    fringekit.errors.ConfigError: optics.wavelength_nm = 1000 is not allowed; ...
    """


class LibraryError(InputError):
    """A library folder that cannot be used (missing, corrupt, another sensor).

    Examples
    --------
    >>> import tempfile, fringekit
    >>> fringekit.Library.open(tempfile.mkdtemp())
    Traceback (most recent call last):
    ...
    fringekit.errors.LibraryError: --library ...: no manifest.json (not a library folder, ...
    """


class SourceError(InputError):
    """A frame source that cannot be read (the SOURCE of ``fringekit track``): a path that
    does not exist, an empty folder, a video that does not decode, a camera that does not
    open, or a frame unlike the first one. The message names the source or the frame, the
    value and what is allowed. A frame's error is raised at that frame, after the earlier
    frames were yielded.

    Examples
    --------
    >>> from fringekit.tracking import open_source
    >>> open_source("camera:abc")
    Traceback (most recent call last):
    ...
    fringekit.errors.SourceError: SOURCE camera:abc is not allowed; a camera is camera:N ...
    """


class RefusedError(FringekitError):
    """Valid inputs whose answer the method cannot stand behind (for example an image the
    response library cannot explain); the message says which quantity is out of range.

    Examples
    --------
    >>> import fringekit
    >>> issubclass(fringekit.InvertError, fringekit.RefusedError)
    True
    """


class ComputeError(FringekitError, RuntimeError):
    """A computation that could not finish (solver, mesher); partial results are kept
    where the raising function says so.

    Examples
    --------
    >>> import fringekit
    >>> from fringekit.fea import SolverError
    >>> issubclass(SolverError, fringekit.ComputeError), issubclass(
    ...     fringekit.PredictError, fringekit.ComputeError)
    (True, True)
    """


class Interrupted(ComputeError):
    """The user stopped a computation (Ctrl-C).

    Examples
    --------
    >>> from fringekit.errors import Interrupted
    >>> from fringekit.fea import SolveInterrupted
    >>> issubclass(SolveInterrupted, Interrupted)
    True
    """
