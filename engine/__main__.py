"""``python -m engine`` runs the ``odmo`` CLI."""

import sys

from engine.cli import main

sys.exit(main())
