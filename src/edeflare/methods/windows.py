"""Aligned windows of a stream through a batch transform: the streaming of window methods."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..events import concat_events, window_start_for
from .base import EMPTY, Streamer

__all__ = ["WindowStreamer"]


class WindowStreamer(Streamer):
    """Aligned windows of ``window_us`` through a batch ``transform``, in window order.

    ``transform(batch, span)`` maps a list of complete ``(window_start, events)``
    windows to their outputs; windows without input events are skipped.
    ``span`` is ``(first, end)``: the time of the stream's first event and,
    once the stream is known to have ended (at :meth:`flush`), one past its
    last event, else None. A transform that synthesises events (the model)
    keeps them inside it: the sensor recorded nothing outside. The window
    holding the latest event is kept back until a later event or the end
    shows whether the stream ends in it.
    """

    def __init__(
        self,
        window_us: int,
        transform: Callable[
            [list[tuple[int, np.ndarray]], tuple[int, int | None]], list[np.ndarray]
        ],
    ) -> None:
        self.window_us = window_us
        self.transform = transform
        self.pending = EMPTY
        self.start: int | None = None
        self.first_t: int | None = None

    def _windows(self, until_us: int | None) -> np.ndarray:
        batch = []
        end_t = None
        if self.pending.size:
            last = int(self.pending["t"][-1]) + 1
            if until_us is None:
                end_t = last
            else:  # hold the window of the last event: it may be the stream's last
                until_us = min(until_us, last)
        # the times once, contiguous: searching the records' strided field copies it
        # on every call, quadratic in a long in-memory stream
        t = np.ascontiguousarray(self.pending["t"])
        i = 0
        while i < t.size:
            if self.start is None or t[i] >= self.start + self.window_us:
                self.start = window_start_for(int(t[i]), self.window_us)
            end = self.start + self.window_us
            if until_us is not None and end > until_us:
                break
            k = int(np.searchsorted(t, end, side="left"))
            batch.append((self.start, self.pending[i:k]))
            i = k
            self.start = end
        self.pending = self.pending[i:]
        if not batch or self.first_t is None:
            return EMPTY.copy()
        out = self.transform(batch, (self.first_t, end_t))
        return concat_events(out) if out else EMPTY.copy()

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        if events.size:
            if self.first_t is None:
                self.first_t = int(events["t"][0])
            self.pending = concat_events([self.pending, events]) if self.pending.size else events
        return self._windows(until_us)

    def flush(self) -> np.ndarray:
        return self._windows(None)
