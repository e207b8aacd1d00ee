"""Response libraries: a sensor solved once over a grid of loads, on a polar lattice of
through-thickness retarder fields; interpolated, turned and superposed for fast images
and for the inverse."""

from fringekit.library.build import build_library
from fringekit.library.store import Library, LoadedIndenter

__all__ = ["Library", "LoadedIndenter", "build_library"]
