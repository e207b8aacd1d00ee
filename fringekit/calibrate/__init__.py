"""fringekit.calibrate."""
