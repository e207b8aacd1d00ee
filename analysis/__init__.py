"""Image analysis: fringe images -> fringe order, isoclinic and stress maps.

Works on image arrays and files only; it does not know whether an image came from a
camera or from :mod:`optics`, and imports none of the other stages (a contract checked
in CI). Reading images, masks, six-step phase shifting and unwrapping, RGB calibration
tables and searches, line profiles, registration of two maps, and the feature and fit
functions of load-to-fringe calibration.
"""

from .calibrate import calibrate_from_maps, estimate_load, load_calibration, save_calibration
from .channels import (
    AGREE_MIN,
    FLAT_NOISE,
    brightest_channel,
    channel_agreement,
    featureless,
    grey_channel,
    strongest_channel,
)
from .circles import Circle, disc_by_symmetry, find_disc, find_discs
from .compare import Comparison, Profile, circle_profile, compare_maps, line_profile
from .features import RADII_MM, fringe_features, radial_profile
from .images import (
    SIX_STEP_ORDER,
    Frame,
    image_noise_sd,
    load_image,
    load_six_step,
    normalise,
    read_pixels,
)
from .masks import border_anchor, check_mask, circle_mask, exclude_circle, polygon_mask
from .mono import MonoResult, mono_order
from .phase import (
    Resolution,
    SixStep,
    principal_stress_difference,
    resolve_ambiguity,
    six_step,
    subtract_reference,
    wrap,
)
from .rgb import (
    MAX_COLOUR_ERROR,
    MIN_COLOUR_SPREAD,
    CalibrationTable,
    RGBResult,
    colour_spread,
    search,
    search_refined,
)
from .rgb_adapt import (
    ADAPT_MAX_ORDER,
    MIN_COLOUR_SPEED,
    AdaptedRGBResult,
    ColourAdaptation,
    colour_reach,
    fit_adaptation,
    search_adapted,
)
from .unwrap import FringeOrderMap, count_fringe_order, unwrap_fringe_order

__all__ = [
    "RADII_MM",
    "Circle",
    "disc_by_symmetry",
    "find_disc",
    "find_discs",
    "MonoResult",
    "grey_channel",
    "channel_agreement",
    "strongest_channel",
    "brightest_channel",
    "featureless",
    "AGREE_MIN",
    "FLAT_NOISE",
    "mono_order",
    "calibrate_from_maps",
    "estimate_load",
    "fringe_features",
    "load_calibration",
    "radial_profile",
    "save_calibration",
    "SIX_STEP_ORDER",
    "CalibrationTable",
    "MAX_COLOUR_ERROR",
    "MIN_COLOUR_SPREAD",
    "colour_spread",
    "Comparison",
    "Frame",
    "FringeOrderMap",
    "border_anchor",
    "count_fringe_order",
    "Profile",
    "RGBResult",
    "Resolution",
    "SixStep",
    "check_mask",
    "circle_mask",
    "circle_profile",
    "compare_maps",
    "exclude_circle",
    "line_profile",
    "load_image",
    "load_six_step",
    "image_noise_sd",
    "normalise",
    "read_pixels",
    "polygon_mask",
    "principal_stress_difference",
    "resolve_ambiguity",
    "search",
    "search_refined",
    "search_adapted",
    "fit_adaptation",
    "colour_reach",
    "ColourAdaptation",
    "AdaptedRGBResult",
    "ADAPT_MAX_ORDER",
    "MIN_COLOUR_SPEED",
    "six_step",
    "subtract_reference",
    "unwrap_fringe_order",
    "wrap",
]
