"""Growable event buffers and event sorting shared by the compiled event simulators.

A kernel walks a list of pixels (increasing pixel order) and appends their
events to the buffers ``(t, pix, p)``. A pixel is committed only once all of
its events fit: when the buffers are full the kernel stops before that pixel
and returns where to resume; the caller doubles them (:func:`grown`) and calls
again, so the output never depends on the capacity. :func:`collect` then
rounds the times and sorts the events; :func:`to_events` packs them.
"""

from __future__ import annotations

import numba
import numpy as np

from ..events import EVENT_DTYPE

__all__ = ["collect", "grown", "new_buffers", "to_events"]

# Intervals longer than this many µs per event are sorted with argsort instead of counting.
_COUNTING_SPAN_PER_EVENT = 64


def new_buffers(capacity: int = 4096) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Empty event buffers: times (float64), flat pixel indices (int64), polarities (uint8)."""
    return (
        np.empty(capacity, dtype=np.float64),
        np.empty(capacity, dtype=np.int64),
        np.empty(capacity, dtype=np.uint8),
    )


@numba.njit(cache=True, nogil=True)
def grown(buf_t, buf_pix, buf_p, used):  # pragma: no cover - compiled
    """The buffers at twice the capacity, keeping the first ``used`` events."""
    cap = 2 * max(buf_t.size, 16)
    t = np.empty(cap, dtype=np.float64)
    pix = np.empty(cap, dtype=np.int64)
    p = np.empty(cap, dtype=np.uint8)
    t[:used] = buf_t[:used]
    pix[:used] = buf_pix[:used]
    p[:used] = buf_p[:used]
    return t, pix, p


@numba.njit(cache=True, nogil=True)
def collect(buf_t, buf_pix, buf_p, n, width, t_lo):  # pragma: no cover - compiled
    """Round the ``n`` stored times half to even and stably sort the events by time.

    Ties keep the buffer's (pixel) order, i.e. ``y`` then ``x``. ``t_lo`` is a
    lower bound of the times (the interval start). Returns ``(t, x, y, p)``.
    """
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
    out_t = np.empty(n, dtype=np.int64)
    out_x = np.empty(n, dtype=np.uint16)
    out_y = np.empty(n, dtype=np.uint16)
    out_p = np.empty(n, dtype=np.uint8)
    for k in range(n):
        i = order[k]
        out_t[k] = ti[i]
        out_x[k] = buf_pix[i] % width
        out_y[k] = buf_pix[i] // width
        out_p[k] = buf_p[i]
    return out_t, out_x, out_y, out_p


def to_events(t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Pack four field arrays into an :data:`EVENT_DTYPE` array."""
    out = np.empty(t.size, dtype=EVENT_DTYPE)
    out["t"] = t
    out["x"] = x
    out["y"] = y
    out["p"] = p
    return out
