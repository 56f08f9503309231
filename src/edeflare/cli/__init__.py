"""The ``edeflare`` command line: one module per command, each a thin layer over the library.

Each command module has ``add_parser(sub, **kwargs)`` (register its
sub-parser, with ``set_defaults(func=run)``) and ``run(args) -> int``.

Exit codes: 0 success; 1 a user error (a bad option, file or value: one line
``edeflare: error: ...`` on stderr, nothing half-written); 130 interrupted;
70 an internal error (a bug: the traceback, then a line asking to report it).

A command whose rerun resumes says so with ``set_defaults(resumes=True)``: an
interrupted run then ends with ``edeflare: interrupted; rerun to resume``.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
import traceback
import warnings
from collections.abc import Sequence

from .._version import __version__
from ..errors import EdeflareError
from . import (
    _common,
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
    train_head,
    tune_head,
    view,
)

__all__ = ["EXIT_INTERNAL", "build_parser", "main"]

EXIT_INTERNAL = 70  # EX_SOFTWARE of sysexits.h: a bug, not the user's input


_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")  # a negative number, not an option


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line and exit 1, like every user error.

    The line starts ``edeflare: error:`` whichever (sub)command failed, and ends
    with a pointer to that command's ``--help``. An unknown option is named,
    with the closest option of the command that was meant.
    """

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(1, f"edeflare: error: {message} (see {self.prog} --help)\n")

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        namespace, extras = self.parse_known_args(args, namespace)
        if extras:  # reported by the command they were given to
            parser = _subcommand(self, getattr(namespace, "command", None)) or self
            parser.error(_unrecognized(parser, extras))
        return namespace


def _subcommand(
    parser: argparse.ArgumentParser, name: str | None
) -> argparse.ArgumentParser | None:
    """The sub-parser of command ``name`` (None: no such command)."""
    for action in parser._actions:  # argparse offers no public way to list sub-parsers
        if isinstance(action, argparse._SubParsersAction):
            return action.choices.get(name) if name is not None else None
    return None


def _unrecognized(parser: argparse.ArgumentParser, extras: Sequence[str]) -> str:
    """What is wrong with the arguments ``parser`` did not recognise.

    The first unknown option (``--name`` or ``--name=value``) is named with the
    closest option of ``parser`` (``difflib``), if one is close enough; stray
    values are listed as argparse lists them.
    """
    option = next((a for a in extras if a[:1] == "-" and a != "-" and not _NUMBER.match(a)), None)
    if option is None:
        return f"unrecognized arguments: {' '.join(extras)}"
    name = option.split("=", 1)[0]
    long = name.startswith("--")
    valid = sorted(
        {
            s
            for action in parser._actions
            for s in action.option_strings
            if s.startswith("--") == long
        }
    )
    close = difflib.get_close_matches(name, valid, n=1)
    return f"unrecognized option {name}" + (f"; did you mean {close[0]}?" if close else "")


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
    train_head,
    tune_head,
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


def _caused_by_interrupt(exc: BaseException) -> bool:
    """True when a ``KeyboardInterrupt`` lies in ``exc``'s chain of causes and contexts."""
    seen: set[int] = set()
    todo: list[BaseException | None] = [exc]
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return False


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``edeflare`` console script; returns the exit code."""
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:  # while starting up: nothing was written yet
        print("edeflare: interrupted", file=sys.stderr)
        return 130
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")  # shown as one line, never raised
            # Python's own default: a Ctrl-C between open() and its with-block leaves a
            # file to the collector, which warns; the process closes it, no user's concern
            warnings.simplefilter("ignore", ResourceWarning)
            warnings.showwarning = _show_warning
            return int(args.func(args))
    except KeyboardInterrupt:
        return _interrupted(args)
    except Exception as exc:
        if _caused_by_interrupt(exc):  # Ctrl-C inside compiled code, wrapped in its error
            return _interrupted(args)
        if isinstance(exc, EdeflareError):
            message = _common.user_message(exc, args, _subcommand(parser, args.command))
            print(f"edeflare: error: {message}", file=sys.stderr)
            return 1
        if isinstance(exc, OSError):  # the system refused: a full disk, a forbidden folder
            print(f"edeflare: error: {exc}", file=sys.stderr)
            return 1
        traceback.print_exc()
        print(
            f"edeflare: internal error in 'edeflare {args.command}' (edeflare {__version__}): "
            "this is a bug, not a problem with your input. Please report it with the "
            "traceback above and the command you ran.",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


def _interrupted(args: argparse.Namespace) -> int:
    """Say that the command was interrupted (and how to resume it, if it resumes): 130."""
    resume = "; rerun to resume" if getattr(args, "resumes", False) else ""
    print(f"edeflare: interrupted{resume}", file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
