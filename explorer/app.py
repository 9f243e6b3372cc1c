"""Entry point of ``odmo-explorer``."""

from __future__ import annotations

import sys


def main() -> int:
    """Launch the explorer (placeholder until the app lands)."""
    print("odmo-explorer: the explorer window is not built yet; use the `odmo` CLI.", file=sys.stderr)
    return 0
