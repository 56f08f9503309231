"""A growable event buffer shared by the compiled event simulators.

A kernel walks a list of pixels (increasing pixel order) and appends their
events to the buffer. A pixel is committed only once all of its events fit:
when the buffer is full the kernel stops before that pixel and returns where to
resume. :meth:`EventBuffer.run` then doubles the capacity and calls the kernel
again, so the output never depends on the capacity.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from ..events import EVENT_DTYPE

__all__ = ["EventBuffer"]

# Intervals longer than this many µs per event are sorted with argsort instead of counting.
_COUNTING_SPAN_PER_EVENT = 64


class EventBuffer:
    """Event storage for one simulator, reused frame after frame.

    Parameters
    ----------
    width : int
        Sensor width, to turn flat pixel indices into ``x, y``.
    capacity : int
        Initial number of events (grows by doubling).
    """

    def __init__(self, width: int, capacity: int = 4096) -> None:
        self.width = width
        self.t = np.empty(capacity, dtype=np.float64)
        self.pix = np.empty(capacity, dtype=np.int64)
        self.p = np.empty(capacity, dtype=np.uint8)

    def _grow(self, used: int) -> None:
        for name in ("t", "pix", "p"):
            old = getattr(self, name)
            new = np.empty(2 * old.size, dtype=old.dtype)
            new[:used] = old[:used]
            setattr(self, name, new)

    def run(self, kernel: Callable[..., tuple[int, int]], n_items: int, t0: float) -> np.ndarray:
        """Call ``kernel(q, n, t, pix, p) -> (q, n)`` until it has done ``n_items`` items.

        ``q`` is the next item to simulate and ``n`` the events stored so far.
        Returns the events as :data:`EVENT_DTYPE`, times rounded half to even,
        stably sorted by time (ties keep pixel order, i.e. ``y`` then ``x``).
        ``t0`` is a lower bound of the event times (the interval start).
        """
        q, n = 0, 0
        while True:
            q, n = kernel(q, n, self.t, self.pix, self.p)
            if q >= n_items:
                break
            self._grow(n)
        out = np.empty(n, dtype=EVENT_DTYPE)
        if n:
            t_lo = int(np.floor(t0))
            _collect(self.t, self.pix, self.p, n, self.width, t_lo,
                     out["t"], out["x"], out["y"], out["p"])  # fmt: skip
        return out


@numba.njit(cache=True, nogil=True)
def _collect(buf_t, buf_pix, buf_p, n, width, t_lo, out_t, out_x, out_y, out_p):  # pragma: no cover
    """Round times half to even and stably sort by them (counting sort when the span is short)."""
    ti = np.empty(n, dtype=np.int64)
    t_hi = t_lo
    for i in range(n):
        v = np.int64(np.rint(buf_t[i]))
        ti[i] = v
        t_hi = max(t_hi, v)
    span = t_hi - t_lo + 1
    if span <= _COUNTING_SPAN_PER_EVENT * n + 1024:
        start = np.zeros(span + 1, dtype=np.int64)
        for i in range(n):
            start[ti[i] - t_lo + 1] += 1
        for b in range(span):
            start[b + 1] += start[b]
        order = np.empty(n, dtype=np.int64)
        for i in range(n):
            b = ti[i] - t_lo
            order[start[b]] = i
            start[b] += 1
    else:
        order = np.argsort(ti, kind="mergesort")
    for k in range(n):
        i = order[k]
        out_t[k] = ti[i]
        out_x[k] = buf_pix[i] % width
        out_y[k] = buf_pix[i] // width
        out_p[k] = buf_p[i]
