"""Live de-flaring: a filter fed chunks of a stream as they arrive, in dv-processing's style.

:class:`Deflarer` holds one method's state over one stream (the method's
:class:`~edeflare.methods.Streamer`): ``accept(chunk)`` takes the next events
from a camera or a reader, ``generate()`` returns the outputs that became
final, and ``flush()`` at the end returns the rest. Fed a whole stream in
chunks of any sizes and flushed, it gives exactly what
:func:`edeflare.deflare` gives on the whole stream at once.

Examples
--------
>>> from edeflare.events import make_events
>>> from edeflare.live import Deflarer
>>> ev = make_events([0, 10, 10, 50_000], [1, 2, 3, 1], [1, 1, 1, 1], [1, 0, 1, 1])
>>> live = Deflarer((8, 8), "raw")
>>> live.accept(ev[:2])
>>> live.generate()["t"].tolist()   # t=10 may still have company in the next chunk
[0]
>>> live(ev[2:])["t"].tolist()      # accept, then generate
[10, 10]
>>> live.flush()["t"].tolist()
[50000]
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ._validation import check_int
from .errors import EventsError, ParameterError
from .events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size, concat_events
from .methods.base import Method, create_method
from .methods.streaming import _Reorder

__all__ = ["Deflarer"]


class Deflarer:
    """De-flare a live stream chunk by chunk: ``accept``, ``generate``, and ``flush`` at the end.

    Parameters
    ----------
    sensor_size : (width, height)
    method : str or Method
        A registered name (see :func:`edeflare.list_methods`; default
        ``"model"``, the bundled model) or a method object, made once and
        reused.
    prepass_us : int, optional
        For methods that compute something over the whole input before
        filtering (``efr`` without a ``bias`` map): compute it over the
        stream's first ``prepass_us`` microseconds instead, holding every
        output until then. Required for such methods (a live stream has no
        "whole input"), an error for the others.
    max_lag_us : int or None
        ``efr`` stamps outputs in the past and they are held until no earlier
        one can come; outputs lagging their input by more than this are
        released anyway, and later ones older than that are dropped (counted
        in :attr:`late_dropped`, with a warning at :meth:`flush`). ``None``
        holds everything (exact for any length; memory grows with the output).
        As :func:`edeflare.deflare_file`.
    rng : numpy.random.Generator or int, optional
        For methods that draw (``voxel``).
    **params
        The method's parameters, when ``method`` is a name.

    Notes
    -----
    Chunks are event arrays of :data:`~edeflare.events.EVENT_DTYPE`, each
    sorted by ``t``, each starting at or after the previous chunk's last
    event (a chunk may start at that same microsecond). A chunk that breaks
    this raises :class:`~edeflare.errors.EventsError` and changes nothing, so
    the caller may fix it and go on. Chunks are copied: a camera driver may
    reuse its buffer.

    Outputs come out sorted, each :meth:`generate` at or after the previous
    one's. They lag the input by what the method needs to decide: the events
    of the latest microsecond (more may come at that time), a model's window
    (20 ms) and, for the default mask model, its delayed second window (5 ms
    more); for ``efr``, until no earlier output can come (its outputs are
    stamped in the past); for ``pfd-*`` and ``raw``, nothing more.

    With ``prepass_us``, ``efr``'s bias map comes from the stream's start, so
    the output equals ``deflare(..., "efr", bias=efr_bias(start))`` with
    ``start`` the events of the first ``prepass_us``, not ``deflare`` with a
    bias over the whole stream (unless the stream ends within the prepass).
    Pass ``bias=`` (a map from :func:`~edeflare.baselines.efr.efr_bias` over a
    recording of the same scene) for no warm-up at all.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> import numpy as np
    >>> from edeflare import deflare
    >>> t = np.arange(12) * 1_000   # a 2x2 patch firing ON, one event per ms
    >>> ev = make_events(t, [1, 2, 1, 2] * 3, [1, 1, 2, 2] * 3, [1] * 12)
    >>> live = Deflarer((8, 8), "pfd-b")
    >>> [len(live(chunk)) for chunk in np.array_split(ev, 3)] + [len(live.flush())]
    [1, 4, 4, 1]
    >>> live.events_in, live.events_out, len(deflare(ev, (8, 8), "pfd-b"))
    (12, 10, 10)
    >>> Deflarer((8, 8), "efr")
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: efr computes its bias map over the whole input before
    filtering, which a live stream does not have: pass bias= (a map from
    edeflare.baselines.efr.efr_bias over a recording of the scene) or prepass_us= (compute
    it over the stream's first microseconds, holding outputs until then)
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        method: str | Method = "model",
        *,
        prepass_us: int | None = None,
        max_lag_us: int | None = 10_000_000,
        rng: np.random.Generator | int | None = None,
        **params: Any,
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        if isinstance(method, Method):
            if params:
                raise ParameterError("pass parameters either to create_method or here, not both")
            self.method = method
        elif isinstance(method, str):
            self.method = create_method(method, **params)
        else:
            raise ParameterError(
                f"method must be a method name or a Method, got {type(method).__name__}"
            )
        name = self.method.name or type(self.method).__name__
        if prepass_us is not None:
            prepass_us = check_int("prepass_us", prepass_us, 1)
            if not self.method.needs_prepass:
                raise ParameterError(
                    f"prepass_us is for methods with a first pass over the input; {name} "
                    "has none here"
                )
        elif self.method.needs_prepass:
            raise ParameterError(
                f"{name} computes its bias map over the whole input before filtering, which a "
                "live stream does not have: pass bias= (a map from "
                "edeflare.baselines.efr.efr_bias over a recording of the scene) or prepass_us= "
                "(compute it over the stream's first microseconds, holding outputs until then)"
            )
        if max_lag_us is not None:
            max_lag_us = check_int("max_lag_us", max_lag_us, 0)
        self.prepass_us = prepass_us
        self.max_lag_us = max_lag_us
        self._rng = rng
        self._streamer = None
        self._reorder: _Reorder | None = None
        if not self.method.needs_prepass:
            self._start(None)
        self._prepass: list[np.ndarray] = []  # the chunks of the prepass
        self._held = np.zeros(0, dtype=EVENT_DTYPE)  # the events of the latest microsecond
        self._until: int | None = None  # every event fed so far is before this
        self._prepass_end: int | None = None
        self._last_t: int | None = None
        self._ready: list[np.ndarray] = []
        self._flushed = False
        self.events_in = 0
        """Events accepted so far."""
        self.events_out = 0
        """Events returned so far (by :meth:`generate`, ``__call__`` and :meth:`flush`)."""

    def __repr__(self) -> str:
        return f"Deflarer({self.sensor_size!r}, {self.method!r})"

    @property
    def late_dropped(self) -> int:
        """Outputs dropped for lagging more than ``max_lag_us`` (``efr`` only)."""
        return self._reorder.dropped if self._reorder is not None else 0

    def _start(self, prepared: Any) -> None:
        self._streamer = self.method.streamer(self.sensor_size, rng=self._rng, prepared=prepared)
        if not self._streamer.ordered:
            self._reorder = _Reorder(self._streamer, self.max_lag_us, batched=False)

    def accept(self, events: np.ndarray) -> None:
        """Take the next chunk of the stream (sorted; at or after the previous chunk).

        Raises
        ------
        EventsError
            A chunk of another dtype, unsorted, off the sensor, or starting
            before the previous chunk's last event; the filter is unchanged.
        ParameterError
            After :meth:`flush`: the stream has ended (make a new filter).

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> live = Deflarer((8, 8), "raw")
        >>> live.accept(make_events([5, 9], [0, 0], [0, 0], [1, 1]))
        >>> live.accept(make_events([7], [0], [0], [1]))
        Traceback (most recent call last):
        ...
        edeflare.errors.EventsError: chunks must come in time order: this chunk starts at
        t=7 us, before the previous chunk's last event at t=9 us
        """
        if self._flushed:
            raise ParameterError("this filter was flushed (its stream ended): make a new one")
        check_events(events, self.sensor_size)
        if events.size == 0:
            return
        first, last = int(events["t"][0]), int(events["t"][-1])
        if self._last_t is not None and first < self._last_t:
            raise EventsError(
                f"chunks must come in time order: this chunk starts at t={first} us, before "
                f"the previous chunk's last event at t={self._last_t} us"
            )
        events = events.copy()
        self._last_t = last
        self.events_in += events.size
        if self._streamer is None:  # the prepass: [first event, first event + prepass_us)
            self._prepass.append(events)
            if self._prepass_end is None:
                self._prepass_end = first + (self.prepass_us or 0)
            if last >= self._prepass_end:
                self._end_prepass(final=False)
            return
        self._push(events)

    def generate(self) -> np.ndarray:
        """The outputs that became final since the last call, sorted (maybe none).

        Examples
        --------
        >>> Deflarer((8, 8), "raw").generate().size
        0
        """
        out = concat_events(self._ready) if self._ready else np.zeros(0, dtype=EVENT_DTYPE)
        self._ready = []
        self.events_out += out.size
        return out

    def __call__(self, events: np.ndarray) -> np.ndarray:
        """``accept(events)``, then ``generate()``.

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> Deflarer((8, 8), "raw")(make_events([1, 2], [0, 0], [0, 0], [1, 1]))["t"].tolist()
        [1]
        """
        self.accept(events)
        return self.generate()

    def flush(self) -> np.ndarray:
        """End of stream: every output not yet returned, sorted. Later calls return none.

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> live = Deflarer((8, 8), "raw")
        >>> live.accept(make_events([1, 2], [0, 0], [0, 0], [1, 1]))
        >>> live.flush()["t"].tolist(), live.flush().size
        ([1, 2], 0)
        """
        if self._flushed:
            return self.generate()
        self._flushed = True
        if self._streamer is None and self._prepass:
            self._end_prepass(final=True)
        if self._streamer is not None:
            if self._held.size:
                self._feed(self._held, int(self._held["t"][-1]) + 1)
                self._held = self._held[:0]
            tail = self._streamer.flush()
            if self._reorder is not None:
                tail = self._reorder.finish(tail)
            if tail.size:
                self._ready.append(tail)
        if self.late_dropped:
            warnings.warn(
                f"{self.late_dropped} output events lagged their input by more than "
                f"max_lag_us={self.max_lag_us} and were dropped; pass max_lag_us=None for an "
                "exact result",
                stacklevel=2,
            )
        return self.generate()

    def _end_prepass(self, *, final: bool) -> None:
        """Compute the prepass over the stream's start (all of it when ``final``), then feed it."""
        buffered = concat_events(self._prepass)
        self._prepass = []
        basis = buffered
        if not final:
            basis = buffered[: int(np.searchsorted(buffered["t"], self._prepass_end, "left"))]
        self._start(self.method.prepare([basis], self.sensor_size))
        self._push(buffered)

    def _push(self, events: np.ndarray) -> None:
        """Feed all but the events of the latest microsecond, which the next chunk may join."""
        pending = concat_events([self._held, events]) if self._held.size else events
        t = pending["t"]
        last = int(t[-1])
        k = int(np.searchsorted(t, last, side="left"))
        self._held = pending[k:]
        self._feed(pending[:k], last)

    def _feed(self, events: np.ndarray, until_us: int) -> None:
        """``events`` all before ``until_us``, every later one at or after it."""
        if not events.size and self._until is not None and until_us <= self._until:
            return
        assert self._streamer is not None
        out = self._streamer.process(events, until_us)
        if self._reorder is not None:
            out = self._reorder.push(out, until_us)
        self._until = until_us
        if out.size:
            self._ready.append(out)
