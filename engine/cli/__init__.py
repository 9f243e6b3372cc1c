"""The ``odmo`` command line: parse, call the engine, print, exit code."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from engine import __version__
from engine.errors import OdmoError

# Each module defines ``register(subparsers)``; a sub-command's ``func(args) -> int`` does the work.
COMMAND_MODULES = (
    "engine.cli.io_commands",
    "engine.cli.model_commands",
    "engine.cli.latent_commands",
    "engine.cli.eval_commands",
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every sub-command registered."""
    parser = argparse.ArgumentParser(prog="odmo", description="ODMO Explorer engine.")
    parser.add_argument("--version", action="version", version=f"odmo {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``odmo``; returns the exit code (0 ok, 1 bad input, 2 usage, 130 interrupted)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    try:
        return int(args.func(args) or 0)
    except OdmoError as exc:
        print(f"odmo {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except (OSError, ValueError) as exc:
        print(f"odmo {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:
        print(
            f"odmo {args.command}: error: out of memory (an input or a requested size is too large "
            "for this machine)",
            file=sys.stderr,
        )
        return 1
    except KeyboardInterrupt:
        print(f"odmo {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
