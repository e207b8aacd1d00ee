"""Analyse fringe images: six phase steps, one white-light colour image or one monochrome
photograph -> a fringe-order map with the pixels the method stands behind; comparison
with a prediction."""

from fringekit.measurement.order import (
    Analysis,
    MonoOptions,
    PhaseOptions,
    Region,
    RGBOptions,
    analyze,
    choose_method,
)

__all__ = [
    "Analysis",
    "MonoOptions",
    "PhaseOptions",
    "RGBOptions",
    "Region",
    "analyze",
    "choose_method",
]
