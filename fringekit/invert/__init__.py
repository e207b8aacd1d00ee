"""The inverse: every indenter's position and load vector from one image and a response
library (detection, start, joint least squares, basin search, verdict)."""

from fringekit.invert.fit import InvertResult
from fringekit.invert.inversion import LOAD_COLUMNS, Inversion, invert
from fringekit.invert.verdict import InvertError

__all__ = ["LOAD_COLUMNS", "InvertError", "InvertResult", "Inversion", "invert"]
