"""PFD: polarity-focused denoising (Shi et al., TCSVT 2025), the event-by-event program ``PFDs``.

Each pixel keeps its last ON time and last OFF time (0 = never), its last
event time (starting at 0), a stored polarity (unset at first) and a ring
buffer of its last ``fifo_size`` polarity-flip times. For each event, with
polarity ``p`` in {-1, +1}, in this order:

1. If the stored polarity is unset, store ``p``; else, if it is opposite to
   ``p``, push ``t`` into the flip buffer. The original never updates the
   stored polarity afterwards, so a flip means "opposite to the pixel's
   *first* event" (``flip_against_previous=True`` compares with the previous
   event instead, the evident intent).
2. Stage 1: record ``t`` as the pixel's last time of polarity ``p``; pass when
   at least ``min_support`` (``var``) of the in-bounds 8 neighbours have a
   same-polarity last time ``T != 0`` with ``t - T < stage1_window_us``.
3. Set the pixel's last event time to ``t``.
4. Stage 2, over the in-bounds 8 neighbours: ``n_active`` counts those with
   ``t - last_event_time <= window_us`` (all of them during the first
   ``window_us``, since last times start at 0); ``C_nbr`` sums their flips
   with ``t - ts <= window_us``; ``C_self`` counts the pixel's own.
5. Score: PFD-A ``|C_self - C_nbr / n_active|``; PFD-B ``C_nbr / n_active``.
   The original stores it in an ``int``, truncating it (so the test below is
   really ``score < 2``); ``real_valued_score=True`` keeps it real.
6. Keep the event when ``n_active > min_active`` (``neibor``), ``score <= 1``
   and stage 1 passed.

The quirks (first-polarity flips, truncated score, 0 as "never", neighbour
last times starting at 0, the 5-entry flip buffer) are reproduced by default
because the paper's PFD numbers come from the original program.

References
----------
C. Shi et al., "Polarity-Focused Denoising for Event Cameras", IEEE TCSVT
2025. Original program: github.com/shicy17/PFD @ 5618127, ``PFDs.cpp``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numba
import numpy as np

from .._registry import cli_option
from .._validation import check_int
from ..errors import ParameterError
from ..events import SensorSize, check_events, check_sensor_size
from ._compiled import prefetch as _prefetch

__all__ = ["PFDFilter", "PFDParams", "pfd", "pfd_mask"]

# An unused flip slot: far enough in the past never to count.
_NEVER = -(1 << 62)
_SCORES = {"A": True, "B": False}


@numba.njit(cache=True, nogil=True)
def _pfd_run(
    t,
    x,
    y,
    p,
    width,
    height,
    last_on,
    last_off,
    last_t,
    stored,
    flips,
    flip_head,
    stage1_window,
    window,
    min_support,
    min_active,
    score_a,
    flip_against_previous,
    real_valued_score,
    keep,
):  # pragma: no cover - compiled
    fifo = flips.shape[1]
    flat_flips = flips.reshape(flips.size)
    n = t.size
    for i in range(n):
        if i + 8 < n:  # fetch the 3x3 neighbourhood of a later event meanwhile
            kk = np.int64(y[i + 8]) * width + x[i + 8]
            for row in (kk - width, kk, kk + width):
                if 0 <= row < last_t.size:
                    _prefetch(last_t, row)
                    _prefetch(last_on if p[i + 8] else last_off, row)
                    _prefetch(flat_flips, row * fifo)
        ti = t[i]
        xi = np.int64(x[i])
        yi = np.int64(y[i])
        k = yi * width + xi
        pol = np.int8(1) if p[i] else np.int8(-1)
        # 1. stored polarity and flips (before scoring: an event's own flip counts)
        s = stored[k]
        if s == 0:
            stored[k] = pol
        else:
            if s != pol:
                h = flip_head[k]
                flips[k, h] = ti
                h += 1
                flip_head[k] = 0 if h == fifo else h
            if flip_against_previous:
                stored[k] = pol
        # 2. stage 1: same-polarity neighbours seen within the window (0 means never)
        same = last_on if pol == 1 else last_off
        same[k] = ti
        y0 = max(yi - 1, 0)
        y1 = min(yi + 1, height - 1)
        x0 = max(xi - 1, 0)
        x1 = min(xi + 1, width - 1)
        support = 0
        for yy in range(y0, y1 + 1):
            row = yy * width
            for xx in range(x0, x1 + 1):
                kk = row + xx
                if kk != k:
                    tt = same[kk]
                    if ti - tt < stage1_window and tt != 0:
                        support += 1
        # 3. last event time, any polarity
        last_t[k] = ti
        keep[i] = False
        if support < min_support:
            continue  # stage 2 has no side effect: skip it
        # 4. stage 2
        n_active = 0
        for yy in range(y0, y1 + 1):
            row = yy * width
            for xx in range(x0, x1 + 1):
                kk = row + xx
                if kk != k and ti - last_t[kk] <= window:
                    n_active += 1
        if n_active <= min_active:
            continue
        c_nbr = 0
        for yy in range(y0, y1 + 1):
            row = yy * width
            for xx in range(x0, x1 + 1):
                kk = row + xx
                if kk != k:
                    for j in range(fifo):
                        if ti - flips[kk, j] <= window:
                            c_nbr += 1
        # 5. score, in float64 as the original; 6. keep
        if score_a:
            c_self = 0
            for j in range(fifo):
                if ti - flips[k, j] <= window:
                    c_self += 1
            score = abs(np.float64(c_self) - np.float64(c_nbr) / np.float64(n_active))
        else:
            score = np.float64(c_nbr) / np.float64(n_active)
        if real_valued_score:
            keep[i] = score <= 1.0
        else:
            keep[i] = np.int64(score) <= 1  # the original's int truncation


@dataclass(frozen=True)
class PFDParams:
    """PFD's parameters, declared once: :class:`PFDFilter`, :func:`pfd`, :func:`pfd_mask`,
    the ``pfd-a`` / ``pfd-b`` methods and the command line's ``--pfd-*`` options take
    them from here (``score`` is the method's: A or B).

    See :class:`PFDFilter` for their meaning (paper: 20 ms windows, 3 neighbours).

    Examples
    --------
    >>> PFDParams().fifo_size
    5
    """

    cli_title: ClassVar[str] = "pfd-a / pfd-b (paper: 20 ms windows, 3 neighbours)"

    stage1_window_us: int = field(
        default=20_000,
        metadata=cli_option(
            "--pfd-stage1-window-ms", "stage-1 window", metavar="MS", unit="ms", type=float
        ),
    )
    window_us: int = field(
        default=20_000,
        metadata=cli_option(
            "--pfd-window-ms",
            "stage-2 window, and stage-1 unless --pfd-stage1-window-ms",
            metavar="MS",
            unit="ms",
            type=float,
        ),
    )
    min_support: int = field(
        default=1, metadata=cli_option("--pfd-min-support", "stage-1 'var'", metavar="N")
    )
    min_active: int = field(
        default=3,
        metadata=cli_option("--pfd-min-active", "stage-2 'neibor': keep needs more", metavar="N"),
    )
    fifo_size: int = field(
        default=5, metadata=cli_option("--pfd-fifo-size", "flip times kept per pixel", metavar="N")
    )
    flip_against_previous: bool = field(
        default=False,
        metadata=cli_option(
            "--pfd-flip-against-previous",
            "count flips against the previous event, not the pixel's first (not the original)",
            kind="flag",
        ),
    )
    real_valued_score: bool = field(
        default=False,
        metadata=cli_option(
            "--pfd-real-score",
            "test the real-valued score <= 1, not the original's truncated int",
            kind="flag",
        ),
    )


_D = PFDParams()


class PFDFilter:
    """PFD as a state machine: feed sorted chunks in order, the state carries over.

    Parameters
    ----------
    sensor_size : (width, height)
    stage1_window_us : int
        Stage-1 window ``delta_t0`` (paper: 20 ms).
    window_us : int
        Stage-2 window ``delta_t`` (paper: 20 ms).
    min_support : int
        Stage-1 neighbour threshold ``var`` (1).
    min_active : int
        Stage-2 active-neighbour threshold ``neibor`` (3): keep needs more.
    score : {"A", "B"}
        PFD-A (``score_select = 1``, general denoising) or PFD-B
        (``score_select = 0``, light-source artifacts).
    fifo_size : int
        Flip times kept per pixel (5).
    flip_against_previous : bool
        Count a flip against the previous event of the pixel (the evident
        intent) instead of its first event (the original).
    real_valued_score : bool
        Test the real score ``<= 1`` instead of the original's truncated int.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([100, 200], [0, 1], [0, 0], [1, 1])
    >>> PFDFilter((2, 1)).mask(ev).tolist()   # too few neighbours on a 2x1 sensor
    [False, False]
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        stage1_window_us: int = _D.stage1_window_us,
        window_us: int = _D.window_us,
        min_support: int = _D.min_support,
        min_active: int = _D.min_active,
        *,
        score: str = "A",
        fifo_size: int = _D.fifo_size,
        flip_against_previous: bool = _D.flip_against_previous,
        real_valued_score: bool = _D.real_valued_score,
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        width, height = self.sensor_size
        self.stage1_window_us = check_int("stage1_window_us", stage1_window_us, 0)
        self.window_us = check_int("window_us", window_us, 0)
        self.min_support = check_int("min_support", min_support, 0)
        self.min_active = check_int("min_active", min_active, 0)
        self.fifo_size = check_int("fifo_size", fifo_size, 1)
        if fifo_size > 255:
            raise ParameterError(f"fifo_size must be at most 255, got {fifo_size!r}")
        if score not in _SCORES:
            raise ParameterError(f"score must be 'A' or 'B', got {score!r}")
        self.score = score
        self.flip_against_previous = bool(flip_against_previous)
        self.real_valued_score = bool(real_valued_score)
        n = width * height
        self._last_on = np.zeros(n, dtype=np.int64)
        self._last_off = np.zeros(n, dtype=np.int64)
        self._last_t = np.zeros(n, dtype=np.int64)
        self._stored = np.zeros(n, dtype=np.int8)
        self._flips = np.full((n, self.fifo_size), _NEVER, dtype=np.int64)
        self._flip_head = np.zeros(n, dtype=np.uint8)
        self._t_last: int | None = None

    def mask(self, events: np.ndarray) -> np.ndarray:
        """Process the next chunk; return its keep mask (bool, one per event)."""
        check_events(events, self.sensor_size)
        keep = np.zeros(events.size, dtype=bool)
        if events.size == 0:
            return keep
        if self._t_last is not None and int(events["t"][0]) < self._t_last:
            raise ParameterError(
                f"chunks must come in time order: t={int(events['t'][0])} after t={self._t_last}"
            )
        self._t_last = int(events["t"][-1])
        width, height = self.sensor_size
        _pfd_run(
            events["t"],
            events["x"],
            events["y"],
            events["p"],
            np.int64(width),
            np.int64(height),
            self._last_on,
            self._last_off,
            self._last_t,
            self._stored,
            self._flips,
            self._flip_head,
            np.int64(self.stage1_window_us),
            np.int64(self.window_us),
            np.int64(self.min_support),
            np.int64(self.min_active),
            _SCORES[self.score],
            self.flip_against_previous,
            self.real_valued_score,
            keep,
        )
        return keep

    def filter(self, events: np.ndarray) -> np.ndarray:
        """Process the next chunk; return the events kept (a new array)."""
        return events[self.mask(events)]

    def pixel_state(self, x: int, y: int) -> dict[str, object]:
        """The state of pixel ``(x, y)``: last ON/OFF/any times, stored polarity, flip times.

        For inspection and tests. ``polarity`` is 0 (unset), 1 or -1; ``flips``
        lists the buffered flip times, oldest first.
        """
        width, height = self.sensor_size
        if not (0 <= x < width and 0 <= y < height):
            raise ParameterError(f"pixel ({x}, {y}) is not on the {width}x{height} sensor")
        k = y * width + x
        head = int(self._flip_head[k])
        order = [(head + j) % self.fifo_size for j in range(self.fifo_size)]
        flips = [int(self._flips[k, j]) for j in order if self._flips[k, j] != _NEVER]
        return {
            "last_on": int(self._last_on[k]),
            "last_off": int(self._last_off[k]),
            "last_t": int(self._last_t[k]),
            "polarity": int(self._stored[k]),
            "flips": flips,
        }

    @property
    def memory_bytes(self) -> int:
        """Bytes held by the filter state."""
        arrays = (
            self._last_on,
            self._last_off,
            self._last_t,
            self._stored,
            self._flips,
            self._flip_head,
        )
        return int(sum(a.nbytes for a in arrays))


def pfd_mask(
    events: np.ndarray,
    sensor_size: SensorSize,
    stage1_window_us: int = _D.stage1_window_us,
    window_us: int = _D.window_us,
    min_support: int = _D.min_support,
    min_active: int = _D.min_active,
    *,
    score: str = "A",
    fifo_size: int = _D.fifo_size,
    flip_against_previous: bool = _D.flip_against_previous,
    real_valued_score: bool = _D.real_valued_score,
) -> np.ndarray:
    """The keep mask of PFD over a whole stream (one pass). See :class:`PFDFilter`.

    Returns
    -------
    numpy.ndarray
        bool, one entry per input event, in input order.

    Examples
    --------
    A 3x3 block whose pixels all fire ON, then OFF (each OFF is a flip). The
    four corners have only 3 neighbours, never more than ``min_active = 3``:

    >>> from edeflare.events import make_events
    >>> xs, ys = [0, 1, 2] * 3, [0] * 3 + [1] * 3 + [2] * 3
    >>> on = make_events([100 + i for i in range(9)], xs, ys, [1] * 9)
    >>> off = make_events([5_000 + i for i in range(9)], xs, ys, [0] * 9)
    >>> ev = np.concatenate([on, off])
    >>> m = pfd_mask(ev, (3, 3))
    >>> m[:9].reshape(3, 3).astype(int).tolist()
    [[0, 1, 0], [1, 1, 1], [0, 1, 0]]
    >>> int(m[9:].sum())
    5
    """
    f = PFDFilter(
        sensor_size,
        stage1_window_us,
        window_us,
        min_support,
        min_active,
        score=score,
        fifo_size=fifo_size,
        flip_against_previous=flip_against_previous,
        real_valued_score=real_valued_score,
    )
    return f.mask(events)


def pfd(
    events: np.ndarray,
    sensor_size: SensorSize,
    stage1_window_us: int = _D.stage1_window_us,
    window_us: int = _D.window_us,
    min_support: int = _D.min_support,
    min_active: int = _D.min_active,
    *,
    score: str = "A",
    fifo_size: int = _D.fifo_size,
    flip_against_previous: bool = _D.flip_against_previous,
    real_valued_score: bool = _D.real_valued_score,
) -> np.ndarray:
    """Denoise with PFD (one pass): the events it keeps, in order. See :class:`PFDFilter`.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 10], [0, 1], [0, 0], [1, 0])
    >>> len(pfd(ev, (2, 1), score="B"))
    0
    """
    mask = pfd_mask(
        events,
        sensor_size,
        stage1_window_us,
        window_us,
        min_support,
        min_active,
        score=score,
        fifo_size=fifo_size,
        flip_against_previous=flip_against_previous,
        real_valued_score=real_valued_score,
    )
    return events[mask]
