"""Command-line options shared by several ``odmo`` commands."""

from __future__ import annotations

import argparse


def add_up_axis(parser: argparse.ArgumentParser) -> None:
    """``--up-axis y|z``: the up axis of the input files, which are turned Y-up when it is z."""
    parser.add_argument(
        "--up-axis",
        choices=("y", "z"),  # engine.motion.axes.UP_AXES, not imported here to keep `odmo --help` quick
        default="y",
        help="up axis of the input motion files (BVH is Y-up; some tools and raw AMASS joints are Z-up)",
    )


def positive_int(text: str) -> int:
    """An argparse type: a whole number of at least 1."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value
