"""The paper's benchmark on a dataset: every method on every test sequence, metrics, speed.

A dataset split is a folder of sequence files (``input`` and ``gt`` groups,
see :mod:`edeflare.io.sequence`). For each method (a registered name, with
parameters) and each sequence, the whole input of the sequence is
de-flared in memory, cut into the aligned 20 ms segments of the sequence
span ``[t_start_us, t_end_us)``, and scored against the ground truth with
:func:`edeflare.eval.metrics.segment_metrics`. Means are over segments, then over
sequences (as :func:`edeflare.eval.evaluate.evaluate`). Speed is measured per
method as 20 ms windows per second and real-time factor (processing time
over stream duration; below 1 is faster than real time), excluding I/O.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..deflare import Method, create_method
from ..io.sequence import list_sequences, read_sequence
from .evaluate import Evaluation, Summary, combine_summaries, evaluate_streams, summarize
from .tables import ResultsTable

__all__ = ["BenchmarkResult", "MethodSpeed", "benchmark"]


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
    """Metrics (``evaluation``) and speed (``speed``) of every method."""

    evaluation: Evaluation
    speed: dict[str, MethodSpeed] = field(default_factory=dict)

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
) -> BenchmarkResult:
    """Run and score every method on every sequence of a split.

    Parameters
    ----------
    split : path-like or sequence of path-like
        A folder of sequence files, or the files.
    methods : mapping
        Row name -> registered method name or :class:`~edeflare.deflare.Method`.
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
        rows of a sequence before the next sequence.
    """
    if isinstance(split, (str, os.PathLike)):
        paths = list_sequences(split)
    else:
        paths = [Path(p) for p in split]
    built = {
        row: m if isinstance(m, Method) else create_method(m, **dict((params or {}).get(row, {})))
        for row, m in methods.items()
    }
    per_file: dict[str, dict[str, Summary]] = {row: {} for row in built}
    seconds = dict.fromkeys(built, 0.0)
    windows = stream_us = 0
    bar = tqdm(
        total=len(paths) * len(built), unit="run", disable=None if progress else True, leave=False
    )
    for k, path in enumerate(paths):
        inp, gt, size, start, end = read_sequence(path)
        windows += -(-(end - start) // window_us)
        stream_us += end - start
        for row, method in built.items():
            bar.set_description(f"{row}: {path.stem}")
            t0 = time.perf_counter()
            pred = method(inp, size, rng=seed * 1_000_003 + k)
            seconds[row] += time.perf_counter() - t0
            if on_output is not None:
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
            segments = evaluate_streams(
                gt, pred, size, window_us=window_us, bins=bins, start_us=start, end_us=end
            )
            per_file[row][path.stem] = summarize(m for _, m in segments)
            bar.update(1)
    bar.close()
    evaluation = Evaluation(
        per_file, {row: combine_summaries(f.values()) for row, f in per_file.items()}
    )
    speed = {row: MethodSpeed(seconds[row], windows, stream_us) for row in built}
    return BenchmarkResult(evaluation, speed)
