"""The simulator's error class and the checks shared by its modules."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from ..errors import EdeflareError

__all__ = [
    "SimError",
    "check_choice",
    "check_range",
    "dataclass_from_dict",
    "make_rng",
]

T = TypeVar("T")


class SimError(EdeflareError, ValueError):
    """A simulator input or option is invalid (the message says what was received)."""


def make_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """``numpy.random.default_rng(rng)``, with a clear error for anything else."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)):
        if rng is not None and int(rng) < 0:
            raise SimError(f"rng seed must be a non-negative int, got {rng!r}")
        return np.random.default_rng(rng)
    raise SimError(f"rng must be a numpy Generator, a non-negative int seed or None, got {rng!r}")


def check_range(
    name: str,
    value: Any,
    lo: float = -math.inf,
    hi: float = math.inf,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """``float(value)`` if it is a finite real in the interval, else :class:`SimError`."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SimError(f"{name} must be a number, got {value!r}") from None
    if isinstance(value, bool) or math.isnan(v):
        raise SimError(f"{name} must be a number, got {value!r}")
    bad_lo = v <= lo if lo_open else v < lo
    bad_hi = v >= hi if hi_open else v > hi
    if bad_lo or bad_hi or (math.isinf(v) and not (math.isinf(lo) or math.isinf(hi))):
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        raise SimError(f"{name} must lie in {left}{lo}, {hi}{right}, got {value!r}")
    return v


def check_interval(name: str, value: Any, like: tuple[Any, Any]) -> tuple[Any, Any]:
    """A ``(low, high)`` range with ``0 <= low <= high < inf``, cast like ``like``'s items.

    Examples
    --------
    >>> check_interval("travel_px", [0, 150.5], (0.0, 1.0))
    (0.0, 150.5)
    >>> check_interval("sources", (1, 3), (1, 2))
    (1, 3)
    """
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise SimError(f"{name} must be (low, high), got {value!r}") from None
    if not (0 <= lo <= hi and math.isfinite(hi)):
        raise SimError(f"{name} must be (low, high) with 0 <= low <= high, got {value!r}")
    cast = int if isinstance(like[0], int) else float
    return cast(lo), cast(hi)


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise :class:`SimError` listing them."""
    if value not in choices:
        raise SimError(f"{name} must be one of {', '.join(map(repr, choices))}; got {value!r}")
    return value


def dataclass_from_dict(cls: type[T], data: Mapping[str, Any], what: str | None = None) -> T:
    """Build the frozen dataclass ``cls`` from a mapping, rejecting unknown keys.

    Lists are turned into tuples (JSON has no tuples); nested dataclass fields
    are not handled here (the caller converts them first). The caller's
    mapping is not modified.
    """
    if not isinstance(data, Mapping):
        raise SimError(f"{what or cls.__name__} must be a mapping, got {type(data).__name__}")
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - names)
    if unknown:
        raise SimError(
            f"unknown key(s) {unknown} for {what or cls.__name__}; valid keys: {sorted(names)}"
        )
    kwargs = {k: (tuple(_tuples(v)) if isinstance(v, list) else v) for k, v in data.items()}
    return cls(**kwargs)


def _tuples(values: list[Any]) -> list[Any]:
    return [tuple(_tuples(v)) if isinstance(v, list) else v for v in values]
