"""Collecting the report's figures while a benchmark runs: samples, reconstructions, scores.

:class:`FigureCollector` is the ``on_output`` hook of
:func:`edeflare.eval.benchmark.benchmark`: each sequence offers its window with
the most flare (the largest ``sum |N_input - N_gt|`` over pixels of the
per-pixel event counts) and the sequences with the largest amounts are kept
(ties: earlier sequence first); it keeps only the kept samples' pictures, the
reconstructions by the leaky integrator (:mod:`edeflare.eval.reconstruct`)
and the flare scores (:mod:`edeflare.eval.flare_score`) of every window, never
whole streams. :func:`edeflare.eval.report.write_report` turns what it
collected (:class:`FigureData`) into the HTML page.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize
from ..viz import event_frame
from .flare_score import FlareGeometry, flare_geometry, region_energies
from .reconstruct import LeakyIntegrator

__all__ = [
    "FIGURE_KINDS",
    "GT",
    "INPUT",
    "FigureCollector",
    "FigureData",
    "Sample",
    "nan_median",
    "window_label",
]

INPUT = "input"
GT = "ground truth"
_RAW = "raw"
FIGURE_KINDS = ("reconstruction", "events")
"""What the flare score is computed on: ``|L|`` of the reconstruction, or event counts."""


@dataclass
class Sample:
    """One chosen window of one sequence, as pictures and scores per stream.

    Streams are keyed by column name: ``"input"``, each method row (the
    ``raw`` row is the input and is left out), ``"ground truth"``.
    """

    sequence: str
    order: int
    window_start_us: int
    t_start_us: int
    window_us: int
    flare_amount: float
    geometry: FlareGeometry
    gif_starts: list[int] = field(default_factory=list)
    frames: dict[str, np.ndarray] = field(default_factory=dict)
    """Event frame (RGB ``uint8``) of the window."""
    recon: dict[str, np.ndarray] = field(default_factory=dict)
    """Reconstruction ``L`` (``float32`` ``(H, W)``) at the window's end."""
    gif: dict[str, list[np.ndarray]] = field(default_factory=dict)
    """Event frames of consecutive windows (``gif_starts``)."""
    scores: dict[str, float] = field(default_factory=dict)
    """Flare score of ``|L|`` (the reconstruction), on the input's geometry."""

    @property
    def label(self) -> str:
        """``"<sequence> <a>-<b> ms"`` (time from the sequence start)."""
        return window_label(self.sequence, self.window_start_us, self.t_start_us, self.window_us)


def window_label(sequence: str, start_us: int, t0_us: int, window_us: int) -> str:
    """A window's caption: the sequence and its span in ms from ``t0_us``.

    Examples
    --------
    >>> window_label("seq_00003", 40_000, 0, 20_000)
    'seq_00003 40-60 ms'
    """
    a = (start_us - t0_us) / 1000
    return f"{sequence} {a:g}-{a + window_us / 1000:g} ms"


@dataclass(frozen=True)
class FigureData:
    """What the report's figures need, as collected during a benchmark."""

    columns: list[str]
    """``input``, the method rows except ``raw``, ``ground truth``."""
    samples: list[Sample]
    energies: dict[str, dict[str, np.ndarray]]
    """``{kind: {column: (n_windows, 2) array}}``: the source and flare energies
    (:func:`edeflare.eval.flare_score.region_energies`) of every window of the split, on
    the input's geometry; ``kind`` is ``"reconstruction"`` (``|L|`` at the window's
    end) or ``"events"`` (event counts of the window)."""
    sensor_size: SensorSize | None
    cutoff_hz: float
    contrast: float

    @property
    def n_windows(self) -> int:
        """Windows scored (over every sequence)."""
        return len(self.energies["events"][INPUT])

    def scores(self, kind: str) -> dict[str, np.ndarray]:
        """Column -> flare score of every window (NaN where the source holds no energy)."""
        out = {}
        for column, e in self.energies[kind].items():
            with np.errstate(divide="ignore", invalid="ignore"):
                out[column] = np.where(e[:, 0] > 0, e[:, 1] / e[:, 0], np.nan)
        return out

    def medians(self) -> dict[str, dict[str, float]]:
        """``{kind: {column: median flare score over the windows where it is defined}}``."""
        return {
            kind: {c: nan_median(v.tolist()) for c, v in self.scores(kind).items()}
            for kind in FIGURE_KINDS
        }

    def kept(self, kind: str) -> dict[str, tuple[float, float]]:
        """Column -> shares of the input's (flare, source) energy, summed over all windows."""
        total = self.energies[kind][INPUT].sum(axis=0)
        out = {}
        for column, e in self.energies[kind].items():
            s = e.sum(axis=0)
            out[column] = tuple(
                float(s[i] / total[i]) if total[i] > 0 else math.nan for i in (1, 0)
            )
        return out


def nan_median(values: Sequence[float]) -> float:
    """The median of the values that are not NaN (NaN when none is).

    Examples
    --------
    >>> nan_median([1.0, float("nan"), 3.0])
    2.0
    """
    vals = [v for v in values if not math.isnan(v)]
    return float(statistics.median(vals)) if vals else math.nan


_CHUNK_WINDOWS = 16  # reconstruction frames held at once per stream


class FigureCollector:
    """Keeps the pictures of the most flared windows while a benchmark runs.

    Pass it as ``on_output`` to :func:`edeflare.eval.benchmark.benchmark`, then
    call :meth:`finish`. Each sequence offers its window with the most flare
    (``sum |N_input - N_gt|`` of per-pixel event counts); the ``samples``
    sequences with the largest amounts are kept, ties to the earlier one.
    For every window of every sequence and every stream it also computes
    the flare score (:func:`edeflare.eval.flare_score.flare_score`, geometry
    located on the input's event counts of the window) of the window's
    event counts and of ``|L|``, the stream's reconstruction at the window's
    end (:class:`edeflare.eval.reconstruct.LeakyIntegrator`, run over the whole
    sequence a few windows at a time).

    Parameters
    ----------
    samples : int
        Rows of the qualitative grid.
    gif_windows : int
        Consecutive windows per GIF (around the sample window).
    cutoff_hz, contrast : float
        Reconstruction parameters (:func:`edeflare.eval.reconstruct.reconstruct`).
    source_radius_px, flare_radius_px : float, optional
        Flare-score radii (:func:`edeflare.eval.flare_score.flare_geometry`).

    Examples
    --------
    >>> from edeflare.data.toy import toy_flare_pair
    >>> scene = toy_flare_pair((64, 48), duration_us=40_000, rng=0)
    >>> c = FigureCollector(samples=1)
    >>> c(row="pfd-b", path="seq", inputs=scene.observed, gt=scene.clean,
    ...   output=scene.clean, sensor_size=(64, 48), start_us=0, end_us=40_000, window_us=20_000)
    >>> data = c.finish()
    >>> data.columns, len(data.samples), data.n_windows
    (['input', 'pfd-b', 'ground truth'], 1, 2)
    """

    def __init__(
        self,
        samples: int = 4,
        gif_windows: int = 5,
        *,
        cutoff_hz: float = 5.0,
        contrast: float = 0.2,
        source_radius_px: float | None = None,
        flare_radius_px: float | None = None,
    ) -> None:
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 0:
            raise ParameterError(f"samples must be an int >= 0, got {samples!r}")
        if isinstance(gif_windows, bool) or not isinstance(gif_windows, int) or gif_windows < 0:
            raise ParameterError(f"gif_windows must be an int >= 0, got {gif_windows!r}")
        # Check the parameters now rather than after the first sequence.
        LeakyIntegrator((1, 1), cutoff_hz=cutoff_hz, contrast=contrast)
        self.n_samples = samples
        self.gif_windows = gif_windows
        self.cutoff_hz = float(cutoff_hz)
        self.contrast = float(contrast)
        self.radii = {"source_radius_px": source_radius_px, "flare_radius_px": flare_radius_px}
        self._rows: list[str] = []
        self._samples: list[Sample] = []
        self._energies: dict[str, dict[str, list[tuple[float, float]]]] = {
            kind: {INPUT: [], GT: []} for kind in FIGURE_KINDS
        }
        self._current: str | None = None
        self._order = -1
        self._size: SensorSize | None = None
        self._starts = np.zeros(0, dtype=np.int64)
        self._window_us = 1
        self._geometries: list[FlareGeometry] = []
        self._pending: Sample | None = None

    def __call__(
        self,
        *,
        row: str,
        path: str | os.PathLike[str],
        inputs: np.ndarray,
        gt: np.ndarray,
        output: np.ndarray,
        sensor_size: SensorSize,
        start_us: int,
        end_us: int,
        window_us: int,
    ) -> None:
        """Take one method's output on one sequence (the benchmark's ``on_output`` hook)."""
        if row in (INPUT, GT):
            raise ParameterError(f"a method row may not be called {row!r} in a report")
        key = os.fspath(path)
        if key != self._current:
            self._begin(key, inputs, gt, sensor_size, start_us, end_us, window_us)
        if row == _RAW:
            return  # the input itself: its column is "input"
        if row not in self._rows:
            self._rows.append(row)
            for kind in FIGURE_KINDS:
                self._energies[kind][row] = []
        self._stream(row, output)

    def _index(self, events: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Window bounds (``n + 1`` indices) and flat pixel indices of a stream."""
        width = self._size[0] if self._size else 1
        bounds = np.append(self._starts, self._starts[-1] + self._window_us)
        idx = np.searchsorted(events["t"], bounds, side="left")
        flat = events["y"].astype(np.int64) * width + events["x"]
        return idx, flat

    def _counts(self, flat: np.ndarray, lo: int, hi: int) -> np.ndarray:
        width, height = self._size or (1, 1)
        counts = np.bincount(flat[lo:hi], minlength=width * height)
        return counts.reshape(height, width).astype(np.float64)

    def _begin(
        self,
        key: str,
        inputs: np.ndarray,
        gt: np.ndarray,
        size: SensorSize,
        start: int,
        end: int,
        window_us: int,
    ) -> None:
        self._current = key
        self._order += 1
        self._size = size
        self._window_us = int(window_us)
        self._starts = np.arange(int(start), int(end), int(window_us), dtype=np.int64)
        self._geometries = []
        self._pending = None
        if not self._starts.size:
            return
        amounts = []
        idx_in, flat_in = self._index(inputs)
        idx_gt, flat_gt = self._index(gt)
        for k in range(self._starts.size):
            e_in = self._counts(flat_in, idx_in[k], idx_in[k + 1])
            e_gt = self._counts(flat_gt, idx_gt[k], idx_gt[k + 1])
            amounts.append(float(np.abs(e_in - e_gt).sum()))
            self._geometries.append(flare_geometry(e_in, **self.radii))
        j = int(np.argmax(amounts))  # the first of equal amounts
        held = [(-s.flare_amount, s.order) for s in self._samples]
        full = len(held) >= self.n_samples
        if self.n_samples and not (full and (-amounts[j], self._order) >= max(held)):
            n = self._starts.size
            g0 = max(0, min(j - self.gif_windows // 2, n - self.gif_windows))
            sample = Sample(
                sequence=Path(key).stem,
                order=self._order,
                window_start_us=int(self._starts[j]),
                t_start_us=int(start),
                window_us=int(window_us),
                flare_amount=amounts[j],
                geometry=self._geometries[j],
                gif_starts=[int(g) for g in self._starts[g0 : g0 + self.gif_windows]],
            )
            self._samples.append(sample)
            self._samples.sort(key=lambda s: (-s.flare_amount, s.order))
            del self._samples[self.n_samples :]
            self._pending = sample
        self._stream(INPUT, inputs, idx_in, flat_in)
        self._stream(GT, gt, idx_gt, flat_gt)

    def _stream(
        self,
        name: str,
        events: np.ndarray,
        idx: np.ndarray | None = None,
        flat: np.ndarray | None = None,
    ) -> None:
        """Score every window of one stream; keep the pictures of the pending sample."""
        size = self._size
        n = self._starts.size
        if size is None or not n:
            return
        if idx is None or flat is None:
            idx, flat = self._index(events)
        sample = self._pending
        keep = {sample.window_start_us, *sample.gif_starts} if sample else set()
        gif: dict[int, np.ndarray] = {}
        integrator = LeakyIntegrator(size, cutoff_hz=self.cutoff_hz, contrast=self.contrast)
        ends = self._starts + self._window_us
        for a in range(0, n, _CHUNK_WINDOWS):
            b = min(n, a + _CHUNK_WINDOWS)
            lo = 0 if a == 0 else int(idx[a])  # the state starts with the stream
            frames = integrator.frames(events[lo : int(idx[b])], ends[a:b])
            for k in range(a, b):
                geometry = self._geometries[k]
                energy = self._counts(flat, idx[k], idx[k + 1])
                self._energies["events"][name].append(region_energies(energy, geometry))
                recon = region_energies(np.abs(frames[k - a]), geometry)
                self._energies["reconstruction"][name].append(recon)
                w = int(self._starts[k])
                if sample is None or w not in keep:
                    continue
                picture = event_frame(events[idx[k] : idx[k + 1]], size)
                gif[w] = picture
                if w == sample.window_start_us:
                    sample.frames[name] = picture
                    sample.recon[name] = frames[k - a].copy()
                    sample.scores[name] = recon[1] / recon[0] if recon[0] > 0 else math.nan
        if sample is not None:
            sample.gif[name] = [gif[g] for g in sample.gif_starts]

    def finish(self) -> FigureData:
        """The collected figures (samples in decreasing flare, then sequence order)."""
        columns = [INPUT, *self._rows, GT]
        return FigureData(
            columns,
            list(self._samples),
            {
                kind: {
                    c: np.array(self._energies[kind][c], dtype=np.float64).reshape(-1, 2)
                    for c in columns
                }
                for kind in FIGURE_KINDS
            },
            self._size,
            self.cutoff_hz,
            self.contrast,
        )
