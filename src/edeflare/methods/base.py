"""The method interface and registry: every de-flaring method is a :class:`Method` made by name.

A method is a callable ``method(events, sensor_size, *, rng=None) -> events``
whose work is done by a :class:`Streamer` (its state over one stream), so that
one pass in memory and a stream of windows give the same result.

Examples
--------
>>> from edeflare.methods import create_method
>>> create_method("pfd-b", window_us=25_000).name
'pfd-b'
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from .._registry import Registry
from ..errors import ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size, concat_events

__all__ = [
    "METHODS",
    "Method",
    "Streamer",
    "create_method",
    "deflare",
    "list_methods",
    "method_parameters",
    "register_method",
]

MethodFactory = Callable[..., "Method"]
METHODS: Registry[MethodFactory] = Registry("method")
"""The registered methods: name -> factory (with its parameter dataclass, where declared)."""
EMPTY = np.zeros(0, dtype=EVENT_DTYPE)


class Streamer:
    """A method's state over one stream: feed windows in time order, then flush.

    ``process(events, until_us)`` receives the next sorted events, all before
    ``until_us``, with the promise that every later event is at or after
    ``until_us``; it returns the outputs that became final. ``ordered``
    streamers return sorted outputs, each call's at or after the previous
    call's; others (EFR, whose outputs are stamped in the past) return them in
    emission order and tell, through :meth:`safe_time_us`, the time before
    which no later output can fall.
    """

    ordered: bool = True

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        """Consume sorted events (all ``< until_us``); return the outputs now final."""
        raise NotImplementedError

    def flush(self) -> np.ndarray:
        """End of stream: return the outputs still held."""
        return EMPTY.copy()

    def safe_time_us(self, until_us: int) -> int:
        """No output of a later call will be earlier than this (unordered streamers)."""
        return int(until_us)


class Method:
    """A de-flaring method: ``method(events, sensor_size, *, rng=None) -> events``.

    Subclasses implement :meth:`streamer`; the one-pass call is the same
    streamer fed the whole stream, so the two always agree. Methods whose
    original computes something over the whole input first (EFR's bias) set
    ``needs_prepass`` and implement :meth:`prepare`.
    """

    name: str = ""
    needs_prepass: bool = False

    def __init__(self, **params: Any) -> None:
        self.params = params

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{type(self).__name__}({args})"

    def prepare(self, chunks: Iterable[np.ndarray], sensor_size: SensorSize) -> Any:
        """A first pass over the whole input (only when ``needs_prepass``)."""
        return None

    def streamer(
        self,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None = None,
        prepared: Any = None,
    ) -> Streamer:
        """A fresh state for one stream on ``sensor_size``."""
        raise NotImplementedError

    def __call__(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> np.ndarray:
        """De-flare a whole stream in memory; returns a new sorted stream."""
        check_events(events, sensor_size)
        size = check_sensor_size(sensor_size)
        prepared = self.prepare([events], size) if self.needs_prepass else None
        streamer = self.streamer(size, rng=rng, prepared=prepared)
        until = int(events["t"][-1]) + 1 if events.size else 0
        parts = [streamer.process(events, until), streamer.flush()]
        out = concat_events(parts)
        if not streamer.ordered:
            out = out[np.argsort(out["t"], kind="stable")]
        return out


def register_method(
    name: str, factory: MethodFactory | None = None, *, params: type | None = None
) -> Any:
    """Register a method factory under ``name`` (usable as a decorator).

    The factory returns a :class:`Method`. Its parameters are the fields of
    ``params`` (a frozen dataclass declared next to the algorithm, whose
    ``cli`` metadata also makes the command-line options), else its keyword
    parameters. Registering a name twice is an error.

    Examples
    --------
    >>> @register_method("doc-identity")
    ... def _make(scale: int = 1) -> Method:
    ...     return create_method("raw")
    >>> "doc-identity" in list_methods()
    True
    >>> register_method("doc-identity", _make)
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: method 'doc-identity' is already registered
    >>> _unregister("doc-identity")
    """

    def decorate(fn: MethodFactory) -> MethodFactory:
        if not callable(fn):
            raise ParameterError(f"the factory of method {name!r} must be callable")
        return METHODS.register(name, fn, params=params)

    if not isinstance(name, str) or not name:
        raise ParameterError(f"a method name must be a non-empty string, got {name!r}")
    return decorate if factory is None else decorate(factory)


def _unregister(name: str) -> None:
    """Remove a registered method (for tests and examples)."""
    METHODS.unregister(name)


def list_methods() -> list[str]:
    """Names of the registered methods, sorted.

    Examples
    --------
    >>> "efr" in list_methods()
    True
    """
    return METHODS.names()


def create_method(name: str, **params: Any) -> Method:
    """Make a method by name with its parameters.

    Raises
    ------
    ParameterError
        (a ``ValueError``) for an unknown name or parameter, listing the valid
        ones, or an invalid value.

    Examples
    --------
    >>> create_method("efr", frequency_hz=100)  # doctest: +ELLIPSIS
    EFRMethod(frequency_hz=100, rho1=0.6, ...)
    >>> create_method("efr", frequency=100)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: method 'efr' has no parameter 'frequency'; valid: ...
    """
    method = METHODS.create(name, **params)
    if not isinstance(method, Method):
        raise ParameterError(f"the factory of method {name!r} returned {type(method).__name__}")
    method.name = name
    return method


def method_parameters(name: str) -> dict[str, Any]:
    """The parameters of a registered method and their defaults.

    Examples
    --------
    >>> method_parameters("voxel")
    {'window_us': 20000, 'bins': 8}
    """
    return METHODS.parameters(name)


def param_values(params: Any) -> dict[str, Any]:
    """The fields of a parameter dataclass as a dict (arrays not copied)."""
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}


def deflare(
    events: np.ndarray,
    sensor_size: SensorSize,
    method: str | Method,
    *,
    rng: np.random.Generator | int | None = None,
    **params: Any,
) -> np.ndarray:
    """De-flare an in-memory stream with a method given by name (and parameters) or object.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5_000, 30_000], [1, 2, 3], [0, 0, 0], [1, 0, 1])
    >>> deflare(ev, (4, 1), "efr", frequency_hz=50)["t"].tolist()  # all in the warm-up
    [0, 5000]
    """
    if isinstance(method, Method):
        if params:
            raise ParameterError("pass parameters either to create_method or here, not both")
        m = method
    else:
        m = create_method(method, **params)
    return m(events, sensor_size, rng=rng)
