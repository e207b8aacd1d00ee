"""Calibrations: the material fringe value from disc photographs (``calibrate --disc``),
load-to-fringe relations from a load path (``calibrate``), and the load they give back
for a measured map (``estimate``)."""

from fringekit.calibrate.disc import DiscCalibration, calibrate_disc

__all__ = ["DiscCalibration", "calibrate_disc"]
