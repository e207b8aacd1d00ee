"""The inverse: every indenter's position and load vector from one image and a response
library (detection, start, joint least squares, basin search, verdict)."""

from fringekit.inversion.fit import InvertResult
from fringekit.inversion.loads import LOAD_COLUMNS, Inversion, invert
from fringekit.inversion.verdict import InvertError

__all__ = ["LOAD_COLUMNS", "InvertError", "InvertResult", "Inversion", "invert"]
