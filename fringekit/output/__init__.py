"""fringekit.output."""
