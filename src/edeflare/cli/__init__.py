"""The ``edeflare`` command line: one module per command, each a thin layer over the library.

Each command module has ``add_parser(sub, **kwargs)`` (register its
sub-parser, with ``set_defaults(func=run)``) and ``run(args) -> int``.

Exit codes: 0 success; 1 a user error (a bad option, file or value: one line
``edeflare: error: ...`` on stderr, nothing half-written); 130 interrupted;
70 an internal error (a bug: the traceback, then a line asking to report it).
"""

from __future__ import annotations

import argparse
import sys
import traceback
import warnings
from collections.abc import Sequence

from .._version import __version__
from ..errors import EdeflareError
from . import (
    ablate,
    benchmark,
    bundle,
    convert,
    deflare,
    demo,
    evaluate,
    export,
    info,
    pair,
    reconstruct,
    score,
    simulate,
    train,
    view,
)

__all__ = ["EXIT_INTERNAL", "build_parser", "main"]

EXIT_INTERNAL = 70  # EX_SOFTWARE of sysexits.h: a bug, not the user's input


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line and exit 1, like every user error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(1, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


# Order of appearance in --help.
COMMANDS = (
    info,
    convert,
    view,
    deflare,
    evaluate,
    score,
    benchmark,
    reconstruct,
    simulate,
    pair,
    train,
    bundle,
    export,
    ablate,
    demo,
)


def _show_warning(message: Warning | str, *args: object, **kwargs: object) -> None:
    """Warnings at the command line: one line each, ``edeflare: warning: ...``."""
    print(f"edeflare: warning: {message}", file=sys.stderr)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``edeflare`` command."""
    parser = _Parser(
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
        with warnings.catch_warnings():
            warnings.simplefilter("default")  # shown as one line, never raised
            warnings.showwarning = _show_warning
            return int(args.func(args))
    except EdeflareError as exc:
        print(f"edeflare: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("edeflare: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:  # the system refused: a full disk, a folder without permission
        print(f"edeflare: error: {exc}", file=sys.stderr)
        return 1
    except Exception:
        traceback.print_exc()
        print(
            f"edeflare: internal error in 'edeflare {args.command}' (edeflare {__version__}): "
            "this is a bug, not a problem with your input. Please report it with the "
            "traceback above and the command you ran.",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
