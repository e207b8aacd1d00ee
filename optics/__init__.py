"""Stage 3 of the pipeline: through-thickness optics, polariscopes, light and camera."""

from .camera import (
    Camera,
    Spectrum,
    colour_chart,
    light_source,
    monochrome_image,
    white_light_image,
    white_light_matrix,
    write_image,
)
from .fem import FEMStressField
from .fields import Boussinesq, DiametralDisc, StressField, TwistedStress, UniformStress
from .grid import PixelGrid, RaySamples, sample_points, sample_rays
from .jones import characteristic, integrate_path, retarder, rotator, secondary_principal
from .opticalmap import OpticalMap, integrate_layers, integrate_samples, optical_map
from .photo import (
    PhotoModel,
    crack_tip_field,
    indent_field,
    photograph,
    residual_birefringence,
    white_light_photograph,
)
from .polariscope import (
    SIX_STEPS,
    Arrangement,
    bright_field_circular,
    dark_field_circular,
    intensity,
    plane_polariscope,
    six_step_arrangements,
)
from .stressoptic import POLYCARBONATE_ASSUMED, PSM4_ASSUMED, StressOpticLaw

__all__ = [
    "POLYCARBONATE_ASSUMED",
    "PSM4_ASSUMED",
    "SIX_STEPS",
    "Arrangement",
    "Boussinesq",
    "Camera",
    "DiametralDisc",
    "FEMStressField",
    "OpticalMap",
    "PhotoModel",
    "PixelGrid",
    "RaySamples",
    "sample_points",
    "sample_rays",
    "Spectrum",
    "StressField",
    "StressOpticLaw",
    "TwistedStress",
    "UniformStress",
    "bright_field_circular",
    "characteristic",
    "colour_chart",
    "dark_field_circular",
    "integrate_path",
    "integrate_layers",
    "integrate_samples",
    "intensity",
    "light_source",
    "monochrome_image",
    "optical_map",
    "crack_tip_field",
    "indent_field",
    "photograph",
    "white_light_photograph",
    "residual_birefringence",
    "plane_polariscope",
    "retarder",
    "rotator",
    "secondary_principal",
    "six_step_arrangements",
    "white_light_image",
    "white_light_matrix",
    "write_image",
]
