"""fringekit.invert."""
