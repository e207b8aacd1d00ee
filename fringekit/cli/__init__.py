"""The ``fringekit`` command: a thin layer that reads inputs, calls the API and writes."""

from fringekit.cli.main import main

__all__ = ["main"]
