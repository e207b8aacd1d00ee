"""``python -m fringekit`` runs the ``fringekit`` command."""

import sys

from fringekit.cli import main

sys.exit(main())
