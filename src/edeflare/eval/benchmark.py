"""The paper's benchmark on a dataset: every method on every test sequence, metrics, speed.

A dataset split is a folder of sequence files (``input`` and ``gt`` groups,
see :mod:`edeflare.io.sequence`). For each method (a registered name, with
parameters) and each sequence, the input is streamed window by window
through the method (as ``edeflare deflare`` does), its outputs are cut into
the aligned 20 ms segments of the sequence span ``[t_start_us, t_end_us)``,
and each segment is scored against the ground truth's with
:func:`edeflare.eval.metrics.segment_metrics` as soon as it is complete, so
memory is bounded by a window, not by the sequence. The results equal
de-flaring the whole input in memory (a method's streamer and its one-pass
call agree). Means are over segments, then over sequences (as
:func:`edeflare.eval.evaluate.evaluate`). With ``convention="authors"`` each
sequence's ground truth and output over the span are kept whole and scored
as one file the way the authors' evaluation code scores it
(:mod:`edeflare.eval.authors`); the means are then over sequences. Speed is measured per method as
20 ms windows per second and real-time factor (processing time over stream
duration; below 1 is faster than real time), excluding reading and scoring.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._progress import progress_bar
from ..errors import ParameterError
from ..events import SensorSize, concat_events, empty_events, iter_chunk_windows
from ..io import open_events
from ..io.sequence import list_sequences, read_frames, sequence_span
from ..methods import Method, StreamRun, create_method
from ..recon.clips import BURN_IN, centre_image
from .authors import authors_metrics, check_convention
from .downstream import CleanFrame, DownstreamScores
from .evaluate import (
    Evaluation,
    Summary,
    combine_summaries,
    summarize,
    summarize_authors,
)
from .metrics import segment_metrics
from .tables import ResultsTable

__all__ = ["GROUND_TRUTH", "BenchmarkResult", "MethodSpeed", "benchmark"]

GROUND_TRUTH = "ground truth"
"""The downstream row of the ground truth's own events (the reconstruction ceiling)."""


@dataclass(frozen=True)
class MethodSpeed:
    """Processing speed of one method over the benchmark."""

    seconds: float
    windows: int
    stream_us: int

    @property
    def windows_per_s(self) -> float:
        """20 ms windows processed per second."""
        return self.windows / self.seconds if self.seconds else math.inf

    @property
    def real_time_factor(self) -> float:
        """Processing time over stream duration (below 1: faster than real time)."""
        return self.seconds / (self.stream_us / 1e6) if self.stream_us else math.nan


@dataclass(frozen=True)
class BenchmarkResult:
    """Metrics (``evaluation``), speed (``speed``) and reconstruction scores (``downstream``).

    ``downstream`` maps each row, and ``"ground truth"`` (the reconstruction
    of the ground-truth events), to ``{"psnr", "ssim", "windows"}``; it is
    empty unless the benchmark ran with ``downstream`` on a split whose files
    hold clean frames (:mod:`edeflare.eval.downstream`).
    """

    evaluation: Evaluation
    speed: dict[str, MethodSpeed] = field(default_factory=dict)
    downstream: dict[str, dict[str, float]] = field(default_factory=dict)
    downstream_sample: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    """One sequence's reconstructions, ``(T, H, W)`` in [0, 1] per stream, and its
    ``"clean"`` frames mapped alike: the report's side-by-side animation."""

    def downstream_markdown(self) -> str:
        """Reconstruction table in Markdown (empty string without downstream scores)."""
        if not self.downstream:
            return ""
        lines = [
            "| Stream | PSNR (dB)↑ | SSIM↑ | flare-region RMSE↓ | windows |",
            "|---|---|---|---|---|",
        ]
        for name, d in self.downstream.items():
            flare = d.get("flare", math.nan)
            lines.append(
                f"| {name} | {d['psnr']:.2f} | {d['ssim']:.4f} | {flare:.4f} | {d['windows']} |"
            )
        return "\n".join(lines) + "\n"

    def table(self) -> ResultsTable:
        """The paper's table (raw input unranked, best/second marked, improvement row)."""
        return ResultsTable({m: s.means for m, s in self.evaluation.methods.items()})

    def speed_markdown(self) -> str:
        """Speed table in Markdown."""
        lines = ["| Method | windows/s | real-time factor |", "|---|---|---|"]
        for name, s in self.speed.items():
            lines.append(f"| {name} | {s.windows_per_s:.2f} | {s.real_time_factor:.3g} |")
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "evaluation": self.evaluation.to_dict(),
            "speed": {
                n: {
                    "seconds": s.seconds,
                    "windows": s.windows,
                    "stream_us": s.stream_us,
                    "windows_per_s": s.windows_per_s,
                    "real_time_factor": s.real_time_factor,
                }
                for n, s in self.speed.items()
            },
            "downstream": {
                row: {k: v if math.isfinite(v) else None for k, v in d.items()}
                for row, d in self.downstream.items()
            },
        }


def benchmark(
    split: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    methods: Mapping[str, str | Method],
    *,
    params: Mapping[str, Mapping[str, Any]] | None = None,
    window_us: int = 20_000,
    bins: int = 8,
    seed: int = 0,
    progress: bool = True,
    on_output: Callable[..., None] | None = None,
    downstream: bool | str | os.PathLike[str] = False,
    convention: str = "edeflare",
) -> BenchmarkResult:
    """Run and score every method on every sequence of a split.

    Parameters
    ----------
    split : path-like or sequence of path-like
        A folder of sequence files, or the files.
    methods : mapping
        Row name -> registered method name or :class:`~edeflare.methods.Method`.
        Call the unprocessed input ``raw`` to get the unranked Raw Input row.
    params : mapping, optional
        Row name -> method parameters (for names).
    seed : int
        Seeds methods that draw (voxel, model decoders), per sequence.
    on_output : callable, optional
        Called after each method ran on each sequence (untimed), with keyword
        arguments ``row, path, inputs, gt, output, sensor_size, start_us,
        end_us, window_us``, e.g. to keep a few windows for figures
        (:class:`edeflare.eval.report.FigureCollector`). Rows run in order, all
        rows of a sequence before the next sequence. The hook receives whole
        streams, so with a hook one sequence's input, ground truth and output
        are held in memory at a time; without one, only a window is.
    downstream : bool or path-like
        Also reconstruct every stream into images and score them against the
        files' clean frames (:mod:`edeflare.eval.downstream`): ``True`` with
        the bundled reconstructor, or a reconstructor weights file. Files
        without frames are left out of these scores.
    convention : {"edeflare", "authors"}
        ``edeflare``: aligned 20 ms segments scored as each completes;
        ``authors``: each sequence scored whole as the authors' code scores a
        file (:mod:`edeflare.eval.authors`; ``window_us`` and ``bins`` keep
        their defaults; a sequence's ground truth and output are held in
        memory).

    Raises
    ------
    ParameterError
        An unknown convention, or the authors' with another window or bins.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec_groups
    >>> split = pathlib.Path(tempfile.mkdtemp())
    >>> gt = make_events([1_000, 25_000], [1, 2], [1, 1], [1, 0])
    >>> flare = make_events([5_000], [3], [3], [1])
    >>> write_dsec_groups(split / "s0.h5", {"input": np.sort(np.concatenate([gt, flare]),
    ...     order="t"), "gt": gt}, (8, 8), {"t_start_us": 0, "t_end_us": 40_000})
    >>> result = benchmark(split, {"raw": "raw", "pfd-a": "pfd-a"}, progress=False)
    >>> result.evaluation.methods["raw"].n_segments
    2
    >>> authors = benchmark(split, {"raw": "raw"}, progress=False, convention="authors")
    >>> authors.evaluation.convention, authors.evaluation.methods["raw"].n_segments
    ('authors', 2)
    """
    check_convention(convention, window_us=window_us, bins=bins)
    if isinstance(split, (str, os.PathLike)):
        paths = list_sequences(split)
    else:
        paths = [Path(p) for p in split]
    built = {
        row: m if isinstance(m, Method) else create_method(m, **dict((params or {}).get(row, {})))
        for row, m in methods.items()
    }
    recon = None
    scores: dict[str, DownstreamScores] = {}
    if downstream is not False and downstream is not None:
        from ..recon.infer import Reconstructor

        recon = Reconstructor(None if downstream is True else downstream)
        if recon.window_us != window_us:
            raise ParameterError(
                f"the reconstructor works on {recon.window_us} µs windows, "
                f"the benchmark on {window_us}"
            )
        scores = {row: DownstreamScores() for row in (*built, GROUND_TRUTH)}
    sample: dict[str, list[np.ndarray]] = {}
    per_file: dict[str, dict[str, Summary]] = {row: {} for row in built}
    seconds = dict.fromkeys(built, 0.0)
    windows = stream_us = 0
    bar = progress_bar(total=len(paths) * len(built), enabled=progress, unit="run", leave=False)
    for k, path in enumerate(paths):
        span = sequence_span(path)
        if span is None:
            for row in built:
                per_file[row][path.stem] = summarize([])
                bar.update(1)
            continue
        size, start, end = span
        windows += -(-(end - start) // window_us)
        stream_us += end - start
        frames = _clean_frames(path) if recon is not None else None
        in_sample = frames is not None and not sample  # the first sequence with frames
        if frames is not None:  # read only with a reconstructor
            keep_gt = sample.setdefault(GROUND_TRUTH, []) if in_sample else None
            _reconstruct_gt(
                recon, path, size, start, end, window_us, frames, scores[GROUND_TRUTH], keep_gt
            )
            if in_sample:
                sample["clean"] = [f.image for f in frames[1]]
        for row, method in built.items():
            bar.set_description(f"{row}: {path.stem}")
            run_seconds, summary, streams = _run_sequence(
                method,
                path,
                size,
                start,
                end,
                window_us=window_us,
                bins=bins,
                rng=seed * 1_000_003 + k,
                keep_streams=on_output is not None,
                recon=(recon, frames, scores[row]) if frames is not None else None,
                keep_images=sample.setdefault(row, []) if in_sample else None,
                convention=convention,
            )
            seconds[row] += run_seconds
            if on_output is not None:
                inp, gt, pred = streams
                on_output(
                    row=row,
                    path=path,
                    inputs=inp,
                    gt=gt,
                    output=pred,
                    sensor_size=size,
                    start_us=start,
                    end_us=end,
                    window_us=window_us,
                )
            per_file[row][path.stem] = summary
            bar.update(1)
    bar.close()
    evaluation = Evaluation(
        per_file, {row: combine_summaries(f.values()) for row, f in per_file.items()}, convention
    )
    speed = {row: MethodSpeed(seconds[row], windows, stream_us) for row in built}
    downstream_sample = {k: np.stack(v) for k, v in sample.items() if v}
    return BenchmarkResult(
        evaluation, speed, {row: d.means() for row, d in scores.items()}, downstream_sample
    )


def _run_sequence(
    method: Method,
    path: Path,
    size: SensorSize,
    start: int,
    end: int,
    *,
    window_us: int,
    bins: int,
    rng: int,
    keep_streams: bool,
    recon: tuple[Any, tuple[np.ndarray, list[CleanFrame]], DownstreamScores] | None = None,
    keep_images: list[np.ndarray] | None = None,
    convention: str = "edeflare",
) -> tuple[float, Summary, tuple[np.ndarray, ...]]:
    """Stream one sequence through one method, scoring each segment once complete.

    Returns the method's seconds (prepass, ``process`` and ``flush`` calls),
    the sequence's summary, and the whole input, ground truth and output when
    ``keep_streams`` (else an empty tuple). In the authors' convention the
    ground truth and output are kept and scored whole at the end. With ``recon`` (the
    reconstructor, the file's frames, the row's scores), each output window
    is also reconstructed and scored (untimed); its images go to
    ``keep_images`` when given.
    """
    src_in = open_events(path, group="input")
    src_gt = open_events(path, group="gt")
    t0 = time.perf_counter()
    prepared = method.prepare(src_in.chunks(), size) if method.needs_prepass else None
    prepass_seconds = time.perf_counter() - t0
    # max_lag_us=None: exact whatever EFR's lag (a sequence's held outputs only).
    run = StreamRun(method, size, rng=rng, prepared=prepared, max_lag_us=None)
    kept: dict[str, list[np.ndarray]] = {"input": [], "gt": [], "output": []}

    def inputs() -> Iterator[tuple[int, np.ndarray]]:
        for w_start, events in src_in.windows(window_us, start_us=start, end_us=end):
            if keep_streams:
                kept["input"].append(events)
            yield w_start, events

    outputs = iter_chunk_windows(
        run.outputs(inputs(), window_us), window_us, start_us=start, end_us=end
    )
    segments = []
    authors = convention == "authors"
    score = _window_scorer(recon, size, window_us, keep_images)
    pairs = zip(src_gt.windows(window_us, start_us=start, end_us=end), outputs, strict=True)
    for k, ((w_start, gt), (_, pred)) in enumerate(pairs):
        if keep_streams or authors:
            kept["gt"].append(gt)
            kept["output"].append(pred)
        if not authors:
            segments.append(segment_metrics(gt, pred, size, w_start, window_us, bins=bins))
        score(k, w_start, pred)
    whole = {k: concat_events(v) if v else empty_events() for k, v in kept.items()}
    if authors:
        summary = summarize_authors(authors_metrics(whole["gt"], whole["output"]))
    else:
        summary = summarize(segments)
    streams = tuple(whole.values()) if keep_streams else ()
    return prepass_seconds + sum(run.call_seconds), summary, streams


def _clean_frames(path: Path) -> tuple[np.ndarray, list[CleanFrame]] | None:
    """A file's clean frames, each prepared once for every stream's scores (None: no frames)."""
    frames = read_frames(path)
    if frames is None:
        return None
    times, images = frames
    return times, [CleanFrame.of(f) for f in images]


def _window_scorer(
    recon: tuple[Any, tuple[np.ndarray, list[CleanFrame]], DownstreamScores] | None,
    size: SensorSize,
    window_us: int,
    keep_images: list[np.ndarray] | None = None,
) -> Callable[[int, int, np.ndarray], None]:
    """A function of ``(window index, start, events)`` that reconstructs and scores a stream
    (and appends each image to ``keep_images`` when given)."""
    if recon is None:
        return lambda k, start, events: None
    reconstructor, (times, images), scores = recon
    reconstructor.reset()
    at = {int(t): i for i, t in enumerate(times.tolist())}

    def score(k: int, start: int, events: np.ndarray) -> None:
        image = reconstructor.step(events, size, start)
        if keep_images is not None:
            keep_images.append(centre_image(image))
        i = at.get(start + window_us)
        if k >= BURN_IN and i is not None:
            scores.add(image, images[i])

    return score


def _reconstruct_gt(
    recon: Any,
    path: Path,
    size: SensorSize,
    start: int,
    end: int,
    window_us: int,
    frames: tuple[np.ndarray, list[CleanFrame]],
    scores: DownstreamScores,
    keep_images: list[np.ndarray] | None = None,
) -> None:
    """Reconstruct a sequence's ground-truth events and score them (the downstream ceiling)."""
    score = _window_scorer((recon, frames, scores), size, window_us, keep_images)
    src = open_events(path, group="gt")
    for k, (w_start, events) in enumerate(src.windows(window_us, start_us=start, end_us=end)):
        score(k, w_start, events)
