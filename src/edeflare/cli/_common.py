"""Argument types shared by the commands."""

from __future__ import annotations

import argparse

from ..errors import EventsError
from ..events import SensorSize, parse_sensor_size

__all__ = ["GROUP_HELP", "SIZE_HELP", "crop_spec", "ms_to_us", "sensor_size_arg"]

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
