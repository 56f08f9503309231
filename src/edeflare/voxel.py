"""The voxel codec of E-DeflareNet (paper, Appendix C): events <-> 8-bin grids.

Encoding sums polarities (ON +1, OFF -1) per cell ``(bin, y, x)`` of a
float32 grid ``(B, H, W)``. Decoding rounds each cell to ``n``, emits ``|n|``
events of sign ``sgn(n)`` at times uniform in the cell's bin, and sorts them.

One deliberate difference from the paper's text: bins are counted from the
**window start**, not from the first event in the window. With ``T`` the
window length and ``t0`` its start, an event at integer time ``t`` falls in
bin ``b = floor((t - t0) * B / T)`` (exact integer arithmetic). Counting
from the first event (as the authors' code did) shifts every bin by a
window-dependent amount, so input and ground truth of one window would be
binned differently. Decoding draws integer times uniformly among those that
encode back to the same bin, so ``encode(decode(V)) == round(V)`` exactly.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from .errors import EventsError
from .events import (
    EVENT_DTYPE,
    SensorSize,
    check_events,
    check_sensor_size,
    concat_events,
    select_events,
)

__all__ = ["decode", "decode_keep", "encode", "encode_polarity"]

# Windows longer than this (16.8 s) are sorted with numpy instead of a counting sort.
_COUNTING_SORT_MAX_US = 1 << 24


def _checked(
    events: Any, sensor_size: SensorSize, window_start_us: int, window_us: int, bins: int
) -> tuple[int, int]:
    check_events(events, sensor_size)
    width, height = check_sensor_size(sensor_size)
    if not isinstance(bins, (int, np.integer)) or bins < 1:
        raise EventsError(f"bins must be a positive int, got {bins!r}")
    if int(window_us) < int(bins):
        raise EventsError(f"window_us ({window_us}) must be at least bins ({bins})")
    if events.size:
        t = events["t"]
        if t[0] < window_start_us or t[-1] >= window_start_us + window_us:
            raise EventsError(
                f"events span [{int(t[0])}, {int(t[-1])}] outside the window "
                f"[{window_start_us}, {window_start_us + window_us}); "
                "select it first with edeflare.events.slice_time"
            )
    return width, height


@numba.njit(cache=True, nogil=True)
def _bin_bounds(t, start, window, bins):  # pragma: no cover - compiled
    """Index of the first event of each bin in a sorted window (``bins + 1`` entries).

    Bin ``b`` holds the integer times from ``start + ceil(b*window/bins)`` up
    to the next bin's first time: exactly the events with
    ``(t - start)*bins // window == b``. Binary search on the (strided) field,
    so nothing is copied.
    """
    bounds = np.empty(bins + 1, dtype=np.int64)
    for b in range(bins + 1):
        first_time = start + (b * window + bins - 1) // bins
        lo, hi = 0, t.size
        while lo < hi:
            mid = (lo + hi) >> 1
            if t[mid] < first_time:
                lo = mid + 1
            else:
                hi = mid
        bounds[b] = lo
    return bounds


# Sorted input lets each bin be a contiguous run of events: no per-event
# division, and bins are independent, so they are filled in parallel.
@numba.njit(cache=True, nogil=True, parallel=True)
def _encode_signed(x, y, p, bounds, out):  # pragma: no cover - compiled
    bins, height, width = out.shape
    for b in numba.prange(bins):
        plane = out[b].reshape(height * width)
        for i in range(bounds[b], bounds[b + 1]):
            plane[np.int64(y[i]) * width + x[i]] += np.float32(2 * np.int32(p[i]) - 1)


@numba.njit(cache=True, nogil=True, parallel=True)
def _encode_split(x, y, p, bounds, out):  # pragma: no cover - compiled
    _, bins, height, width = out.shape
    for b in numba.prange(bins):
        on = out[0, b].reshape(height * width)
        off = out[1, b].reshape(height * width)
        for i in range(bounds[b], bounds[b + 1]):
            k = np.int64(y[i]) * width + x[i]
            pi = np.float32(p[i])
            on[k] += pi
            off[k] += np.float32(1.0) - pi


def encode(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_start_us: int,
    window_us: int,
    bins: int = 8,
) -> np.ndarray:
    """Encode one window of events into a signed voxel grid.

    Parameters
    ----------
    events : numpy.ndarray
        Sorted events, all within ``[window_start_us, window_start_us + window_us)``.
    sensor_size : (width, height)
    window_start_us, window_us : int
        The half-open window, in microseconds.
    bins : int
        Temporal bins (paper: 8).

    Returns
    -------
    numpy.ndarray
        float32 ``(bins, H, W)``: per cell, ON count minus OFF count.

    Notes
    -----
    ``V(b, y, x) = sum_{k : (x_k, y_k, b_k) = (x, y, b)} p_k`` with
    ``p_k`` in {-1, +1} and ``b_k = floor((t_k - window_start) * bins / window)``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 15], [0, 0, 1], [0, 0, 0], [1, 1, 0])
    >>> encode(ev, (2, 1), 0, 16, bins=2)[:, 0, :].tolist()
    [[2.0, 0.0], [0.0, -1.0]]
    """
    width, height = _checked(events, sensor_size, window_start_us, window_us, bins)
    out = np.zeros((bins, height, width), dtype=np.float32)
    if events.size:
        bounds = _bin_bounds(events["t"], np.int64(window_start_us), np.int64(window_us), bins)
        _encode_signed(events["x"], events["y"], events["p"], bounds, out)
    return out


def encode_polarity(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_start_us: int,
    window_us: int,
    bins: int = 8,
) -> np.ndarray:
    """Encode one window into a polarity-separated grid ``(2, bins, H, W)``.

    Channel 0 counts ON events, channel 1 counts OFF events (both >= 0), so
    ``grid[0] - grid[1] == encode(...)``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1], [0, 0], [0, 0], [1, 0])
    >>> encode_polarity(ev, (1, 1), 0, 8, bins=1).reshape(-1).tolist()
    [1.0, 1.0]
    """
    width, height = _checked(events, sensor_size, window_start_us, window_us, bins)
    out = np.zeros((2, bins, height, width), dtype=np.float32)
    if events.size:
        bounds = _bin_bounds(events["t"], np.int64(window_start_us), np.int64(window_us), bins)
        _encode_split(events["x"], events["y"], events["p"], bounds, out)
    return out


@numba.njit(cache=True, nogil=True)
def _decode_into(
    cells, counts, bins, height, width, start, window, u, t, x, y, p
):  # pragma: no cover
    """Draw each cell's events and place them in time order by a counting sort.

    Pass 1 draws every event's integer offset in its bin and histograms the
    offsets (O(n + window)); pass 2 walks the cells in the same order and
    writes each event straight to its sorted position, so ties keep cell order.
    """
    plane = height * width
    total = u.size
    off = np.empty(total, dtype=np.int64)
    slot = np.zeros(window + 1, dtype=np.int64)
    j = 0
    for c in range(cells.size):
        b = cells[c] // plane
        lo = (b * window + bins - 1) // bins  # first integer offset of bin b
        span = ((b + 1) * window + bins - 1) // bins - lo
        for _ in range(abs(counts[c])):
            o = lo + np.int64(u[j] * span)
            off[j] = o
            slot[o + 1] += 1
            j += 1
    for k in range(window):
        slot[k + 1] += slot[k]
    j = 0
    for c in range(cells.size):
        rem = cells[c] % plane
        yy = rem // width
        xx = rem - yy * width
        pol = 1 if counts[c] > 0 else 0
        for _ in range(abs(counts[c])):
            o = off[j]
            pos = slot[o]
            slot[o] = pos + 1
            t[pos] = start + o
            x[pos] = xx
            y[pos] = yy
            p[pos] = pol
            j += 1


def decode(
    voxel: np.ndarray,
    window_start_us: int,
    window_us: int,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Decode a signed voxel grid ``(bins, H, W)`` back into sorted events.

    Each cell is rounded to the nearest integer ``n`` (halves to even, as
    ``numpy.rint``); it yields ``|n|`` events of polarity ``sgn(n)`` with
    integer timestamps drawn uniformly among those of the cell's bin, so that
    :func:`encode` maps the result back to ``rint(voxel)``. Events are sorted
    by time (ties keep cell order), so the output is a valid stream.

    Parameters
    ----------
    voxel : numpy.ndarray
        Finite ``(bins, H, W)`` grid (any float or int dtype).
    window_start_us, window_us : int
        The window the grid covers.
    rng : numpy.random.Generator or int or None
        Source of the timestamps; a seed makes decoding deterministic.

    Returns
    -------
    numpy.ndarray
        Events of :data:`~edeflare.events.EVENT_DTYPE` on a ``(W, H)`` sensor.

    Examples
    --------
    >>> grid = np.zeros((2, 1, 2), dtype=np.float32)
    >>> grid[1, 0, 1] = -1.6   # two OFF events in the second bin at x=1
    >>> ev = decode(grid, 1000, 20, rng=0)
    >>> ev["x"].tolist(), ev["p"].tolist(), bool((ev["t"] >= 1010).all())
    ([1, 1], [0, 0], True)
    """
    voxel = np.asarray(voxel)
    if voxel.ndim != 3:
        raise EventsError(f"voxel must have shape (bins, H, W), got {voxel.shape}")
    if voxel.dtype.kind not in "fiu":
        raise EventsError(f"voxel must be numeric, got dtype {voxel.dtype}")
    if voxel.dtype.kind == "f" and not np.isfinite(voxel).all():
        raise EventsError("voxel contains NaN or infinity")
    bins, height, width = voxel.shape
    window_us = int(window_us)
    if window_us < bins:
        raise EventsError(f"window_us ({window_us}) must be at least bins ({bins})")
    rng = np.random.default_rng(rng)
    counts = np.rint(voxel).astype(np.int64).reshape(-1)
    cells = np.flatnonzero(counts)
    cell_counts = counts[cells]
    total = int(np.abs(cell_counts).sum())
    u = rng.random(total)
    events = np.empty(total, dtype=EVENT_DTYPE)
    if window_us <= _COUNTING_SORT_MAX_US:
        _decode_into(
            cells,
            cell_counts,
            bins,
            height,
            width,
            np.int64(window_start_us),
            np.int64(window_us),
            u,
            events["t"],
            events["x"],
            events["y"],
            events["p"],
        )
    else:  # very long windows: a histogram per microsecond would be too large
        events = _decode_by_argsort(
            cells, cell_counts, bins, height, width, int(window_start_us), window_us, u
        )
    return events


def _decode_by_argsort(
    cells: np.ndarray,
    counts: np.ndarray,
    bins: int,
    height: int,
    width: int,
    start: int,
    window: int,
    u: np.ndarray,
) -> np.ndarray:
    """Vectorised decode with a stable argsort, for windows too long for a counting sort."""
    reps = np.abs(counts)
    cell = np.repeat(cells, reps)
    b, rem = np.divmod(cell, height * width)
    lo = (b * window + bins - 1) // bins
    span = ((b + 1) * window + bins - 1) // bins - lo
    off = lo + (u * span).astype(np.int64)
    order = np.argsort(off, kind="stable")
    events = np.empty(cell.size, dtype=EVENT_DTYPE)
    events["t"] = start + off[order]
    events["y"] = (rem // width)[order]
    events["x"] = (rem % width)[order]
    events["p"] = np.repeat(counts > 0, reps)[order]
    return events


@numba.njit(cache=True, nogil=True)
def _keep_mask(cells, p, order, remove_on, remove_off):  # pragma: no cover - compiled
    """Drop input events while their cell still has to lose events of their polarity.

    Events are visited in the random ``order``, so the dropped ones are a
    uniform random subset of each cell's events of that polarity. The
    budgets left over (nothing more to drop) are updated in place.
    """
    keep = np.ones(cells.size, dtype=np.bool_)
    for k in range(order.size):
        i = order[k]
        c = cells[i]
        if p[i]:
            if remove_on[c] > 0:
                remove_on[c] -= 1
                keep[i] = False
        elif remove_off[c] > 0:
            remove_off[c] -= 1
            keep[i] = False
    return keep


def decode_keep(
    voxel: np.ndarray,
    events: np.ndarray,
    window_start_us: int,
    window_us: int,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Decode a restored grid as the smallest edit of the input events.

    Per cell, with ``m`` the input's net count (ON minus OFF) and ``n`` the
    rounded restored value, ``d = n - m`` events must change: for ``d < 0``
    up to ``|d|`` of the cell's ON events are removed (a seeded uniform random
    subset) and any remainder is added as OFF events; for ``d > 0`` OFF events
    are removed first and ON events added. Added events get uniform times in
    the cell's bin, as in :func:`decode`. Every other input event is kept with
    its real timestamp: a cell the model leaves alone keeps all its events,
    even ON/OFF pairs that cancel in the signed grid, and
    ``encode(result) == rint(voxel)`` still holds.

    Parameters
    ----------
    voxel : numpy.ndarray
        Restored ``(bins, H, W)`` grid.
    events : numpy.ndarray
        The input events of the window (sorted, inside it).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([3, 7, 12], [0, 0, 1], [0, 0, 0], [1, 1, 0])
    >>> grid = encode(ev, (2, 1), 0, 16, bins=2)
    >>> grid[0, 0, 0] = 1            # the model removes one of the two ON events
    >>> out = decode_keep(grid, ev, 0, 16, rng=0)
    >>> len(out), int(out["t"][-1])  # the OFF event keeps its own timestamp
    (2, 12)
    """
    voxel = np.asarray(voxel)
    if voxel.ndim != 3:
        raise EventsError(f"voxel must have shape (bins, H, W), got {voxel.shape}")
    bins, height, width = voxel.shape
    if voxel.dtype.kind == "f" and not np.isfinite(voxel).all():
        raise EventsError("voxel contains NaN or infinity")
    _checked(events, (width, height), window_start_us, window_us, bins)
    rng = np.random.default_rng(rng)
    target = np.rint(voxel).astype(np.int64).reshape(-1)
    have = encode(events, (width, height), window_start_us, window_us, bins)
    delta = target - have.astype(np.int64).reshape(-1)
    remove_on = np.maximum(-delta, 0)
    remove_off = np.maximum(delta, 0)
    b = ((events["t"] - int(window_start_us)) * bins) // int(window_us)
    cells = (b * height + events["y"].astype(np.int64)) * width + events["x"]
    order = rng.permutation(events.size)
    keep = _keep_mask(cells, events["p"], order, remove_on, remove_off)
    # What could not be removed is added with the other polarity.
    added = decode((remove_off - remove_on).reshape(voxel.shape), window_start_us, window_us, rng)
    kept = select_events(events, keep)
    if not added.size:
        return kept
    merged = concat_events([kept, added])
    return merged[np.argsort(merged["t"], kind="stable")]
