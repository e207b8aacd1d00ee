"""fringekit.library."""
