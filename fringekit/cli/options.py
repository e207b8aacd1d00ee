"""Command-line value types that check ranges at the edge, and a one-line-error parser.

Each type turns the text of one option into a number or raises
:class:`argparse.ArgumentTypeError` with the value and what is allowed; argparse adds the
option's name, so a bad value reads ``argument --pixel-mm: 0 is not allowed; give a
finite number > 0``.
"""

from __future__ import annotations

import argparse
import math
import sys

__all__ = [
    "Parser",
    "at_least_one",
    "at_least_zero",
    "finite",
    "fraction",
    "nonnegative",
    "pixel",
    "positive",
]


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit status 2)."""

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
