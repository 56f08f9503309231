"""Argument types shared by the commands."""

from __future__ import annotations

import argparse
import warnings
from typing import Any

from .._registry import param_fields
from ..errors import EventsError, ParameterError
from ..events import SensorSize, parse_sensor_size

__all__ = [
    "GROUP_HELP",
    "SIZE_HELP",
    "add_param_options",
    "crop_spec",
    "ms_to_us",
    "param_options",
    "sensor_size_arg",
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


def add_param_options(parser: argparse.ArgumentParser, params: type) -> None:
    """Add a parameter dataclass's options (fields with ``cli`` metadata) as a group.

    The options default to ``SUPPRESS``: absent unless given, so a misplaced one
    is caught (:func:`param_options`). Help texts end with the default.
    """
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
