"""De-flaring as a tonic transform: :class:`Deflare` in ``tonic.transforms.Compose``.

tonic (the neuromorphic datasets and transforms library) holds a sample's
events in a numpy structured array with fields ``x, y, t, p`` in any order
and of varying dtypes (``t`` int64 or float, ``p`` bool, 0/1 or -1/+1), and
a sensor size ``(W, H, P)``. :func:`from_structured` converts such an array
to edeflare's :data:`~edeflare.events.EVENT_DTYPE`, :func:`to_structured`
converts back to the input's own layout, and :class:`Deflare` runs a method
between the two. Nothing here imports tonic: the transform works on any
array of that shape, with or without tonic installed (the ``tonic`` extra).

Examples
--------
>>> import numpy as np
>>> from edeflare.transforms import Deflare
>>> layout = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<f8"), ("p", "?")])
>>> ev = np.array([(1, 1, 0.0, True), (2, 1, 10.0, False)], dtype=layout)
>>> out = Deflare((4, 4, 2), "raw")(ev)
>>> out.dtype == layout, out.tolist()
(True, [(1, 1, 0.0, True), (2, 1, 10.0, False)])
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import EventsError, ParameterError
from .events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size

if TYPE_CHECKING:  # pragma: no cover
    from .methods import Method

__all__ = ["Deflare", "from_structured", "to_structured"]

_FIELDS = ("x", "y", "t", "p")
_U16_MAX = np.iinfo(np.uint16).max


def _structured(events: Any) -> np.ndarray:
    """``events`` if it is a 1-D structured array with exactly the fields x, y, t, p."""
    if not isinstance(events, np.ndarray) or events.dtype.names is None:
        got = events.dtype if isinstance(events, np.ndarray) else type(events).__name__
        raise EventsError(
            f"events must be a structured array with fields x, y, t, p (tonic's layout), got {got}"
        )
    names = set(events.dtype.names)
    if names != set(_FIELDS):
        missing = [f for f in _FIELDS if f not in names]
        extra = sorted(names - set(_FIELDS))
        what = "; ".join(
            part
            for part in (
                f"missing {', '.join(missing)}" if missing else "",
                f"unexpected {', '.join(extra)}" if extra else "",
            )
            if part
        )
        raise EventsError(
            f"events must have exactly the fields x, y, t, p, got {events.dtype.names} ({what})"
        )
    if events.ndim != 1:
        raise EventsError(f"events must be one-dimensional, got shape {events.shape}")
    return events


def _whole(name: str, values: np.ndarray, lo: int, hi: int, unit: str = "") -> np.ndarray:
    """``values`` as int64, rejecting NaN, fractions and values outside ``[lo, hi]``."""
    kind = values.dtype.kind
    if kind == "b":
        return values.astype(np.int64)
    if kind == "f":
        bad = ~np.isfinite(values) | (values != np.round(values))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise EventsError(
                f"{name} must hold whole numbers{unit}, got {values[i]!r} at index {i}"
                + ("; scale or round the times to microseconds first" if name == "t" else "")
            )
    elif kind not in "iu":
        raise EventsError(f"field {name} must be numeric or bool, got dtype {values.dtype}")
    if values.size and (values.min() < lo or values.max() > hi):
        i = int(np.flatnonzero((values < lo) | (values > hi))[0])
        raise EventsError(f"{name} must lie in [{lo}, {hi}], got {values[i]!r} at index {i}")
    return values.astype(np.int64)


def from_structured(events: np.ndarray) -> np.ndarray:
    """Convert tonic-style events (fields ``x, y, t, p``, any order and dtypes) to edeflare's.

    ``t`` must be whole microseconds (integers, or floats holding whole
    numbers); ``p`` bool, 0/1 or -1/+1 (True, 1, +1 = ON). Unsorted input is
    sorted stably by ``t`` (tonic's samples usually are sorted already).

    Parameters
    ----------
    events : numpy.ndarray
        A 1-D structured array with exactly the fields ``x, y, t, p``; not
        modified.

    Returns
    -------
    numpy.ndarray
        A new stream of :data:`~edeflare.events.EVENT_DTYPE`, sorted by ``t``.

    Raises
    ------
    EventsError
        Another kind of array, missing or extra fields, NaN or fractional
        values, negative coordinates, polarities other than 0/1/-1 (or
        mixing 0 and -1).

    Examples
    --------
    >>> import numpy as np
    >>> layout = np.dtype([("t", "<i8"), ("x", "<i8"), ("y", "<i8"), ("p", "i1")])
    >>> ev = np.array([(20, 1, 2, -1), (10, 3, 4, 1)], dtype=layout)
    >>> from_structured(ev).tolist()   # sorted by t; p -1 -> 0 (OFF)
    [(10, 3, 4, 1), (20, 1, 2, 0)]
    """
    events = _structured(events)
    t = _whole("t", events["t"], np.iinfo(np.int64).min, np.iinfo(np.int64).max, " of µs")
    x = _whole("x", events["x"], 0, _U16_MAX)
    y = _whole("y", events["y"], 0, _U16_MAX)
    p = _whole("p", events["p"], -1, 1)
    if (p == -1).any() and (p == 0).any():
        raise EventsError("p mixes 0 and -1: use either 0/1 or -1/+1 for OFF")
    out = np.empty(events.size, dtype=EVENT_DTYPE)
    out["t"], out["x"], out["y"], out["p"] = t, x, y, p > 0
    if out.size > 1 and (np.diff(t) < 0).any():
        out = out[np.argsort(t, kind="stable")]
    return out


def _off_value(like: np.ndarray) -> int:
    """The OFF polarity of ``like``'s layout: -1 where it holds -1, else 0 (False)."""
    p = like["p"]
    return -1 if p.dtype.kind in "if" and p.size and (p < 0).any() else 0


def to_structured(events: np.ndarray, like: np.ndarray) -> np.ndarray:
    """Convert edeflare events to the layout of ``like`` (its dtype and its OFF polarity).

    OFF becomes -1 when ``like`` holds a -1 polarity, else 0 (False for bool).

    Parameters
    ----------
    events : numpy.ndarray
        A stream of :data:`~edeflare.events.EVENT_DTYPE`.
    like : numpy.ndarray
        A structured array with fields ``x, y, t, p`` (as :func:`from_structured`
        takes): the result has its dtype, field order included.

    Returns
    -------
    numpy.ndarray
        A new array of ``like.dtype``.

    Examples
    --------
    >>> import numpy as np
    >>> from edeflare.events import make_events
    >>> layout = [("x", "i2"), ("y", "i2"), ("t", "f8"), ("p", "i1")]
    >>> like = np.array([(0, 0, 0.0, -1)], dtype=layout)
    >>> to_structured(make_events([5], [1], [2], [0]), like).tolist()
    [(1, 2, 5.0, -1)]
    """
    check_events(events)
    like = _structured(like)
    out = np.empty(events.size, dtype=like.dtype)
    out["t"] = events["t"]
    out["x"] = events["x"]
    out["y"] = events["y"]
    if like.dtype["p"].kind == "b":
        out["p"] = events["p"].astype(bool)
    else:
        out["p"] = np.where(events["p"] > 0, 1, _off_value(like))
    return out


def _sensor_size(sensor_size: Any) -> SensorSize:
    """``(W, H)`` from tonic's ``(W, H, P)`` or edeflare's ``(W, H)``."""
    try:
        n = len(sensor_size)
    except TypeError:
        n = 0
    if n not in (2, 3):
        raise ParameterError(
            f"sensor_size must be (width, height, polarities) as in tonic or (width, height), "
            f"got {sensor_size!r}"
        )
    if n == 3:
        polarities = sensor_size[2]
        if (
            isinstance(polarities, bool)
            or not isinstance(polarities, (int, np.integer))
            or polarities not in (1, 2)
        ):
            raise ParameterError(
                f"sensor_size's polarity count must be 1 or 2, got {sensor_size!r}"
            )
    return check_sensor_size(tuple(sensor_size[:2]))


@dataclasses.dataclass(frozen=True, init=False)
class Deflare:
    """Remove flare from a sample's events: a transform for ``tonic.transforms.Compose``.

    Converts the events to edeflare's layout (:func:`from_structured`),
    de-flares them with :func:`edeflare.deflare` and converts the result back
    to the input's own dtype and field order (:func:`to_structured`). The
    method is made once and reused for every sample.

    Parameters
    ----------
    sensor_size : (W, H, P) or (W, H)
        As tonic's datasets give it (``dataset.sensor_size``); ``P`` is 1 or 2.
    method : str or Method
        A registered name (:func:`edeflare.list_methods`; default ``"model"``,
        the bundled model) or a method object.
    **params
        The method's parameters, when ``method`` is a name.

    Notes
    -----
    Timestamps must be whole microseconds, as tonic's datasets give them. Unsorted
    input is sorted stably by ``t`` first, so the output is sorted by ``t`` (its
    order is not the input's). Each sample is a whole stream: stateful methods
    start afresh on every call, and ``efr`` computes its bias over the sample.

    Examples
    --------
    >>> import numpy as np
    >>> layout = np.dtype([("x", "<i8"), ("y", "<i8"), ("t", "<i8"), ("p", "<i8")])
    >>> pixels = [(1, 1), (2, 1), (1, 2), (2, 2)] * 3
    >>> patch = [(x, y, k * 1_000, 1) for k, (x, y) in enumerate(pixels)]
    >>> ev = np.array(patch + [(6, 6, 12_000, 0)], dtype=layout)   # a 2x2 patch, a lone event
    >>> transform = Deflare((8, 8, 2), "pfd-b")
    >>> transform
    Deflare(sensor_size=(8, 8, 2), method='pfd-b', params={})
    >>> out = transform(ev)
    >>> out.dtype == layout, len(out), int(out["p"].min())
    (True, 10, 1)
    """

    sensor_size: tuple[int, ...]
    method: str | Method
    params: dict[str, Any] = dataclasses.field(hash=False)
    _method: Method | None = dataclasses.field(init=False, repr=False, compare=False)

    def __init__(
        self, sensor_size: tuple[int, ...], method: str | Method = "model", **params: Any
    ) -> None:
        from .methods import Method, create_method

        size = tuple(int(v) for v in _sensor_size(sensor_size)) + tuple(
            int(v) for v in tuple(sensor_size)[2:]
        )
        if isinstance(method, Method):
            if params:
                raise ParameterError("pass parameters either to create_method or here, not both")
            made = method
        elif isinstance(method, str):
            made = create_method(method, **params)
        else:
            raise ParameterError(
                f"method must be a method name or a Method, got {type(method).__name__}"
            )
        object.__setattr__(self, "sensor_size", size)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "params", dict(params))
        object.__setattr__(self, "_method", made)

    def __getstate__(self) -> dict[str, Any]:
        # A method made here from a name is made again after unpickling (a data
        # loader's workers): it may hold a loaded network.
        state = dict(self.__dict__)
        if isinstance(self.method, str):
            state["_method"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        for key, value in state.items():
            object.__setattr__(self, key, value)

    def __call__(self, events: np.ndarray) -> np.ndarray:
        """De-flare one sample's events; returns a new array of the input's dtype."""
        from .methods import create_method, deflare

        if self._method is None:
            object.__setattr__(self, "_method", create_method(self.method, **self.params))
        ev = from_structured(events)
        out = deflare(ev, self.sensor_size[:2], self._method)
        return to_structured(out, events)
