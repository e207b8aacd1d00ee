"""fringekit.predict."""
