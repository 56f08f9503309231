"""Argument types shared by the commands."""

from __future__ import annotations

import argparse
import re
import warnings
from collections.abc import Iterable
from typing import Any

from .._registry import param_fields
from ..errors import EdeflareError, EventsError, ParameterError
from ..events import SensorSize, parse_sensor_size

__all__ = [
    "GROUP_HELP",
    "SIZE_HELP",
    "add_param_options",
    "crop_spec",
    "ms_to_us",
    "param_options",
    "sensor_size_arg",
    "user_message",
    "warn_outside_span",
]

SIZE_HELP = "sensor size WxH, for files that record none (else max+1, with a warning)"
GROUP_HELP = (
    "HDF5 event group to read from a file with several, e.g. input or gt of a paired sequence file"
)


def sensor_size_arg(text: str) -> SensorSize:
    """argparse type for ``WxH``."""
    try:
        return parse_sensor_size(text)
    except EventsError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def crop_spec(text: str) -> tuple[int, int, int, int] | SensorSize:
    """argparse type for ``WxH`` (centre crop) or ``X,Y,W,H``."""
    if "," in text:
        try:
            x0, y0, w, h = (int(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"crop must be WxH or X,Y,W,H, got {text!r}") from None
        return x0, y0, w, h
    return sensor_size_arg(text)


def ms_to_us(ms: float | None) -> int | None:
    """Milliseconds (or None) to integer microseconds."""
    return None if ms is None else round(ms * 1000)


def warn_outside_span(source: Any, origin_us: int, start_us: int, end_us: int | None) -> None:
    """Warn that ``[start_us, end_us)`` holds no events because it lies outside the recording.

    Times are shown in ms relative to ``origin_us`` (the recording's first
    event), as the ``--start-ms`` / ``--end-ms`` options take them. Nothing is
    said when the window lies inside the span (it is merely quiet).
    """
    span = source.time_span_us()
    if span is None:
        return
    first, last = span
    if start_us <= last and (end_us is None or end_us > first):
        return
    lo = (start_us - origin_us) / 1000
    window = f"{lo:g} ms on" if end_us is None else f"{lo:g}-{(end_us - origin_us) / 1000:g} ms"
    warnings.warn(
        f"{source.path}: the window {window} lies outside the recording, which spans "
        f"0-{(last - origin_us) / 1000:g} ms from its first event (times are relative "
        "to the recording's start, not absolute)",
        stacklevel=2,
    )


def add_param_options(
    parser: argparse.ArgumentParser, params: type, applies_to: Iterable[str] | None = None
) -> None:
    """Add a parameter dataclass's options (fields with ``cli`` metadata) as a group.

    The options default to ``SUPPRESS``: absent unless given, so a misplaced one
    is caught (:func:`param_options`). Help texts end with the default.

    ``applies_to``: the ``--method`` values that take these parameters (None:
    every run of the command). The parser records the group, so that an error
    about one of its parameters names the option (:func:`user_message`).
    """
    groups = parser.get_default(_PARAM_GROUPS) or ()
    methods = None if applies_to is None else tuple(applies_to)
    parser.set_defaults(**{_PARAM_GROUPS: (*groups, (params, methods))})
    group = parser.add_argument_group(getattr(params, "cli_title", params.__name__))
    for f, opt in param_fields(params):
        if opt is None:
            continue
        kwargs: dict[str, Any] = {"default": argparse.SUPPRESS, "help": opt.help_text(f.default)}
        if opt.kind == "flag":
            kwargs["action"] = "store_true"
        elif opt.kind == "bool":
            kwargs["action"] = argparse.BooleanOptionalAction
        else:
            if opt.choices is not None:
                kwargs["choices"] = list(opt.choices)
            else:
                kwargs["type"] = opt.type or type(f.default)
            if opt.metavar is not None:
                kwargs["metavar"] = opt.metavar
        group.add_argument(opt.flag, **kwargs)


def param_options(
    args: argparse.Namespace, params: type, method: str, applies_to: tuple[str, ...]
) -> dict[str, Any]:
    """The parameters of ``params`` given on the command line (only those given).

    An option given for a ``method`` it does not apply to is an error naming
    the methods it applies to.
    """
    out: dict[str, Any] = {}
    for f, opt in param_fields(params):
        if opt is None:
            continue
        value = getattr(args, opt.flag[2:].replace("-", "_"), None)
        if value is None:
            continue
        if method not in applies_to:
            flag = opt.flag if value is not False else "--no-" + opt.flag[2:]
            raise ParameterError(f"{flag} applies to --method {' or '.join(applies_to)}")
        out[f.name] = opt.to_param(value)
    return out


# ----------------------------------------------------------------------------- error messages

_PARAM_GROUPS = "_param_groups"  # the namespace default holding (dataclass, methods) pairs


def _option_names(
    args: argparse.Namespace, parser: argparse.ArgumentParser | None
) -> tuple[dict[str, tuple[str, str]], dict[str, tuple[str, str]]]:
    """The Python names of a command's options: ``{name: (flag, unit)}``, in two kinds.

    The first holds the fields of the parameter dataclasses that apply to this
    run (their ``--method``; :func:`add_param_options`); the second the command's
    own options by destination (``max_lag_ms`` for ``--max-lag-ms``), with
    ``X_us`` for an option ``--X-ms`` (unit ``"ms"``).
    """
    declared: dict[str, tuple[str, str]] = {}
    for params, methods in getattr(args, _PARAM_GROUPS, ()):
        if methods is not None and getattr(args, "method", None) not in methods:
            continue
        for f, opt in param_fields(params):
            if opt is not None:
                declared[f.name] = (opt.flag, opt.unit)
    own: dict[str, tuple[str, str]] = {}
    for action in parser._actions if parser is not None else ():
        flags = [s for s in action.option_strings if s.startswith("--")]
        if not flags or action.dest in (argparse.SUPPRESS, "help"):
            continue
        own[action.dest] = (flags[0], "")
        if action.dest.endswith("_ms"):
            own[action.dest[:-3] + "_us"] = (flags[0], "ms")
    return declared, own


def _name_pattern(name: str, anywhere: bool) -> re.Pattern[str]:
    """Where ``name`` stands as an identifier: not inside a word, an option, a path or quotes."""
    before = r"(?<![\w\-./\\'\"])" if anywhere else r"^"
    return re.compile(before + re.escape(name) + r"(?![\w\-/\\'\"]|\.\w)")


def name_options(
    message: str, declared: dict[str, tuple[str, str]], own: dict[str, tuple[str, str]]
) -> str:
    """``message`` with the Python names of options replaced by the options' flags.

    A declared parameter (``keep_threshold``) is replaced wherever it stands as
    an identifier; a command's own option too when its name looks like one
    (``max_lag_us``: an underscore or a digit), else only where it opens the
    message (``workers must be ...``), so that plain words stay words. A
    parameter kept in µs but given in ms (``merge_us``, ``--efr-merge-ms``)
    gets a note that the values shown are µs.

    Examples
    --------
    >>> declared = {"merge_us": ("--efr-merge-ms", "ms")}
    >>> name_options("merge_us must be >= 0, got -5000", declared, {})
    '--efr-merge-ms must be >= 0, got -5000 (in µs; --efr-merge-ms takes ms)'
    >>> own = {"workers": ("--workers", ""), "sequences": ("--sequences", "")}
    >>> name_options("workers must be >= 1; more workers than sequences", {}, own)
    '--workers must be >= 1; more workers than sequences'
    """
    names = {
        name: (flag, unit, bool(re.search(r"[_\d]", name))) for name, (flag, unit) in own.items()
    }
    names |= {name: (flag, unit, True) for name, (flag, unit) in declared.items()}
    in_ms: list[str] = []
    for name in sorted(names, key=len, reverse=True):  # longest first
        flag, unit, anywhere = names[name]
        message, count = _name_pattern(name, anywhere).subn(flag, message)
        if count and unit == "ms" and flag not in in_ms:
            in_ms.append(flag)
    if in_ms:
        in_ms.sort(key=message.index)  # as they appear
        message += f" (in µs; {', '.join(in_ms)} {'takes' if len(in_ms) == 1 else 'take'} ms)"
    return message


def user_message(
    exc: EdeflareError, args: argparse.Namespace, parser: argparse.ArgumentParser | None
) -> str:
    """The line to show for a user error of a command, options named as the user types them.

    A :class:`~edeflare.errors.ParameterError` raised by the library names
    parameters by their Python names; here they become the command's options
    (:func:`name_options`). Other errors (files, events) are shown unchanged.
    """
    if not isinstance(exc, ParameterError):
        return str(exc)
    return name_options(str(exc), *_option_names(args, parser))
