"""fea stage."""
