"""EFR: the event-based linear comb filter of Wang et al. (ICRA 2022), as the original runs.

EFR removes periodic (flicker) events with a per-pixel linear comb filter built
from four FIFO queues of ``(time, value)`` and an event sampler. With base
frequency ``f``, ``d1 = 1e6 // f`` µs (integer division, as the original) and
``d2 = d1 / 10`` (a float: 833.3 µs at 120 Hz), every pixel runs, on each
input event of polarity ``p`` in {-1, +1}, in this order:

- **q1**, pure delay ``d1``: push ``(t, p - b)``; each entry at least ``d1``
  old leaves and sends ``(t_old + d1, -v)`` to q2; then ``(t, p - b)`` goes
  to q2.
- **q2**, feedback at period ``d1``: each entry at least ``d1`` old (relative
  to the incoming time) is re-pushed as ``(t_old + d1, rho1 * v)`` and the
  same pair is sent to q3; the incoming value is then added into the back
  entry when their times differ by less than ``merge_us``, else appended.
- **q3**, pure delay ``d2``: push; each entry at least ``d2`` old sends
  ``(t_old + d2, -rho2 * v)`` to q4; then the pushed pair goes to q4.
- **q4**, recirculation at period ``d2`` with gain 1: each due entry is
  re-pushed as ``(t_old + d2, v)``, ``v`` is added to the accumulator and the
  sampler runs at ``t_old + d2``; incoming values merge as in q2.
- **sampler**: while ``|acc| >= threshold``, emit ``(t, x, y, sign(acc))``
  and move ``acc`` by ``threshold`` toward zero.

Here ``rho2 = 1 - (1 - rho1) / 10`` and ``b`` is the pixel's bias (see
:func:`efr_bias`). Every value is float64 and computed in the original's
order of operations (sampler decisions within 1e-9 of the threshold are
common, so a different order or float32 flips events). The quirks of the
original are kept on purpose, because the paper's EFR numbers come from it:

- "at least ``d2`` old" compares an integer age with the float ``d2``, so at
  120 Hz an entry is due at 834 µs, while forwarded times are truncated to
  ``t_old + 833``. We use ``ceil(d2)`` for ages and ``floor(d2)`` for
  forwarded times (identical for the non-negative times the original takes).
- Queues of a pixel advance only while an event *of that pixel* is being
  handled, so outputs appear when a later event reaches the same pixel,
  timestamped in the past, and nothing is flushed at the end of the input.
- Outputs are delayed by the filter: the earliest output of a stream is at
  least ``delay_us = d1 + floor(d2)`` after its first event (22 ms at 50 Hz).

The paper's wrapper (Appendix D) keeps the input events of the first
``delay_us`` of the stream and appends them unmodified to the output; that is
the default here (``keep_warmup``). ``shift_back=True`` instead moves every
output ``delay_us`` earlier. Warm-up events and filter outputs never share a
timestamp, so the result is well defined in either case.

The bias is computed by the original over the **whole input** before
filtering. :func:`efr` does that for an in-memory stream; to stream a file,
make a first pass with :func:`efr_bias` over its chunks and give the map to
:class:`EFRFilter` (``edeflare.deflare_file`` does exactly this).

References
----------
Z. Wang, D. Yuan, Y. Ng, R. Mahony, "A Linear Comb Filter for Event Flicker
Removal", ICRA 2022. Original program: github.com/ziweiWWANG/EFR @ a0e0189.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numba
import numpy as np

from .._registry import cli_option
from ..errors import EventFileError, ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size, sort_events
from ._compiled import prefetch as _prefetch

__all__ = ["EFRFilter", "EFRParams", "efr", "efr_bias", "efr_delays", "load_bias_map"]

_TIME_RESOLUTION_US = 1_000_000
_NO_TIME = np.iinfo(np.int64).max
# Columns of the per-(pixel, queue) ring-buffer table.
_BASE, _CAP, _HEAD, _SIZE = 0, 1, 2, 3
_Q1, _Q2, _Q3, _Q4 = 0, 1, 2, 3
_FIRST_BLOCK = 4
_POOL_LIMIT = np.iinfo(np.int32).max


def load_bias_map(path: str | os.PathLike[str]) -> np.ndarray:
    """Read an EFR bias map ``(H, W)`` saved with ``numpy.save`` (``.npy``)."""
    try:
        bias = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise EventFileError(Path(path), f"cannot read a bias map ({exc})") from None
    if not isinstance(bias, np.ndarray) or bias.ndim != 2:
        raise EventFileError(Path(path), "a bias map must be a 2-D (H, W) array in a .npy file")
    return bias


@dataclass(frozen=True)
class EFRParams:
    """EFR's parameters, declared once: :class:`EFRFilter`, :func:`efr`, the ``efr``
    method and the command line's ``--efr-*`` options take them from here.

    See :class:`EFRFilter` for their meaning (paper: 50 Hz, rho1 0.6, 10 ms, 0.7).

    Examples
    --------
    >>> EFRParams().frequency_hz, EFRParams(rho1=0.5).rho1
    (50.0, 0.5)
    """

    cli_title: ClassVar[str] = "efr (paper: 50 Hz, rho1 0.6)"

    frequency_hz: float = field(
        default=50.0, metadata=cli_option("--efr-frequency", "base frequency", metavar="HZ")
    )
    rho1: float = field(
        default=0.6, metadata=cli_option("--rho1", "feedback gain of the first comb")
    )
    merge_us: int = field(
        default=10_000,
        metadata=cli_option("--efr-merge-ms", "merge window", metavar="MS", unit="ms", type=float),
    )
    threshold: float = field(
        default=0.7, metadata=cli_option("--efr-threshold", "sampler threshold", metavar="X")
    )
    bias: np.ndarray | None = field(
        default=None,
        compare=False,
        metadata=cli_option(
            "--efr-bias",
            "per-pixel bias map (H, W); default: computed over the input (a first pass)",
            metavar="FILE.npy",
            type=Path,
            convert=load_bias_map,
        ),
    )
    min_bias_events: int = field(
        default=20,
        metadata=cli_option("--efr-min-bias-events", "events for a pixel's bias", metavar="N"),
    )
    keep_warmup: bool | None = field(
        default=None,
        metadata=cli_option(
            "--efr-warmup",
            "keep the input events of the first d1+d2 unchanged",
            kind="bool",
            default_text="yes, unless shifted back",
        ),
    )
    shift_back: bool = field(
        default=False,
        metadata=cli_option(
            "--efr-shift-back",
            "move outputs back by the filter delay (then the warm-up is not kept)",
            kind="flag",
        ),
    )


_D = EFRParams()


def efr_delays(frequency_hz: float) -> tuple[int, float]:
    """The comb delays ``(d1_us, d2_us)`` the original derives from a base frequency.

    ``d1`` is the integer division ``1_000_000 // f`` (the original reads
    ``f`` as an int; a fractional ``f`` is floored the same way) and
    ``d2 = d1 / 10`` stays a float.

    Examples
    --------
    >>> efr_delays(50), efr_delays(120)
    ((20000, 2000.0), (8333, 833.3))
    """
    f = float(frequency_hz)
    if not math.isfinite(f) or f <= 0:
        raise ParameterError(f"frequency_hz must be a positive number, got {frequency_hz!r}")
    d1 = _TIME_RESOLUTION_US // int(f) if f.is_integer() else math.floor(_TIME_RESOLUTION_US / f)
    if d1 < 10:
        raise ParameterError(
            f"frequency_hz={frequency_hz!r} is too high: the delay d2 = d1/10 must be >= 1 µs "
            "(use at most 100000 Hz)"
        )
    return int(d1), d1 / 10


def efr_bias(
    events: np.ndarray | Iterable[np.ndarray],
    sensor_size: SensorSize,
    min_events: int = _D.min_bias_events,
) -> np.ndarray:
    """Per-pixel polarity bias ``(N_on - N_off) / (N_on + N_off)``, as EFR computes it.

    Pixels with fewer than ``min_events`` events get 0. The original computes
    this over the whole input before filtering; pass an iterable of chunks
    (for example ``edeflare.open_events(path).chunks()``) to compute it over a
    file without loading it.

    Parameters
    ----------
    events : numpy.ndarray or iterable of numpy.ndarray
        One stream, or its chunks.
    sensor_size : (width, height)
    min_events : int
        Pixels with fewer events have bias 0 (original: 20).

    Returns
    -------
    numpy.ndarray
        float64 ``(H, W)``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2, 3], [0, 0, 0, 1], [0, 0, 0, 0], [1, 1, 0, 1])
    >>> efr_bias(ev, (2, 1), min_events=3).tolist()
    [[0.3333333333333333, 0.0]]
    """
    width, height = check_sensor_size(sensor_size)
    if not isinstance(min_events, (int, np.integer)) or min_events < 0:
        raise ParameterError(f"min_events must be a non-negative int, got {min_events!r}")
    chunks = [events] if isinstance(events, np.ndarray) else events
    n_all = np.zeros(width * height, dtype=np.int64)
    n_on = np.zeros(width * height, dtype=np.int64)
    for chunk in chunks:
        check_events(chunk, (width, height))
        if chunk.size:
            _count_polarities(chunk["x"], chunk["y"], chunk["p"], width, n_all, n_on)
    bias = np.zeros(width * height, dtype=np.float64)
    ok = (n_all >= min_events) & (n_all > 0)
    # (N_on - N_off) / N, with the counts exact in float64 as in the original.
    bias[ok] = (2.0 * n_on[ok] - n_all[ok]) / n_all[ok].astype(np.float64)
    return bias.reshape(height, width)


@numba.njit(cache=True, nogil=True)
def _count_polarities(x, y, p, width, n_all, n_on):  # pragma: no cover - compiled
    for i in range(x.size):
        k = np.int64(y[i]) * width + x[i]
        n_all[k] += 1
        n_on[k] += p[i]


# --------------------------------------------------------------------------------------
# The compiled filter. Each pixel's queues are ring buffers carved from one pool (times and
# values); a queue that outgrows its block moves to a block twice as large at the end of the
# pool. An event only touches its own pixel, so it runs on a scratch copy of that pixel's
# q2..q4 (q1 stays in the pool: an event only appends to it and pops from it), with the ring
# indices in local variables, and is committed at the end. When an array is too small the
# event is abandoned before anything is committed and the kernel returns, so that Python
# can grow the array and resume at the same event: arrays are never reallocated inside the
# compiled loops (numba's reference counting of reassigned arrays would cost 3-4x).

_OK, _NEED_POOL, _NEED_OUT, _NEED_SCRATCH = 0, 1, 2, 3
_AHEAD = 8  # events ahead whose pixel state is prefetched


@numba.njit(cache=True, nogil=True)
def _move_block(meta, pool_t, pool_v, top, k, q, new_cap):  # pragma: no cover - compiled
    """Copy queue ``q`` of pixel ``k`` to a new block of ``new_cap`` at the pool's end."""
    base = np.int64(meta[k, q, _BASE])
    cap = np.int64(meta[k, q, _CAP])
    head = np.int64(meta[k, q, _HEAD])
    size = np.int64(meta[k, q, _SIZE])
    start = top[0]
    for i in range(size):
        j = head + i
        if j >= cap:
            j -= cap
        pool_t[start + i] = pool_t[base + j]
        pool_v[start + i] = pool_v[base + j]
    meta[k, q, _BASE] = start
    meta[k, q, _CAP] = new_cap
    meta[k, q, _HEAD] = 0
    top[0] = start + new_cap


@numba.njit(cache=True, nogil=True)
def _efr_event(
    ti,
    xi,
    yi,
    pi,
    k,
    meta,
    pool_t,
    pool_v,
    top,
    acc,
    bias,
    sc_t,
    sc_v,
    step1,
    due1,
    step2,
    due2,
    rho1,
    rho2,
    merge_us,
    threshold,
    warm_end,
    shift,
    out_t,
    out_x,
    out_y,
    out_p,
    n_out,
):  # pragma: no cover - compiled
    """Run one event through pixel ``k``'s queues: ``(status, n_out)``.

    The nesting mirrors the original's calls: q1 -> q2 -> q3 -> q4 -> sampler.
    On a status other than ``_OK`` nothing has been committed.
    """
    room = sc_t.size // 3  # scratch ring capacity per queue (a power of two)
    mask = room - 1
    u = (1.0 if pi else -1.0) - bias[k]
    if ti < warm_end:  # the paper's wrapper keeps warm-up inputs as they are
        if n_out == out_t.size:
            return _NEED_OUT, n_out
        out_t[n_out] = ti
        out_x[n_out] = xi
        out_y[n_out] = yi
        out_p[n_out] = pi
        n_out += 1
    # q1 stays in the pool; make room for its push first (a committed relocation is harmless).
    s1 = np.int64(meta[k, _Q1, _SIZE])
    c1 = np.int64(meta[k, _Q1, _CAP])
    if s1 == c1:
        new_cap = _FIRST_BLOCK if c1 == 0 else 2 * c1
        if top[0] + new_cap > pool_t.size:
            return _NEED_POOL, n_out
        _move_block(meta, pool_t, pool_v, top, k, _Q1, new_cap)
        c1 = new_cap
    b1 = np.int64(meta[k, _Q1, _BASE])
    h1 = np.int64(meta[k, _Q1, _HEAD])
    # q2, q3, q4 -> scratch rings at 0, room, 2 * room (head 0).
    for q in range(1, 4):
        size = np.int64(meta[k, q, _SIZE])
        if size >= room:
            return _NEED_SCRATCH, n_out
        base = np.int64(meta[k, q, _BASE])
        cap = np.int64(meta[k, q, _CAP])
        head = np.int64(meta[k, q, _HEAD])
        dst = (q - 1) * room
        for i in range(size):
            j = head + i
            if j >= cap:
                j -= cap
            sc_t[dst + i] = pool_t[base + j]
            sc_v[dst + i] = pool_v[base + j]
    o2 = 0
    o3 = room
    o4 = 2 * room
    h2 = 0
    h3 = 0
    h4 = 0
    s2 = np.int64(meta[k, _Q2, _SIZE])
    s3 = np.int64(meta[k, _Q3, _SIZE])
    s4 = np.int64(meta[k, _Q4, _SIZE])
    acc_k = acc[k]
    # ---- update_q1(ti, u): push, then forward every entry at least d1 old, then u itself
    j = h1 + s1
    if j >= c1:
        j -= c1
    pool_t[b1 + j] = ti
    pool_v[b1 + j] = u
    s1 += 1
    last1 = False
    while not last1:
        if ti - pool_t[b1 + h1] >= due1:
            t2 = pool_t[b1 + h1] + step1
            v2 = -pool_v[b1 + h1]
            h1 += 1
            if h1 == c1:
                h1 = 0
            s1 -= 1
        else:
            t2 = ti
            v2 = u
            last1 = True
        # ---- update_q2(t2, v2): feedback entries at least d1 old, then merge or append
        while s2 > 0:
            f = o2 + h2
            if t2 - sc_t[f] < due1:
                break
            t3 = sc_t[f] + step1
            v3 = rho1 * sc_v[f]
            h2 = (h2 + 1) & mask
            f = o2 + ((h2 + s2 - 1) & mask)  # re-push at the back (the pop made room)
            sc_t[f] = t3
            sc_v[f] = v3
            # ---- update_q3(t3, v3): push, forward entries at least d2 old, then v3 itself
            if s3 == room:
                return _NEED_SCRATCH, n_out
            f = o3 + ((h3 + s3) & mask)
            sc_t[f] = t3
            sc_v[f] = v3
            s3 += 1
            last3 = False
            while not last3:
                f = o3 + h3
                if t3 - sc_t[f] >= due2:
                    t4 = sc_t[f] + step2
                    v4 = -rho2 * sc_v[f]
                    h3 = (h3 + 1) & mask
                    s3 -= 1
                else:
                    t4 = t3
                    v4 = v3
                    last3 = True
                # ---- update_q4(t4, v4): recirculate entries at least d2 old into the sampler
                if s4 == 1:  # the common case (merging keeps q4 short): cycle in registers
                    f = o4 + h4
                    t5 = sc_t[f]
                    v5 = sc_v[f]
                    while t4 - t5 >= due2:
                        t5 += step2
                        acc_k += v5
                        while acc_k >= threshold or acc_k <= -threshold:
                            if n_out == out_t.size:
                                return _NEED_OUT, n_out
                            out_t[n_out] = t5 - shift
                            out_x[n_out] = xi
                            out_y[n_out] = yi
                            if acc_k >= threshold:
                                out_p[n_out] = 1
                                acc_k -= threshold
                            else:
                                out_p[n_out] = 0
                                acc_k += threshold
                            n_out += 1
                    sc_t[f] = t5
                while s4 > 1:
                    f = o4 + h4
                    if t4 - sc_t[f] < due2:
                        break
                    t5 = sc_t[f] + step2
                    v5 = sc_v[f]
                    h4 = (h4 + 1) & mask
                    f = o4 + ((h4 + s4 - 1) & mask)
                    sc_t[f] = t5
                    sc_v[f] = v5
                    acc_k += v5
                    # ---- sampler at t5
                    while acc_k >= threshold or acc_k <= -threshold:
                        if n_out == out_t.size:
                            return _NEED_OUT, n_out
                        out_t[n_out] = t5 - shift
                        out_x[n_out] = xi
                        out_y[n_out] = yi
                        if acc_k >= threshold:
                            out_p[n_out] = 1
                            acc_k -= threshold
                        else:
                            out_p[n_out] = 0
                            acc_k += threshold
                        n_out += 1
                f = o4 + ((h4 + s4 - 1) & mask)
                if s4 > 0 and abs(sc_t[f] - t4) < merge_us:
                    sc_v[f] += v4
                else:
                    if s4 == room:
                        return _NEED_SCRATCH, n_out
                    f = o4 + ((h4 + s4) & mask)
                    sc_t[f] = t4
                    sc_v[f] = v4
                    s4 += 1
        f = o2 + ((h2 + s2 - 1) & mask)
        if s2 > 0 and abs(sc_t[f] - t2) < merge_us:
            sc_v[f] += v2
        else:
            if s2 == room:
                return _NEED_SCRATCH, n_out
            f = o2 + ((h2 + s2) & mask)
            sc_t[f] = t2
            sc_v[f] = v2
            s2 += 1
    # ---- commit: blocks large enough for q2..q4, then entries, heads, sizes, accumulator
    need = 0
    for q in range(1, 4):
        size = s2 if q == 1 else (s3 if q == 2 else s4)
        cap = np.int64(meta[k, q, _CAP])
        if size > cap:
            new_cap = max(_FIRST_BLOCK, cap)
            while new_cap < size:
                new_cap *= 2
            need += new_cap
    if top[0] + need > pool_t.size:
        return _NEED_POOL, n_out
    for q in range(1, 4):
        if q == 1:
            size, head, src = s2, h2, o2
        elif q == 2:
            size, head, src = s3, h3, o3
        else:
            size, head, src = s4, h4, o4
        cap = np.int64(meta[k, q, _CAP])
        if size > cap:
            new_cap = max(_FIRST_BLOCK, cap)
            while new_cap < size:
                new_cap *= 2
            meta[k, q, _BASE] = top[0]
            meta[k, q, _CAP] = new_cap
            top[0] += new_cap
        base = np.int64(meta[k, q, _BASE])
        for i in range(size):
            f = src + ((head + i) & mask)
            pool_t[base + i] = sc_t[f]
            pool_v[base + i] = sc_v[f]
        meta[k, q, _HEAD] = 0
        meta[k, q, _SIZE] = size
    meta[k, _Q1, _HEAD] = h1
    meta[k, _Q1, _SIZE] = s1
    acc[k] = acc_k
    return _OK, n_out


@numba.njit(cache=True, nogil=True)
def _efr_run(
    t,
    x,
    y,
    p,
    start,
    width,
    meta,
    pool_t,
    pool_v,
    top,
    acc,
    bias,
    sc_t,
    sc_v,
    step1,
    due1,
    step2,
    due2,
    rho1,
    rho2,
    merge_us,
    threshold,
    warm_end,
    shift,
    out_t,
    out_x,
    out_y,
    out_p,
    n_out,
):  # pragma: no cover - compiled
    """Events ``start..`` through the filter: ``(next event, n_out, status)``."""
    n = t.size
    meta_flat = meta.reshape(meta.size)
    for i in range(start, n):
        # Prefetch the pixel state of later events: their meta rows first, then (once
        # those have arrived) the queue blocks they point to.
        if i + _AHEAD < n:
            kk = np.int64(y[i + _AHEAD]) * width + x[i + _AHEAD]
            _prefetch(meta_flat, kk * 16)
            _prefetch(acc, kk)
        if i + _AHEAD // 2 < n:
            kk = np.int64(y[i + _AHEAD // 2]) * width + x[i + _AHEAD // 2]
            for q in range(4):
                if meta[kk, q, _CAP] > 0:
                    _prefetch(pool_t, np.int64(meta[kk, q, _BASE]) + meta[kk, q, _HEAD])
        k = np.int64(y[i]) * width + x[i]
        status, n_new = _efr_event(
            t[i],
            x[i],
            y[i],
            p[i],
            k,
            meta,
            pool_t,
            pool_v,
            top,
            acc,
            bias,
            sc_t,
            sc_v,
            step1,
            due1,
            step2,
            due2,
            rho1,
            rho2,
            merge_us,
            threshold,
            warm_end,
            shift,
            out_t,
            out_x,
            out_y,
            out_p,
            n_out,
        )
        if status != _OK:
            return i, n_out, status
        n_out = n_new
    return t.size, n_out, _OK


@numba.njit(cache=True, nogil=True)
def _compact(meta, pool_t, pool_v, new_t, new_v):  # pragma: no cover - compiled
    """Copy every live block into ``new_*`` back to back (dropping garbage); return the top."""
    top = 0
    n_pix, n_q, _ = meta.shape
    for k in range(n_pix):
        for q in range(n_q):
            cap = np.int64(meta[k, q, _CAP])
            if cap == 0:
                continue
            base = np.int64(meta[k, q, _BASE])
            for i in range(cap):
                new_t[top + i] = pool_t[base + i]
                new_v[top + i] = pool_v[base + i]
            meta[k, q, _BASE] = top
            top += cap
    return top


@numba.njit(cache=True, nogil=True)
def _pending_min(meta, pool_t):  # pragma: no cover - compiled
    """Smallest time held in any queue (int64 max when all are empty)."""
    best = np.iinfo(np.int64).max
    n_pix, n_q, _ = meta.shape
    for k in range(n_pix):
        for q in range(n_q):
            size = meta[k, q, _SIZE]
            if size == 0:
                continue
            base = np.int64(meta[k, q, _BASE])
            cap = np.int64(meta[k, q, _CAP])
            head = np.int64(meta[k, q, _HEAD])
            for j in range(size):
                jj = head + j
                if jj >= cap:
                    jj -= cap
                v = pool_t[base + jj]
                if v < best:
                    best = v
    return best


def _check_real(name: str, value: Any, lo: float, hi: float, *, lo_open: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(v) or v > hi or v < lo or (lo_open and v == lo):
        bound = f"({lo}, {hi}]" if lo_open else f"[{lo}, {hi}]"
        raise ParameterError(f"{name} must lie in {bound}, got {value!r}")
    return v


class EFRFilter:
    """EFR as a state machine: feed sorted chunks in order, the state carries over.

    Feeding a stream chunk by chunk gives exactly the outputs of one call on
    the whole stream, in the same order.

    Parameters
    ----------
    sensor_size : (width, height)
    frequency_hz : float
        Base flicker frequency (paper: 50 Hz); its harmonics are notched
        except multiples of ``10 * frequency_hz``.
    rho1 : float
        Feedback gain of the first comb (original default 0.6), in [0, 1).
    merge_us : int
        q2/q4 merge window ``delta_t`` (original default 10 ms).
    threshold : float
        Sampler threshold (original default 0.7).
    bias : numpy.ndarray, optional
        float64 ``(H, W)`` map from :func:`efr_bias` computed over the whole
        input (as the original does); ``None`` means zero bias.
    keep_warmup : bool, optional
        Pass the input events of the first ``delay_us`` of the stream through
        unchanged (the paper's wrapper). Default: ``not shift_back``.
    shift_back : bool
        Move every filter output ``delay_us`` earlier, compensating the delay.

    Attributes
    ----------
    d1_us : int
    d2_us : float
    rho2 : float
    delay_us : int
        ``d1 + floor(d2)``: the minimum delay from an input to an output.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 30_000, 42_000], [0] * 3, [0] * 3, [1] * 3)
    >>> f = EFRFilter((1, 1), 50)
    >>> f.process(ev[:2])["t"].tolist()   # the warm-up event (t < 22 ms) passes through
    [0]
    >>> f.process(ev[2:])["t"].tolist()   # the queues advance: an output stamped 32 ms
    [32000]
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        frequency_hz: float = _D.frequency_hz,
        rho1: float = _D.rho1,
        merge_us: int = _D.merge_us,
        threshold: float = _D.threshold,
        *,
        bias: np.ndarray | None = _D.bias,
        keep_warmup: bool | None = _D.keep_warmup,
        shift_back: bool = _D.shift_back,
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        width, height = self.sensor_size
        self.frequency_hz = frequency_hz
        self.d1_us, self.d2_us = efr_delays(frequency_hz)
        self.rho1 = _check_real("rho1", rho1, 0.0, 1.0)
        if self.rho1 == 1.0:
            raise ParameterError("rho1 must be below 1 (the feedback comb would not decay)")
        self.rho2 = 1 - (1 - self.rho1) / 10
        if isinstance(merge_us, bool) or not isinstance(merge_us, (int, np.integer)):
            raise ParameterError(f"merge_us must be an int number of µs, got {merge_us!r}")
        if merge_us < 0:
            raise ParameterError(f"merge_us must be >= 0, got {merge_us!r}")
        self.merge_us = int(merge_us)
        self.threshold = _check_real("threshold", threshold, 0.0, math.inf, lo_open=True)
        self.shift_back = bool(shift_back)
        self.keep_warmup = (not self.shift_back) if keep_warmup is None else bool(keep_warmup)
        # Ages are integers compared with the float delays; forwarded times are truncated.
        self._step1 = self.d1_us
        self._due1 = self.d1_us
        self._step2 = math.floor(self.d2_us)
        self._due2 = math.ceil(self.d2_us)
        self.delay_us = self._step1 + self._step2
        # Per pixel (accumulator, bias) side by side, and each queue entry's (time, value)
        # side by side: an event then touches few cache lines.
        self._pixel = np.zeros((width * height, 2), dtype=np.float64)
        self._acc = self._pixel[:, 0]
        self._bias = self._pixel[:, 1]
        if bias is not None:
            b = np.asarray(bias)
            if b.shape != (height, width):
                raise ParameterError(
                    f"bias must have shape (H, W) = ({height}, {width}), got {b.shape}"
                )
            if b.dtype.kind not in "fiu" or not np.isfinite(b).all():
                raise ParameterError("bias must hold finite numbers")
            self._bias[:] = b.reshape(-1)
        self._meta = np.zeros((width * height, 4, 4), dtype=np.int32)
        self._set_pool(np.empty(2 << 16, dtype=np.int64))
        self._top = np.zeros(1, dtype=np.int64)
        self._scratch_t = np.empty(3 * 64, dtype=np.int64)
        self._scratch_v = np.empty(3 * 64, dtype=np.float64)
        self.t_first_us: int | None = None
        self._t_last: int | None = None

    def _grow_pool(self) -> None:
        """Double the queue pool, compacting it: live blocks only, in pixel order."""
        n = 2 * self._pool_t.size
        if n > _POOL_LIMIT:
            raise MemoryError("EFR queue pool would exceed 2**31 entries")
        old_t, old_v = self._pool_t, self._pool_v
        self._set_pool(np.empty(2 * n, dtype=np.int64))
        self._top[0] = _compact(self._meta, old_t, old_v, self._pool_t, self._pool_v)

    def _set_pool(self, pool: np.ndarray) -> None:
        self._pool = pool
        self._pool_t = pool[0::2]
        self._pool_v = pool.view(np.float64)[1::2]

    @property
    def bias(self) -> np.ndarray:
        """The bias map in use, float64 ``(H, W)`` (a copy)."""
        width, height = self.sensor_size
        return self._bias.reshape(height, width).copy()

    @property
    def warmup_end_us(self) -> int | None:
        """Inputs before this time are passed through (None before the first event)."""
        if self.t_first_us is None:
            return None
        return self.t_first_us + self.delay_us if self.keep_warmup else self.t_first_us

    def process(self, events: np.ndarray) -> np.ndarray:
        """Filter the next chunk; return what the filter emitted meanwhile, in emission order.

        The result is sorted per pixel, not globally (outputs are stamped with
        queue times in the past): :func:`edeflare.events.sort_events` sorts it.
        """
        check_events(events, self.sensor_size)
        if events.size == 0:
            return np.zeros(0, dtype=EVENT_DTYPE)
        if self._t_last is not None and int(events["t"][0]) < self._t_last:
            raise ParameterError(
                f"chunks must come in time order: t={int(events['t'][0])} after t={self._t_last}"
            )
        if self.t_first_us is None:
            self.t_first_us = int(events["t"][0])
        self._t_last = int(events["t"][-1])
        n = events.size
        out = [
            np.empty(max(1024, n // 2), dtype=np.int64),
            np.empty(max(1024, n // 2), dtype=np.uint16),
            np.empty(max(1024, n // 2), dtype=np.uint16),
            np.empty(max(1024, n // 2), dtype=np.uint8),
        ]
        warm_end = self.warmup_end_us
        shift = self.delay_us if self.shift_back else 0
        t, x, y, p = events["t"], events["x"], events["y"], events["p"]
        i = n_out = 0
        while True:
            i, n_out, status = _efr_run(
                t,
                x,
                y,
                p,
                i,
                np.int64(self.sensor_size[0]),
                self._meta,
                self._pool_t,
                self._pool_v,
                self._top,
                self._acc,
                self._bias,
                self._scratch_t,
                self._scratch_v,
                np.int64(self._step1),
                np.int64(self._due1),
                np.int64(self._step2),
                np.int64(self._due2),
                np.float64(self.rho1),
                np.float64(self.rho2),
                np.int64(self.merge_us),
                np.float64(self.threshold),
                np.int64(warm_end),
                np.int64(shift),
                *out,
                n_out,
            )
            if status == _OK:
                break
            if status == _NEED_POOL:
                self._grow_pool()
            elif status == _NEED_OUT:
                out = [np.concatenate([a, np.empty_like(a)]) for a in out]
            else:
                self._scratch_t = np.empty(2 * self._scratch_t.size, dtype=np.int64)
                self._scratch_v = np.empty(2 * self._scratch_v.size, dtype=np.float64)
        ot, ox, oy, op = out
        result = np.empty(n_out, dtype=EVENT_DTYPE)
        result["t"] = ot[:n_out]
        result["x"] = ox[:n_out]
        result["y"] = oy[:n_out]
        result["p"] = op[:n_out]
        return result

    def safe_time_us(self, next_input_us: int) -> int:
        """No future output falls before this, if later inputs start at ``next_input_us``.

        Every future output is a queue time plus at least ``floor(d2)``, or a
        later input's time plus ``delay_us`` (minus the shift when
        ``shift_back``), or a warm-up input. This scans every queue: O(pixels).
        """
        next_input_us = int(next_input_us)
        bound = next_input_us + self.delay_us
        pending = int(_pending_min(self._meta, self._pool_t))
        if pending != _NO_TIME:
            bound = min(bound, pending + self._step2)
        if self.shift_back:
            bound -= self.delay_us
        warm_end = self.warmup_end_us
        if self.keep_warmup and (warm_end is None or next_input_us < warm_end):
            bound = min(bound, next_input_us)
        return bound

    def pixel_state(self, x: int, y: int) -> tuple[list[list[tuple[int, float]]], float]:
        """The queues q1..q4 of pixel ``(x, y)`` as ``(time, value)`` lists, and its accumulator.

        For inspection and tests; queue order is front first.
        """
        width, height = self.sensor_size
        if not (0 <= x < width and 0 <= y < height):
            raise ParameterError(f"pixel ({x}, {y}) is not on the {width}x{height} sensor")
        k = y * width + x
        queues = []
        for q in range(4):
            base, cap, head, size = (int(v) for v in self._meta[k, q])
            idx = [base + (head + i) % cap for i in range(size)]
            queues.append([(int(self._pool_t[i]), float(self._pool_v[i])) for i in idx])
        return queues, float(self._acc[k])

    @property
    def memory_bytes(self) -> int:
        """Bytes held by the filter state."""
        return int(
            self._meta.nbytes
            + self._pool.nbytes
            + self._pixel.nbytes
            + self._scratch_t.nbytes
            + self._scratch_v.nbytes
        )


def efr(
    events: np.ndarray,
    sensor_size: SensorSize,
    frequency_hz: float = _D.frequency_hz,
    rho1: float = _D.rho1,
    merge_us: int = _D.merge_us,
    threshold: float = _D.threshold,
    *,
    bias: np.ndarray | None = _D.bias,
    min_bias_events: int = _D.min_bias_events,
    keep_warmup: bool | None = _D.keep_warmup,
    shift_back: bool = _D.shift_back,
) -> np.ndarray:
    """Remove flicker with EFR (one pass over the whole stream), sorted by time.

    Parameters
    ----------
    events : numpy.ndarray
        A sorted stream (:data:`~edeflare.events.EVENT_DTYPE`); not modified.
    sensor_size : (width, height)
    frequency_hz, rho1, merge_us, threshold
        See :class:`EFRFilter` (paper: 50 Hz, 0.6, 10 ms, 0.7).
    bias : numpy.ndarray, optional
        ``(H, W)`` bias map; default: computed over ``events`` with
        :func:`efr_bias` (``min_bias_events``), as the original does.
    keep_warmup, shift_back
        See :class:`EFRFilter`. By default the input events of the first
        ``d1 + floor(d2)`` µs are kept unchanged (the paper's wrapper).

    Returns
    -------
    numpy.ndarray
        New events, stably sorted by ``t`` (ties in emission order).

    Notes
    -----
    Per pixel, in z-transform terms (``z`` one period of the queue clock),
    ``H(z) = (1 - z^-d1) / (1 - rho1 z^-d1) * (1 - rho2 z^-d2) / (1 - z^-d2)``:
    zeros at every multiple of ``f`` except multiples of ``10 f``.

    Examples
    --------
    A pixel flickering at 50 Hz (one ON and one OFF event per period) goes
    quiet once the warm-up has passed:

    >>> from edeflare.events import make_events
    >>> t = [k * 10_000 for k in range(40)]
    >>> ev = make_events(t, [0] * 40, [0] * 40, [1, 0] * 20)
    >>> out = efr(ev, (1, 1), 50)
    >>> len(out), int(out["t"].max())
    (3, 20000)
    """
    check_events(events, sensor_size)
    if bias is None:
        bias = efr_bias(events, sensor_size, min_bias_events)
    f = EFRFilter(
        sensor_size,
        frequency_hz,
        rho1,
        merge_us,
        threshold,
        bias=bias,
        keep_warmup=keep_warmup,
        shift_back=shift_back,
    )
    return sort_events(f.process(events))
