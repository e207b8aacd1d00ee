"""optics stage."""
