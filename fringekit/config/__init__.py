"""fringekit.config."""
