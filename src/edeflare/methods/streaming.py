"""Streaming de-flaring: a method over a file window by window, its reorder buffer and stats.

:func:`deflare_file` streams any readable file through any method with bounded
memory and writes any writable format atomically. Stateful methods (EFR, PFD)
carry their state across windows, so the result equals one pass over the
whole file.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
import warnings
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import numpy as np

from .._progress import progress_bar
from ..errors import ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_events, concat_events
from .base import EMPTY, Method, Streamer, create_method

__all__ = ["DeflareStats", "StreamRun", "deflare_file"]

# Held outputs are re-sorted once at least this many (and as many as already held) arrived.
_REORDER_BATCH = 1 << 16


@dataclasses.dataclass(frozen=True)
class DeflareStats:
    """What :func:`deflare_file` did, and how fast.

    The timings are not part of the equality or the repr (they differ run to run).
    """

    events_in: int
    events_out: int
    late_dropped: int
    """Outputs that lagged their input by more than ``max_lag_us`` (EFR only)."""
    seconds: float = dataclasses.field(default=0.0, compare=False, repr=False)
    """Wall time of reading, de-flaring and writing (not of the method's setup,
    such as loading a model)."""
    span_us: int = dataclasses.field(default=0, compare=False, repr=False)
    """Time from the input's first event to its last."""
    latency_ms: tuple[float, float, float] = dataclasses.field(
        default=(0.0, 0.0, 0.0), compare=False, repr=False
    )
    """Median, 95th percentile and maximum, over the streaming windows, of the
    time from the moment a window is complete (its last event read) to the
    moment the method returns its output: the method's latency in a live stream."""

    @property
    def real_time_factor(self) -> float:
        """Run time over recording time (below 1: faster than the sensor)."""
        return self.seconds / (self.span_us * 1e-6) if self.span_us > 0 else math.nan


class _Reorder:
    """Holds an unordered streamer's outputs until no later output can precede them.

    Outputs arrive in emission order; released batches are stable-sorted by
    time, so their concatenation is the stable sort of all outputs (the
    one-pass result) as long as nothing is dropped. An output older than
    what was already released (it lagged more than ``max_lag_us``) is dropped
    and counted. ``batched`` releases only once enough outputs arrived (linear
    work over a file); otherwise every push releases what is final (a live
    filter's latency, at the cost of merging with what is held each time).
    """

    def __init__(self, streamer: Streamer, max_lag_us: int | None, *, batched: bool = True) -> None:
        self.streamer = streamer
        self.max_lag_us = max_lag_us
        self.batched = batched
        self.held = EMPTY  # sorted
        self.new: list[np.ndarray] = []
        self.n_new = 0
        self.released: int | None = None
        self.dropped = 0

    def _merge(self) -> None:
        if not self.new:
            return
        new = concat_events(self.new)
        new = new[np.argsort(new["t"], kind="stable")]
        both = concat_events([self.held, new])
        self.held = both[np.argsort(both["t"], kind="stable")]  # two sorted runs: linear
        self.new, self.n_new = [], 0

    def push(self, outputs: np.ndarray, until_us: int) -> np.ndarray:
        if outputs.size and self.released is not None:
            late = outputs["t"] < self.released
            if late.any():
                self.dropped += int(late.sum())
                outputs = outputs[~late]
        if outputs.size:
            self.new.append(outputs)
            self.n_new += outputs.size
        # Release in batches at least as large as what is held: linear work overall.
        if self.batched and self.n_new < max(_REORDER_BATCH, self.held.size):
            return EMPTY
        mark = self.streamer.safe_time_us(until_us)
        if self.max_lag_us is not None:
            mark = max(mark, until_us - self.max_lag_us)
        self._merge()
        k = int(np.searchsorted(self.held["t"], mark, side="left"))
        out, self.held = self.held[:k], self.held[k:]
        self.released = mark if self.released is None else max(self.released, mark)
        return out

    def finish(self, outputs: np.ndarray) -> np.ndarray:
        if outputs.size and self.released is not None:
            late = outputs["t"] < self.released
            self.dropped += int(late.sum())
            outputs = outputs[~late]
        self.new.append(outputs)
        self._merge()
        out, self.held = self.held, EMPTY
        return out


class StreamRun:
    """One method streamed over aligned windows: sorted outputs, counts and call timings.

    Shared by :func:`deflare_file` (which writes the outputs) and the benchmark
    (which scores them window by window), so both run a method the same way.
    """

    def __init__(
        self,
        method: Method,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None,
        prepared: Any,
        max_lag_us: int | None,
    ) -> None:
        self.streamer = method.streamer(sensor_size, rng=rng, prepared=prepared)
        # load the stream check's compiled kernel now (start-up), not in the first window;
        # two events, as a window's fields are strided views (one event's are contiguous,
        # which numba compiles separately)
        check_events(np.zeros(2, dtype=EVENT_DTYPE))
        self.reorder = None if self.streamer.ordered else _Reorder(self.streamer, max_lag_us)
        self.n_in = 0
        self.first_t: int | None = None
        self.last_t: int | None = None
        self.call_seconds: list[float] = []
        """Seconds of each ``process`` call and of the final ``flush``."""

    @property
    def dropped(self) -> int:
        """Outputs dropped for lagging more than ``max_lag_us`` (EFR only)."""
        return self.reorder.dropped if self.reorder is not None else 0

    def outputs(
        self, windows: Iterable[tuple[int, np.ndarray]], window_us: int
    ) -> Iterator[np.ndarray]:
        """Feed ``(start_us, events)`` windows in order; yield sorted output chunks."""
        streamer, reorder = self.streamer, self.reorder
        for start, events in windows:
            self.n_in += events.size
            if events.size:
                self.first_t = int(events["t"][0]) if self.first_t is None else self.first_t
                self.last_t = int(events["t"][-1])
            t_call = time.perf_counter()
            out = streamer.process(events, start + window_us)
            self.call_seconds.append(time.perf_counter() - t_call)
            yield out if reorder is None else reorder.push(out, start + window_us)
        t_call = time.perf_counter()
        tail = streamer.flush()
        self.call_seconds.append(time.perf_counter() - t_call)
        yield tail if reorder is None else reorder.finish(tail)


def deflare_file(
    in_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    method: str | Method,
    window_us: int = 20_000,
    sensor_size: SensorSize | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    rng: np.random.Generator | int | None = None,
    max_lag_us: int | None = 10_000_000,
    evt_version: str = "evt2",
    progress: bool | None = None,
    group: str | None = None,
) -> DeflareStats:
    """Stream a file through a method window by window and write the result atomically.

    Parameters
    ----------
    in_path, out_path : path-like
        Any readable / writable event format, by suffix (see
        :func:`edeflare.io.list_formats`). The output is written to a
        temporary file and moved into place only when complete.
    method : str or Method
        A registered name (see :func:`list_methods`) or a method object.
    window_us : int
        Length of the aligned windows read at a time (memory: one window).
    sensor_size : (width, height), optional
        For files that record none.
    params : mapping, optional
        The method's parameters, when ``method`` is a name.
    rng : numpy.random.Generator or int, optional
        For methods that draw (``voxel``); a seed makes the output reproducible.
    max_lag_us : int or None
        EFR stamps outputs in the past (a pixel's queues advance only when it
        gets a new event), so outputs are held until no earlier one can come.
        Outputs lagging their input by more than this are released anyway and
        later ones older than that are dropped (counted in the result, with a
        warning), which bounds memory. ``None`` holds everything: exact for
        any length, memory grows with the output. Files shorter than
        ``max_lag_us`` are always exact.
    evt_version : {"evt2", "evt3"}
        Encoding of ``.raw`` outputs (see :func:`edeflare.io.write_event_chunks`).
    progress : bool, optional
        False: no progress bar; otherwise one is shown on a terminal only.

    Returns
    -------
    DeflareStats
        Events read, events written, late outputs dropped.

    Notes
    -----
    EFR computes its per-pixel bias over the whole input, as the original
    program does: unless a ``bias`` map is given, the file is read twice (a
    first pass for the bias map, then the filtering pass).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io import write_events, read_events
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> ev = make_events([0, 100, 40_000], [1, 2, 3], [1, 1, 1], [1, 0, 1])
    >>> write_events(folder / "in.h5", ev, (8, 8))
    >>> deflare_file(folder / "in.h5", folder / "out.npz", "raw", progress=False)
    DeflareStats(events_in=3, events_out=3, late_dropped=0)
    """
    from ..io import open_events, write_event_chunks

    if isinstance(window_us, bool) or not isinstance(window_us, (int, np.integer)):
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if window_us <= 0:
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if max_lag_us is not None and (isinstance(max_lag_us, bool) or max_lag_us < 0):
        raise ParameterError(f"max_lag_us must be a non-negative int or None, got {max_lag_us!r}")
    if isinstance(method, Method):
        if params:
            raise ParameterError("pass parameters either to create_method or here, not both")
        m = method
    else:
        m = create_method(method, **dict(params or {}))
    src = open_events(in_path, sensor_size, group=group)
    size = src.sensor_size
    prepared = None
    if m.needs_prepass:
        with progress_bar(
            total=src.n_events,
            unit="ev",
            unit_scale=True,
            enabled=progress,
            leave=False,
            desc="first pass",
        ) as bar:

            def counted() -> Iterator[np.ndarray]:
                for chunk in src.chunks():
                    bar.update(chunk.size)
                    yield chunk

            prepared = m.prepare(counted(), size)
    run = StreamRun(m, size, rng=rng, prepared=prepared, max_lag_us=max_lag_us)
    t_begin = time.perf_counter()

    def windows(bar: Any) -> Iterator[tuple[int, np.ndarray]]:
        for start, events in src.windows(window_us):
            bar.update(events.size)
            yield start, events

    desc = m.name or type(m).__name__
    with progress_bar(
        total=src.n_events, unit="ev", unit_scale=True, enabled=progress, leave=False, desc=desc
    ) as bar:
        n_out = write_event_chunks(
            out_path, run.outputs(windows(bar), window_us), size, evt_version=evt_version
        )
    dropped = run.dropped
    if dropped:
        warnings.warn(
            f"{out_path}: {dropped} output events lagged their input by more than "
            f"max_lag_us={max_lag_us} and were dropped; pass max_lag_us=None for an exact result",
            stacklevel=2,
        )
    calls_ms = np.asarray(run.call_seconds) * 1e3
    return DeflareStats(
        run.n_in,
        n_out,
        dropped,
        seconds=time.perf_counter() - t_begin,
        span_us=0 if run.first_t is None or run.last_t is None else run.last_t - run.first_t,
        latency_ms=(
            float(np.median(calls_ms)),
            float(np.percentile(calls_ms, 95)),
            float(calls_ms.max()),
        ),
    )
