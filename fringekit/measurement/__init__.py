"""Analyse fringe images: six phase steps, one white-light colour image or one monochrome
photograph -> a fringe-order map with the pixels the method stands behind; comparison
with a prediction."""

from fringekit.measurement.options import MonoOptions, PhaseOptions, Region, RGBOptions
from fringekit.measurement.order import Analysis, analyze, choose_method

__all__ = [
    "Analysis",
    "MonoOptions",
    "PhaseOptions",
    "RGBOptions",
    "Region",
    "analyze",
    "choose_method",
]
