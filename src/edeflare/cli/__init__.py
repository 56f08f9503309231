"""The ``edeflare`` command line: one module per command, each a thin layer over the library.

Each command module has ``add_parser(sub, **kwargs)`` (register its
sub-parser, with ``set_defaults(func=run)``) and ``run(args) -> int``. User
errors print one line (``edeflare: error: ...``) to stderr and exit 1;
nothing is half-written.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .._version import __version__
from ..errors import EdeflareError
from . import (
    ablate,
    benchmark,
    convert,
    deflare,
    demo,
    evaluate,
    info,
    pair,
    score,
    simulate,
    train,
    view,
)

__all__ = ["build_parser", "main"]

# Order of appearance in --help.
COMMANDS = (
    info,
    convert,
    view,
    deflare,
    evaluate,
    score,
    benchmark,
    simulate,
    pair,
    train,
    ablate,
    demo,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``edeflare`` command."""
    parser = argparse.ArgumentParser(
        prog="edeflare",
        description="Remove lens flare from event-camera data (E-Deflare).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"edeflare {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``edeflare`` console script; returns the exit code."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except EdeflareError as exc:
        print(f"edeflare: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("edeflare: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
