"""fringekit.sweep."""
