"""A mask model's keep decisions from two windowings of a stream, averaged.

Where a recording's windows start relative to what it shows is chance, and one
windowing can flatter or wrong a model: on the DAVIS346 flicker lamps the
default model alone removes 84 % of the flare with windows at one phase and
36 % a quarter window later (the lamps flicker at 100 Hz: a 10 ms shift would
see them at the same phase again, 5 ms at the opposite one). A mask model
therefore judges each event in the aligned windows and in windows delayed by
a quarter window, and keeps it where the mean of its two keep logits passes.
"""

from __future__ import annotations

import concurrent.futures
import functools
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..events import concat_events, select_events
from ..methods.base import EMPTY, Streamer
from .weights import ModelCard

__all__ = ["TwoViewStreamer", "check_phase_shift", "view_windows"]


def check_phase_shift(phase_shift_us: object, card: ModelCard, where: object) -> int:
    """The delay of the second view: a quarter of a mask model's window by default, else 0.

    Examples
    --------
    >>> check_phase_shift(None, ModelCard(preset="mask.lite"), "m.safetensors")
    5000
    >>> check_phase_shift(None, ModelCard(preset="unet2d.lite"), "m.safetensors")
    0
    """
    mask = card.preset.startswith("mask.")
    if phase_shift_us is None:
        phase_shift_us = card.window_us // 4 if mask else 0
    if (
        isinstance(phase_shift_us, bool)
        or not isinstance(phase_shift_us, (int, np.integer))
        or not 0 <= phase_shift_us < card.window_us
    ):
        raise ParameterError(
            f"phase_shift_us must be an int in [0, {card.window_us}) (the model's "
            f"window), got {phase_shift_us!r}"
        )
    if phase_shift_us and not mask:
        raise ParameterError(
            f"phase_shift_us needs a mask model; {where} is a {card.preset} "
            "(voxel-to-voxel): give 0"
        )
    return int(phase_shift_us)


def view_windows(
    t: np.ndarray, window_us: int, delay_us: int, until_us: int | None = None
) -> list[tuple[int, int, int]]:
    """``(start_us, first, end)`` of each window of sorted timestamps ``t`` in the windowing
    delayed by ``delay_us`` (windows start at ``k * window_us - delay_us``; only those that
    hold an event), its events ``t[first:end]``; with ``until_us``, up to the first window
    that ends after it.

    Examples
    --------
    >>> view_windows(np.array([1, 4, 12, 13]), 10, 5)
    [(-5, 0, 2), (5, 2, 4)]
    >>> view_windows(np.array([1, 4, 12, 13]), 10, 0, until_us=12)
    [(0, 0, 2)]
    """
    out = []
    i = 0
    while i < t.size:
        start = (int(t[i]) + delay_us) // window_us * window_us - delay_us
        end = start + window_us
        if until_us is not None and end > until_us:
            break
        k = int(np.searchsorted(t, end, side="left"))
        out.append((start, i, k))
        i = k
    return out


@functools.cache
def _blas_threads() -> Any:
    """numpy's BLAS libraries, whose thread counts can be limited (threadpoolctl)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController().select(user_api="blas")


class TwoViewStreamer(Streamer):
    """A mask model's keep decisions from two windowings of the stream, averaged.

    View 0 cuts the stream into aligned windows of ``window_us``, view 1 into
    the same windows delayed by ``shift_us``. ``logits(batch)`` gives per-event
    keep logits for a list of ``(window_start, events)``; an event is kept
    where the mean of its two logits exceeds ``cut``. Events are emitted once
    both of their windows are complete, so outputs lag the input by up to a
    window plus the shift.
    """

    def __init__(
        self,
        window_us: int,
        shift_us: int,
        logits: Callable[[list[tuple[int, np.ndarray]]], list[np.ndarray]],
        cut: float,
        batch_windows: int,
    ) -> None:
        self.window_us = window_us
        self.delays = (0, shift_us)
        self.logits = logits
        self.cut = cut
        self.batch_windows = batch_windows
        self.pending = EMPTY  # events not yet emitted
        # per view, the logits of the first pending events (those whose window is done)
        self.done: list[np.ndarray] = [np.zeros(0), np.zeros(0)]
        # the second view's thread, kept for the stream: the per-event kernels' frames
        # are per thread (16 MB at 1280x720), and a new thread per window paid for
        # zeroing fresh ones every window
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None

    def warm_up(self, work: Callable[[], object]) -> None:
        """Run ``work`` (a model's warm-up) on the second view's thread, and wait: the
        thread's first window then finds its kernels' frames made, as the main thread's."""
        self._second_view_pool().submit(work).result()

    def _second_view_pool(self) -> concurrent.futures.ThreadPoolExecutor:
        if self._pool is None:
            self._pool = concurrent.futures.ThreadPoolExecutor(1, "edeflare-view")
            weakref.finalize(self, self._pool.shutdown, wait=False)
        return self._pool

    def _batches(self, view: int, until_us: int | None) -> list[list[tuple[int, np.ndarray]]]:
        """The view's complete windows not yet judged, in network batches."""
        w, delay = self.window_us, self.delays[view]
        events = self.pending[self.done[view].size :]
        t = np.ascontiguousarray(events["t"])  # searched once per window: no strided copies
        windows = [(start, events[i:k]) for start, i, k in view_windows(t, w, delay, until_us)]
        step = self.batch_windows
        return [windows[j : j + step] for j in range(0, len(windows), step)]

    def _judge(self, batches: list[list[tuple[int, np.ndarray]]]) -> list[np.ndarray]:
        return [v for batch in batches for v in self.logits(batch)]

    def _advance(self, until_us: int | None) -> None:
        work = [self._batches(view, until_us) for view in (0, 1)]
        if work[0] and work[1]:
            # the two views are independent: the second runs on another core (the
            # per-event kernels and the network release the GIL); the results do not
            # depend on it
            # numpy's BLAS (a learned head's matrix products) would start threads of its
            # own in each view, two per core: a head of 64 and 32 ran 1.5x slower on 2
            # cores. Limited from this thread alone, around both views (the products'
            # values do not depend on their thread count).
            with _blas_threads().limit(limits=1):
                second = self._second_view_pool().submit(self._judge, work[1])
                values = [self._judge(work[0]), second.result()]
        else:
            values = [self._judge(w) for w in work]
        self.done = [np.concatenate([d, *v]) for d, v in zip(self.done, values, strict=True)]

    def _emit(self) -> np.ndarray:
        n = min(v.size for v in self.done)
        keep = (self.done[0][:n] + self.done[1][:n]) / 2 > self.cut
        out = select_events(self.pending[:n], keep)
        self.pending = self.pending[n:]
        self.done = [v[n:] for v in self.done]
        return out

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        if events.size:
            self.pending = concat_events([self.pending, events]) if self.pending.size else events
        self._advance(until_us)
        return self._emit()

    def flush(self) -> np.ndarray:
        self._advance(None)
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        return self._emit()
