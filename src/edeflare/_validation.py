"""Boundary checks shared by the package; every error names the argument and what it got.

Each check raises :class:`~edeflare.errors.ParameterError` by default, or the
error class a subpackage passes (the simulator's :class:`~edeflare.sim.SimError`
through :mod:`edeflare.sim._validation`). Validate once at a public boundary;
kernels trust their inputs.

Examples
--------
>>> check_int("fifo_size", 5, 1)
5
>>> check_int("fifo_size", 0, 1)
Traceback (most recent call last):
...
edeflare.errors.ParameterError: fifo_size must be an int >= 1, got 0
>>> check_choice("decoder", "keep", ("keep", "paper"))
'keep'
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from .errors import ParameterError

__all__ = [
    "check_choice",
    "check_int",
    "check_interval",
    "check_range",
    "dataclass_from_dict",
    "make_rng",
    "nested_from_dicts",
]

T = TypeVar("T")


def make_rng(
    rng: np.random.Generator | int | None, *, error: type[Exception] = ParameterError
) -> np.random.Generator:
    """``numpy.random.default_rng(rng)``, with a clear error for anything else."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)):
        if rng is not None and int(rng) < 0:
            raise error(f"rng seed must be a non-negative int, got {rng!r}")
        return np.random.default_rng(rng)
    raise error(f"rng must be a numpy Generator, a non-negative int seed or None, got {rng!r}")


def check_int(name: str, value: Any, lo: int, *, error: type[Exception] = ParameterError) -> int:
    """``int(value)`` if it is an int (not a bool) ``>= lo``, else an error naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise error(f"{name} must be an int >= {lo}, got {value!r}")
    return int(value)


def check_range(
    name: str,
    value: Any,
    lo: float = -math.inf,
    hi: float = math.inf,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    error: type[Exception] = ParameterError,
) -> float:
    """``float(value)`` if it is a finite real in the interval, else an error naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, got {value!r}") from None
    if isinstance(value, bool) or math.isnan(v):
        raise error(f"{name} must be a number, got {value!r}")
    bad_lo = v <= lo if lo_open else v < lo
    bad_hi = v >= hi if hi_open else v > hi
    if bad_lo or bad_hi or (math.isinf(v) and not (math.isinf(lo) or math.isinf(hi))):
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        raise error(f"{name} must lie in {left}{lo}, {hi}{right}, got {value!r}")
    return v


def check_interval(
    name: str, value: Any, like: tuple[Any, Any], *, error: type[Exception] = ParameterError
) -> tuple[Any, Any]:
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
        raise error(f"{name} must be (low, high), got {value!r}") from None
    if not (0 <= lo <= hi and math.isfinite(hi)):
        raise error(f"{name} must be (low, high) with 0 <= low <= high, got {value!r}")
    cast = int if isinstance(like[0], int) else float
    return cast(lo), cast(hi)


def check_choice(
    name: str, value: Any, choices: tuple[str, ...], *, error: type[Exception] = ParameterError
) -> str:
    """Return ``value`` if it is one of ``choices``, else an error listing them."""
    if value not in choices:
        raise error(f"{name} must be one of {', '.join(map(repr, choices))}; got {value!r}")
    return value


def dataclass_from_dict(
    cls: type[T],
    data: Mapping[str, Any],
    what: str | None = None,
    *,
    error: type[Exception] = ParameterError,
) -> T:
    """Build the frozen dataclass ``cls`` from a mapping, rejecting unknown keys.

    Lists are turned into tuples (JSON has no tuples); nested dataclass fields
    are not handled here (the caller converts them first). The caller's
    mapping is not modified.
    """
    if not isinstance(data, Mapping):
        raise error(f"{what or cls.__name__} must be a mapping, got {type(data).__name__}")
    names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - names)
    if unknown:
        raise error(
            f"unknown key(s) {unknown} for {what or cls.__name__}; valid keys: {sorted(names)}"
        )
    kwargs = {k: (tuple(_tuples(v)) if isinstance(v, list) else v) for k, v in data.items()}
    return cls(**kwargs)


def nested_from_dicts(
    data: dict[str, Any], nested: Mapping[str, Any], what: str = "recipe"
) -> dict[str, Any]:
    """Turn the mappings at ``nested``'s keys into their config types (``from_dict``), in place.

    An error of a nested config becomes a :class:`ParameterError` naming ``what`` and
    the key; values that are not mappings (configs already) are left as they are.

    Examples
    --------
    >>> from edeflare.sim.sensing import SensingConfig
    >>> d = nested_from_dicts({"sensing": {"enabled": True}}, {"sensing": SensingConfig})
    >>> d["sensing"].enabled, d["sensing"] == SensingConfig(enabled=True)
    (True, True)
    """
    from .errors import EdeflareError

    for key, config_type in nested.items():
        if key in data and isinstance(data[key], Mapping):
            try:
                data[key] = config_type.from_dict(data[key])
            except EdeflareError as exc:
                raise ParameterError(f"{what} {key!r}: {exc}") from None
    return data


def _tuples(values: list[Any]) -> list[Any]:
    return [tuple(_tuples(v)) if isinstance(v, list) else v for v in values]
