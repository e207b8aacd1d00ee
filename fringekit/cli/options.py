"""What the subcommands share: value types that check ranges at the edge, a one-line-error
parser, the options of the commands that solve, and a config with ``--set`` overrides.

Each type turns the text of one option into a number or raises
:class:`argparse.ArgumentTypeError` with the value and what is allowed; argparse adds the
option's name, so a bad value reads ``argument --pixel-mm: 0 is not allowed; give a
finite number > 0``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import sys
from collections.abc import Callable

from fringekit.config.files import apply_overrides, check_number, load_config, tomllib
from fringekit.config.schema import Key, schema_key
from fringekit.errors import ConfigError
from fringekit.library.build import MAX_RATIO

__all__ = [
    "DISC_DIAMETER_MM",
    "MAX_ORDER",
    "PIXEL_MM",
    "RADIUS_PX",
    "ROTATION_DEG",
    "SHEAR_RATIO",
    "SMOOTH_PX",
    "WINDOW",
    "Parser",
    "at_least_one",
    "at_least_zero",
    "finite",
    "fraction",
    "in_range",
    "nonnegative",
    "overrides",
    "pixel",
    "positive",
    "origin_px_option",
    "residual_steps_option",
    "run_options",
]


#: A negative number in float() notation: -12, -1.5, -.5, -1e6, -2.5E-3, -inf, -nan.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*(e[-+]?\d+)?|\.\d+(e[-+]?\d+)?|inf(inity)?|nan)$", re.I)


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit status 2), and that
    reads a negative number in any float notation (``-1e6``, ``-.5``, ``-inf``) as a value,
    not an option (argparse itself knows only ``-12`` and ``-1.5``)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # argparse's hook for telling negative numbers from options (a private attribute,
        # the same name in Python 3.10-3.13): a value whenever float() would take it
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str):  # noqa: D102 - argparse's hook
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


def _number(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give a finite number")
    return v


def finite(text: str) -> float:
    """Any finite number."""
    return _number(text)


def pixel(text: str) -> tuple[float, float]:
    """A pixel "ROW,COL" (finite numbers), a polygon vertex."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give ROW,COL (e.g. 10,20)")
    return (_number(parts[0]), _number(parts[1]))


def positive(text: str) -> float:
    """A finite number > 0."""
    v = _number(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give a finite number > 0")
    return v


def nonnegative(text: str) -> float:
    """A finite number >= 0."""
    v = _number(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give a finite number >= 0")
    return v


def fraction(text: str) -> float:
    """A number in [0, 1]."""
    v = _number(text)
    if not 0 <= v <= 1:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give a number in [0, 1]")
    return v


#: The ranges of the options that set no config key (docs/cli.md lists them). An option
#: that sets a config key takes that key's range from the schema (:func:`in_range`).
PIXEL_MM = Key(
    None,
    "pixel pitch on the sheet: 0.1 um (below any lens's resolution) to 10 mm",
    "mm",
    lo=1e-4,
    hi=10,
)
DISC_DIAMETER_MM = Key(None, "diameter of a calibration disc", "mm", lo=1, hi=500)
RADIUS_PX = Key(None, "disc radius in a photograph", "px", lo=2, hi=1e5)
ROTATION_DEG = Key(None, "rotation of a measured map", "deg", lo=-360, hi=360)
MAX_ORDER = Key(None, "highest fringe order of a colour chart", "", lo=0, hi=100, lo_open=True)
WINDOW = Key(None, "refined window of a colour match (fringe)", "", lo=0, hi=10, lo_open=True)
SMOOTH_PX = Key(None, "Gaussian smoothing", "px", lo=0, hi=100)
#: A library's tangential / normal load ratios (library build).
SHEAR_RATIO = Key(None, "tangential over normal load of a library", "", lo=0, hi=MAX_RATIO)


def in_range(key: str | Key, *, positive: bool = False) -> Callable[[str], float]:
    """An option's type: a number in the range of config key ``key`` (its
    :class:`~fringekit.config.schema.Key` in the schema: options and configs share one
    range), or of a Key made for an option that sets no config key. ``positive`` leaves
    out 0 (a load of a grid, say).

    A value outside reads ``argument --thickness-mm: 1e-300 is not allowed; allowed range
    [0.01, 100] mm (the range of config key sheet.thickness_mm)``.
    """
    k = schema_key(key) if isinstance(key, str) else key
    if positive and k.lo == 0:
        k = dataclasses.replace(k, lo_open=True)
    source = f" (the range of config key {key})" if isinstance(key, str) else ""

    def parse(text: str) -> float:
        v = _number(text)
        try:
            return check_number(text, v, k)
        except ConfigError:
            raise argparse.ArgumentTypeError(
                f"{text} is not allowed; {k.allowed()}{source}"
            ) from None

    parse.__name__ = key if isinstance(key, str) else k.help
    return parse


def _whole(text: str, minimum: int) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < minimum:
        raise argparse.ArgumentTypeError(f"{text} is not allowed; give a whole number >= {minimum}")
    return v


def at_least_one(text: str) -> int:
    """A whole number >= 1."""
    return _whole(text, 1)


def at_least_zero(text: str) -> int:
    """A whole number >= 0."""
    return _whole(text, 0)


def origin_px_option(
    p: argparse.ArgumentParser,
    text: str = "image pixel of the sensor origin (default: the image centre)",
) -> None:
    """``--origin-px ROW COL``: the image pixel of the sheet's origin (two finite numbers,
    default None), as the commands that place images on the sheet take it; ``text`` is
    its help."""
    p.add_argument(
        "--origin-px", nargs=2, type=finite, metavar=("ROW", "COL"), default=None, help=text
    )


def residual_steps_option(p: argparse.ArgumentParser) -> None:
    """``--residual-steps STEP...``: the six phase steps of the sensor at rest that give a
    mono measurement the sheet's residual retarder (``invert``, ``track``)."""
    p.add_argument(
        "--residual-steps",
        nargs="+",
        default=None,
        metavar="STEP",
        help="mono: the six phase steps of the sensor at rest (or 6n), taken once with "
        "the plates stepped: the sheet's residual retarder, put into the model (for a "
        "residual beyond what a rest frame's subtraction serves, about 0.05 fringe)",
    )


def run_options(p: argparse.ArgumentParser) -> None:
    """Options of the commands that mesh and solve a config (predict, calibrate)."""
    p.add_argument("--out", default=None, help="output folder (default fringekit-out/<case>)")
    p.add_argument(
        "--set",
        action="append",
        metavar="TABLE.KEY=VALUE",
        help="override one config value, e.g. --set optics.pixels=128 (repeatable)",
    )
    p.add_argument("--cache-dir", default=None, help="mesh and solution cache root")
    p.add_argument("--no-cache", action="store_true", help="re-mesh and re-solve")
    p.add_argument("--quiet", action="store_true", help="no progress output")


def overrides(cfg_source, sets: list[str], base: dict | None = None) -> dict:
    """Effective config from CONFIG (or ``base``) plus ``--set table.key=value`` overrides."""
    base = load_config(cfg_source) if base is None or cfg_source is not None else base
    values = {}
    for item in sets:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {item!r} is not allowed; use --set table.key=value")
        try:
            values[key.strip()] = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            values[key.strip()] = text.strip()  # a bare word is a string
    return apply_overrides(base, values) if values else base
