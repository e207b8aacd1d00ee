"""fringekit.analyze."""
