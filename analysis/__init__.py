"""Stage 4 of the pipeline: fringe images -> fringe order, isoclinic and stress maps.

Works on image arrays and files only; it does not know whether an image came from a
camera or from :mod:`optics`.
"""

from .compare import Comparison, Profile, compare_maps, comparison_figure, line_profile
from .images import SIX_STEP_ORDER, Frame, load_image, load_six_step, normalise
from .masks import check_mask, circle_mask, exclude_circle, polygon_mask
from .phase import (
    FringeOrderMap,
    Resolution,
    SixStep,
    principal_stress_difference,
    resolve_ambiguity,
    six_step,
    unwrap_fringe_order,
    wrap,
)
from .rgb import CalibrationTable, RGBResult, search, search_refined

__all__ = [
    "SIX_STEP_ORDER",
    "CalibrationTable",
    "Comparison",
    "Frame",
    "FringeOrderMap",
    "Profile",
    "RGBResult",
    "Resolution",
    "SixStep",
    "check_mask",
    "circle_mask",
    "compare_maps",
    "comparison_figure",
    "exclude_circle",
    "line_profile",
    "load_image",
    "load_six_step",
    "normalise",
    "polygon_mask",
    "principal_stress_difference",
    "resolve_ambiguity",
    "search",
    "search_refined",
    "six_step",
    "unwrap_fringe_order",
    "wrap",
]
