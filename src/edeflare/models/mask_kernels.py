"""A mask model's per-event work: cell features from events, and keep logits per event.

:func:`event_features` counts a window's events into the network's low-resolution
input straight from the events; :func:`event_keep_logits` reads each event's keep
logit at its own pixel, bin and polarity from the network's output (with the
per-pixel refinement of a ``mask.pixel`` model), and :func:`event_keep_mask`
turns them into keep decisions. The loops are numba kernels: no full-resolution
voxel grid is ever built.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import numba
import numpy as np

__all__ = [
    "EventRecords",
    "event_features",
    "event_keep_logits",
    "event_keep_mask",
    "event_pixel_features",
    "event_records",
    "event_support",
    "keep_logit_threshold",
]


def event_features(
    events: np.ndarray,
    sensor_size: tuple[int, int],
    window_start_us: int,
    window_us: int,
    bins: int,
    scale: int,
    *,
    records: EventRecords | None = None,
) -> np.ndarray:
    """The features of :meth:`FlareMaskNet.features`, straight from events (float32).

    Equal to ``net.features(encode(...))`` where no cell holds ON and OFF events
    of one pixel and bin that cancel (the voxel grid is signed; the event counts
    are not), which is what real windows mostly look like. ``records``, the
    window's :func:`event_records` at these ``bins`` if already made, saves making them.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5, 15], [0, 1, 5], [0, 0, 0], [1, 1, 0])
    >>> f = event_features(ev, (8, 4), 0, 20, bins=2, scale=4)
    >>> f.shape, round(float(f[0, 0, 0]), 4), float(f[4, 0, 0])  # log(1 + 2), 2 of 16 pixels
    ((5, 1, 2), 1.0986, 0.125)
    """
    width, height = int(sensor_size[0]), int(sensor_size[1])
    h, w = -(-height // scale), -(-width // scale)
    if records is None:
        records = event_records(events, window_start_us, window_us, bins, sensor_size)
    else:
        records.check(events, bins, (width, height))
    seen = _seen_frame(width, height)
    counts = _cell_counts(records.rows, int(bins), int(scale), h, w, seen, width)
    feats = counts.astype(np.float64)
    feats[:-1] = np.log1p(feats[:-1])
    feats[-1] /= float(scale * scale)
    return feats.astype(np.float32)


class EventRecords(NamedTuple):
    """A window's events as the kernels read them (:func:`event_records`), with what
    they were made for: the compiled kernels index their frames unchecked, so a
    consumer checks these (cheaply) instead of the rows."""

    rows: np.ndarray
    """``(n, 4) int32``: ``x``, ``y``, twice the channel plus the polarity, the index."""
    bins: int
    """The time bins per polarity the channels count."""
    sensor_size: tuple[int, int] | None
    """The sensor every event was checked on (None: not checked)."""

    def check(self, events: np.ndarray, bins: int, sensor_size: tuple[int, int] | None) -> None:
        """Raise unless these are ``events``' records at ``bins``, checked on ``sensor_size``."""
        if self.rows.shape != (events.size, 4) or self.bins != bins:
            raise ValueError(
                f"records must be the window's {events.size} event_records at {bins} bins"
            )
        if sensor_size is not None and self.sensor_size != tuple(sensor_size):
            made = "without a sensor" if self.sensor_size is None else f"on {self.sensor_size}"
            raise ValueError(f"records made {made}; these kernels need them on {sensor_size}")


def event_records(
    events: np.ndarray,
    window_start_us: int,
    window_us: int,
    bins: int,
    sensor_size: tuple[int, int] | None = None,
) -> EventRecords:
    """A window's events as the kernels read them: ``(n, 4) int32`` rows in bands of
    8 sensor rows, in time order within a band.

    Each row holds ``x``, ``y``, twice the event's time bin and polarity channel
    (``bin + bins * (1 - polarity)``, the network's output channel) plus its polarity,
    and the event's index in the window. Made once per window, they serve both
    :func:`event_features` and :func:`event_keep_logits`. The events must lie in the
    window and, given ``sensor_size``, on the sensor.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5, 15], [0, 1, 5], [9, 2, 3], [1, 0, 1])
    >>> event_records(ev, 0, 20, bins=2, sensor_size=(8, 12)).rows.tolist()  # rows 2, 3, 9
    [[1, 2, 4, 1], [5, 3, 3, 2], [0, 9, 1, 0]]
    """
    if sensor_size is None:
        bounds = (1 << 31, 1 << 31)
        height = int(events["y"].max()) + 1 if events.size else 1
    else:
        bounds = (int(sensor_size[0]), int(sensor_size[1]))
        height = bounds[1]
    _check_inside(events, window_start_us, window_us, *bounds)
    rows = _band_records(
        events["t"], events["x"], events["y"], events["p"], int(window_start_us),
        int(window_us), int(bins), height,
    )  # fmt: skip
    size = None if sensor_size is None else (int(sensor_size[0]), int(sensor_size[1]))
    return EventRecords(rows, int(bins), size)


@numba.njit(cache=True, nogil=True)
def _first_outside(t, x, y, t0, window_us, width, height):  # pragma: no cover - compiled
    """Index of the first event outside the window or the sensor, else -1."""
    for i in range(t.size):
        if t[i] < t0 or t[i] - t0 >= window_us or x[i] >= width or y[i] >= height:
            return i
    return -1


def _check_inside(
    events: np.ndarray, start_us: int, window_us: int, width: int, height: int
) -> None:
    """The compiled kernels index frames without bounds checks: refuse what would overflow."""
    i = _first_outside(
        events["t"], events["x"], events["y"], int(start_us), int(window_us), width, height
    )
    if i >= 0:
        e = events[i]
        raise ValueError(
            f"event {i} (t={int(e['t'])}, x={int(e['x'])}, y={int(e['y'])}) lies outside the "
            f"window [{start_us}, {start_us + window_us}) us or the {width}x{height} sensor"
        )


@numba.njit(cache=True, nogil=True)
def _cell_counts(rec, bins, scale, h, w, seen, width):  # pragma: no cover - compiled
    """Events per (polarity, bin, cell), then pixels that fired per cell ``(2 bins + 1, h, w)``,
    from the window's records (:func:`event_records`).

    ``seen`` is a zeroed ``uint8`` frame of the sensor's pixels, left zeroed.
    """
    out = np.zeros((2 * bins + 1, h, w), np.int32)
    for k in range(rec.shape[0]):
        x, y = np.int64(rec[k, 0]), np.int64(rec[k, 1])
        cy, cx = y // scale, x // scale
        out[rec[k, 2] >> 1, cy, cx] += 1
        pix = y * width + x
        out[2 * bins, cy, cx] += 1 - seen[pix]
        seen[pix] = 1
    for k in range(rec.shape[0]):
        seen[np.int64(rec[k, 1]) * width + rec[k, 0]] = 0
    return out


# The per-event work (pixel counts, box sums, the bilinear logit, the refinement) is
# hand-written with numba rather than numpy: numpy needs a bincount, a summed-area
# table of the whole frame, a dozen full-length temporaries and gathers per window;
# this is one pass per event, 3-5x faster at 1-3 M events/s, and releases the GIL.
_scratch = threading.local()

_PAD = 2
"""The count frames have this many zero pixels on every side: each event's 5x5 square
is then 25 reads at fixed offsets, with no bounds to clip (about 3x faster than
clipped loops on a 640x480 window of 60 k events)."""


def _count_frames(
    width: int, height: int, n_events: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count frames of one thread, reused across windows: the ON and all events per pixel
    of the sensor padded by :data:`_PAD` on every side (row stride ``width + 2 _PAD``),
    and two ring counts per padded pixel (read only where the counts say a pixel fired,
    after :func:`_ring_counts` wrote them).

    ``uint16`` for a window of fewer than 65,536 events (no pixel's count nor any
    square's sum can reach it), else ``int32``: half the bytes keep a 640x480 window's
    frames in a core's cache (its refinement 1.6x faster when other work ran between
    windows). The kernels leave the counts zeroed (they reset the pixels they touched):
    a fresh frame per window costs more in page faults than the counting itself.
    """
    dtype = np.uint16 if n_events <= np.iinfo(np.uint16).max else np.int32
    key = (int(width), int(height), np.dtype(dtype).char)
    frames = _scratch.__dict__.setdefault("counts", {})
    if key not in frames:
        for old in [k for k in frames if k[:2] != key[:2]]:
            del frames[old]  # another sensor's
        padded = (key[0] + 2 * _PAD) * (key[1] + 2 * _PAD)
        made = (np.zeros(padded, dtype), np.zeros(padded, dtype), np.zeros(2 * padded, dtype))
        for frame in made:
            frame.fill(0)  # their pages mapped now (warm-up), not in the first window
        frames[key] = made
    return frames[key]


def _seen_frame(width: int, height: int) -> np.ndarray:
    """One ``uint8`` mark per pixel of the sensor, zeroed, of one thread (the cell counts
    leave it zeroed)."""
    key = (int(width), int(height))
    if getattr(_scratch, "seen_key", None) != key:
        _scratch.seen_key = key
        _scratch.seen = np.zeros(key[0] * key[1], np.uint8)
    return _scratch.seen


@numba.njit(cache=True, nogil=True, inline="always")
def _padded_pixel(x, y, stride):  # pragma: no cover - compiled
    """Index of sensor pixel ``(x, y)`` in a padded frame of row stride ``stride``."""
    return (np.int64(y) + _PAD) * stride + np.int64(x) + _PAD


@numba.njit(cache=True, nogil=True)
def _count(x, y, p, on, total, stride, sign):  # pragma: no cover - compiled
    """Add (``sign`` 1) or remove (-1) the events' counts in the padded ON and total
    frames."""
    for i in range(x.size):
        pix = _padded_pixel(x[i], y[i], stride)
        total[pix] += sign
        on[pix] += sign * (p[i] != 0)


@numba.njit(cache=True, nogil=True, inline="always")
def _rings_at(total, stride, pix):  # pragma: no cover - compiled
    """Events in the 3x3 and the 5x5 squares centred on padded pixel ``pix``."""
    # the 5x5 square row by row (contiguous reads), its inner 3x3 on the way; the
    # padding keeps every read inside the frame
    corner = pix - _PAD * stride - _PAD
    b3 = np.int64(0)
    b5 = np.int64(0)
    for r in range(5):
        row = corner + r * stride
        inner = np.int64(total[row + 1]) + total[row + 2] + total[row + 3]
        b5 += inner + total[row] + total[row + 4]
        if 1 <= r <= 3:
            b3 += inner
    return b3, b5


@numba.njit(cache=True, nogil=True, inline="always")
def _pixel_row(x, y, p, on, total, stride, i, out):  # pragma: no cover - compiled
    """Event ``i``'s four counts (own polarity, other, 3x3 ring, 5x5 ring) into ``out``."""
    pix = _padded_pixel(x[i], y[i], stride)
    here = np.int64(total[pix])
    own = np.int64(on[pix]) if p[i] != 0 else here - on[pix]
    b3, b5 = _rings_at(total, stride, pix)
    out[0] = own
    out[1] = here - own
    out[2] = b3 - here
    out[3] = b5 - b3


_LOG1P_TABLE = 1024
"""Counts below this take their log1p from a table (the same values, computed once)."""


@numba.njit(cache=True, nogil=True)
def _log1p_table():  # pragma: no cover - compiled
    out = np.empty(_LOG1P_TABLE, np.float64)
    for k in range(_LOG1P_TABLE):
        out[k] = np.log1p(np.float64(k))
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _log1p_count(k, table):  # pragma: no cover - compiled
    return table[k] if k < table.size else np.log1p(np.float64(k))


@numba.njit(cache=True, nogil=True)
def _pixel_counts(x, y, p, on, total, stride):  # pragma: no cover - compiled
    """The four counts of every event ``(n, 4)``; ``on``/``total`` zeroed padded frames."""
    _count(x, y, p, on, total, stride, 1)
    out = np.empty((x.size, 4), np.int64)
    for i in range(x.size):
        _pixel_row(x, y, p, on, total, stride, i, out[i])
    _count(x, y, p, on, total, stride, -1)
    return out


_RING_MEMO_REPEATS = 0.5
"""Where at least this share of a window's events repeat a pixel, the refinement sums
each pixel's rings once (:func:`_ring_counts`); below it, once per event. The values
are the same; where most pixels fire once (a sparse 1280x720 window), the extra pass
over the pixels costs more than it saves."""


_BAND_ROWS_LOG2 = 3
"""The kernels visit a window's events band by band (:func:`event_records`), each band
this power of two of sensor rows (8), in time order within a band: the frames' rows a
band reads (12 rows of the counts) stay in the core's cache instead of being read at
random across the whole sensor. The values are the same; on a dense 1280x720 window of
500 k events the refinement costs a third less, sorting included."""


@numba.njit(cache=True, nogil=True)
def _band_records(t, x, y, p, t0, window_us, bins, height):  # pragma: no cover
    """The events' records ``(n, 4) int32`` in band order (a counting sort on
    ``y >> _BAND_ROWS_LOG2``, stable): ``x``, ``y``, twice the logits' channel plus the
    polarity (1 ON), the event's index in the window."""
    bands = (np.int64(height) >> _BAND_ROWS_LOG2) + 1
    first = np.zeros(bands + 1, np.int64)
    for i in range(y.size):
        first[(np.int64(y[i]) >> _BAND_ROWS_LOG2) + 1] += 1
    for b in range(bands):
        first[b + 1] += first[b]
    rec = np.empty((y.size, 4), np.int32)
    for i in range(y.size):
        b = np.int64(y[i]) >> _BAND_ROWS_LOG2
        k = first[b]
        first[b] = k + 1
        pol = np.int64(p[i] != 0)
        rec[k, 0] = x[i]
        rec[k, 1] = y[i]
        channel = ((np.int64(t[i]) - t0) * bins) // window_us + bins * (1 - pol)
        rec[k, 2] = 2 * channel + pol
        rec[k, 3] = i
    return rec


@numba.njit(cache=True, nogil=True)
def _ring_counts(rec, on, total, rings, stride):  # pragma: no cover - compiled
    """Count the records' events into the padded ``on`` and ``total``; where most of them
    repeat a pixel, also each pixel's 3x3 and 5x5 squares' events into ``rings[2 pix]``
    and ``rings[2 pix + 1]``, once per pixel that fired.

    A dense window's events repeat their pixels (84 % of the Gen3 light's do) and the
    squares depend on the pixel alone: summed once per pixel instead of once per event,
    the Gen3 light's refinement costs a third less. Returns the padded pixels that
    fired (to reset them) and whether ``rings`` holds their squares.
    """
    n_events = rec.shape[0]
    pixels = np.empty(n_events, np.int64)
    n = 0
    for k in range(n_events):
        pix = _padded_pixel(rec[k, 0], rec[k, 1], stride)
        if total[pix] == 0:
            pixels[n] = pix
            n += 1
        total[pix] += 1
        on[pix] += rec[k, 2] & 1
    memo = n_events - n >= _RING_MEMO_REPEATS * n_events
    if memo:
        for k in range(n):
            pix = pixels[k]
            rings[2 * pix], rings[2 * pix + 1] = _rings_at(total, stride, pix)
    return pixels[:n], memo


@numba.njit(cache=True, nogil=True, inline="always")
def _bilinear(logits, c, x, y, scale):  # pragma: no cover - compiled
    """``logits[c]`` sampled bilinearly at pixel ``(x, y)``'s centre, clipped to the cells."""
    _, h, w = logits.shape
    # align_corners=False: pixel centre x + 0.5 sits at (x + 0.5) / scale - 0.5 in cells
    fx = min(max((x + 0.5) / scale - 0.5, 0.0), w - 1.0)
    fy = min(max((y + 0.5) / scale - 0.5, 0.0), h - 1.0)
    x0, y0 = np.int64(np.floor(fx)), np.int64(np.floor(fy))
    x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
    ax, ay = fx - x0, fy - y0
    return (
        np.float64(logits[c, y0, x0]) * (1 - ax) * (1 - ay)
        + np.float64(logits[c, y0, x1]) * ax * (1 - ay)
        + np.float64(logits[c, y1, x0]) * (1 - ax) * ay
        + np.float64(logits[c, y1, x1]) * ax * ay
    )


@numba.njit(cache=True, nogil=True)
def _event_logits(
    rec, logits, scale, on, total, rings, stride, w_in, b_in, gain, w_out, b_out, support
):  # pragma: no cover - compiled
    """Each event's keep logit from the window's records (:func:`event_records`): the
    bilinear sample of ``logits (2 bins, h, w)`` at its pixel centre, plus the
    refinement where ``w_in`` has rows (see event_keep_mask). Where ``w_in`` has rows
    and ``support`` is as long as the events, also each event's :func:`event_support`
    into it (the refinement's four counts, summed)."""
    hidden = w_in.shape[0]
    out = np.empty(rec.shape[0], np.float64)
    if not hidden:
        for k in range(rec.shape[0]):
            out[rec[k, 3]] = _bilinear(logits, rec[k, 2] >> 1, rec[k, 0], rec[k, 1], scale)
        return out
    pixels, memo = _ring_counts(rec, on, total, rings, stride)
    # the hidden units' inputs by feature (contiguous over the units: the first layer
    # vectorises), each unit's output summed in order after
    w_t = np.ascontiguousarray(w_in.T)
    unit = np.empty(hidden, np.float64)
    table = _log1p_table()
    for k in range(rec.shape[0]):
        cp, i = rec[k, 2], rec[k, 3]
        v = _bilinear(logits, cp >> 1, rec[k, 0], rec[k, 1], scale)
        pix = _padded_pixel(rec[k, 0], rec[k, 1], stride)
        here = np.int64(total[pix])
        own = np.int64(on[pix]) if cp & 1 else here - on[pix]
        if memo:
            b3, b5 = np.int64(rings[2 * pix]), np.int64(rings[2 * pix + 1])
        else:
            b3, b5 = _rings_at(total, stride, pix)
        f0, f1, f2, f3 = own, here - own, b3 - here, b5 - b3
        if support.size:
            support[i] = f0 + f1 + f2 + f3 - 1
        g0, g1 = _log1p_count(f0, table), _log1p_count(f1, table)
        g2, g3 = _log1p_count(f2, table), _log1p_count(f3, table)
        for q in range(hidden):
            a = g0 * w_t[0, q] + g1 * w_t[1, q] + g2 * w_t[2, q] + g3 * w_t[3, q]
            a += b_in[q] + v * gain[q]
            unit[q] = max(a, 0.0) * w_out[q]
        delta = 0.0
        for q in range(hidden):
            delta += unit[q]
        out[i] = v + delta + b_out[0]
    for pix in pixels:
        on[pix] = 0
        total[pix] = 0
    return out


def event_pixel_features(events: np.ndarray, sensor_size: tuple[int, int]) -> np.ndarray:
    """The refinement's :data:`PIXEL_FEATURES` at each event ``(n, 4)`` (float64).

    Counts over the given events (one window), as :meth:`FlareMaskNet.pixel_logits`
    counts them in the window's voxel grid.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2], [1, 1, 2], [1, 1, 1], [1, 0, 1])
    >>> np.expm1(event_pixel_features(ev, (6, 4))).round().tolist()
    [[1.0, 1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 0.0], [1.0, 0.0, 2.0, 0.0]]
    """
    return np.log1p(_event_pixel_counts(events, sensor_size).astype(np.float64))


def _event_pixel_counts(events: np.ndarray, sensor_size: tuple[int, int]) -> np.ndarray:
    """The refinement's four counts at each event ``(n, 4)`` (int64), events checked on
    the sensor (the compiled kernel indexes its frames without bounds checks)."""
    width, height = int(sensor_size[0]), int(sensor_size[1])
    x, y = events["x"], events["y"]
    if events.size and (int(x.max()) >= width or int(y.max()) >= height):
        raise ValueError(f"events lie outside the {width}x{height} sensor")
    on, total, _ = _count_frames(width, height, events.size)
    return _pixel_counts(x, y, events["p"], on, total, width + 2 * _PAD)


def event_support(events: np.ndarray, sensor_size: tuple[int, int]) -> np.ndarray:
    """How many other events of the window fired in each event's 5x5 square (``int64``).

    The window's own events, both polarities, the event's pixel included (its other
    events there count): the sum of the refinement's four counts
    (:data:`PIXEL_FEATURES`) less the event itself. An isolated event, as the
    scattered light of a night lamp fires them along its streaks, has 0; an event on
    a moving edge has its neighbours along the edge.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2, 3], [1, 1, 3, 9], [1, 1, 2, 9], [1, 0, 1, 1])
    >>> event_support(ev, (12, 12)).tolist()   # (1, 1) twice, (3, 2) two away, (9, 9) alone
    [2, 2, 2, 0]
    """
    return _event_pixel_counts(events, sensor_size).sum(axis=1) - 1


def keep_logit_threshold(threshold: float) -> float:
    """The logit above which an event's keep probability :math:`\\sigma(\\ell + \\ln 3)` exceeds it.

    Examples
    --------
    >>> round(keep_logit_threshold(0.5), 4)  # -ln 3
    -1.0986
    """
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold must be in (0, 1), got {threshold}")
    return float(np.log(threshold / (1.0 - threshold)) - np.log(3.0))


def event_keep_logits(
    logits: np.ndarray,
    events: np.ndarray,
    window_start_us: int,
    window_us: int,
    scale: int,
    *,
    pixel_params: dict[str, np.ndarray] | None = None,
    sensor_size: tuple[int, int] | None = None,
    support: np.ndarray | None = None,
    records: EventRecords | None = None,
) -> np.ndarray:
    """Per-event keep logits (float64) from low-resolution logits ``(2 bins, h, w)``.

    What :func:`event_keep_mask` thresholds: the logit of the event's own
    polarity and bin, interpolated bilinearly at the event's pixel centre and
    refined with the event's pixel features where ``pixel_params`` are given.
    The window may start anywhere (it need not be aligned). ``support``, an
    ``int64`` array as long as the events, receives :func:`event_support` (with the
    refinement, from the counts it makes anyway: no second pass over the window).
    ``records``, the window's :func:`event_records` (at the logits' bins, checked on
    the sensor) if already made, saves making them again.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 15], [1, 1], [1, 1], [1, 1])
    >>> lg = np.zeros((4, 1, 1), np.float32); lg[1] = -5.0   # ON events of bin 1
    >>> event_keep_logits(lg, ev, 0, 20, scale=4).tolist()
    [0.0, -5.0]
    """
    if pixel_params is None:
        on = total = rings = np.zeros(0, np.int32)
        width = 0
        w_in = np.zeros((0, 4))
        b_in = gain = w_out = b_out = np.zeros(1)
    else:
        if sensor_size is None:
            raise ValueError("the per-pixel refinement needs the sensor size")
        width = int(sensor_size[0])
        on, total, rings = _count_frames(width, int(sensor_size[1]), events.size)
        w_in, b_in, gain, w_out, b_out = (
            np.ascontiguousarray(pixel_params[k], dtype=np.float64)
            for k in ("w_in", "b_in", "gain", "w_out", "b_out")
        )
    if support is not None and (support.shape != events.shape or support.dtype != np.int64):
        raise ValueError(f"support must be int64 of shape {events.shape}")
    if support is not None and pixel_params is None:
        if sensor_size is None:
            raise ValueError("the events' support needs the sensor size")
        support[:] = event_support(events, sensor_size)
    # the refinement counts into sensor-sized frames; the logits are sampled clipped
    on_sensor = sensor_size if pixel_params is not None else None
    if records is None:
        records = event_records(events, window_start_us, window_us, logits.shape[0] // 2, on_sensor)
    else:
        records.check(events, logits.shape[0] // 2, on_sensor)
    return _event_logits(
        records.rows,
        np.ascontiguousarray(logits, dtype=np.float32),
        int(scale),
        on,
        total,
        rings,
        width + 2 * _PAD,
        w_in,
        b_in,
        gain,
        w_out,
        b_out,
        np.zeros(0, np.int64) if support is None or pixel_params is None else support,
    )


def event_keep_mask(
    logits: np.ndarray,
    events: np.ndarray,
    window_start_us: int,
    window_us: int,
    scale: int,
    threshold: float = 0.5,
    *,
    pixel_params: dict[str, np.ndarray] | None = None,
    sensor_size: tuple[int, int] | None = None,
) -> np.ndarray:
    """Per-event keep decisions from low-resolution logits ``(2 bins, h, w)``.

    The logit of the event's own polarity and bin is interpolated bilinearly at
    the event's pixel centre (as :meth:`FlareMaskNet.forward` upsamples it),
    refined with the event's pixel features where ``pixel_params``
    (:meth:`FlareMaskNet.pixel_params`; needs ``sensor_size``) are given, and
    the event is kept where its keep probability :math:`\\sigma(\\ell + \\ln 3)`
    (:func:`keep_loss`'s) exceeds ``threshold``; at 1/2 that is
    :math:`\\min(1, 2\\sigma(\\ell)) > 1/2`, i.e. :math:`\\ell > -\\ln 3`. A lower
    threshold keeps more (of the scene, and of the flare).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 15], [1, 1], [1, 1], [1, 1])
    >>> lg = np.zeros((4, 1, 1), np.float32); lg[1] = -5.0   # drop ON events of bin 1
    >>> event_keep_mask(lg, ev, 0, 20, scale=4).tolist()
    [True, False]
    """
    cut = keep_logit_threshold(threshold)
    v = event_keep_logits(
        logits,
        events,
        window_start_us,
        window_us,
        scale,
        pixel_params=pixel_params,
        sensor_size=sensor_size,
    )
    return v > cut
