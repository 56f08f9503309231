"""The evaluation harness: paired streams -> aligned 20 ms segments -> eight metrics -> averages.

As in the paper, "all reported scores are computed by averaging the results
over 20 ms segments": a restored stream and its ground truth are cut into
the same aligned half-open windows ``[start + k*20ms, start + (k+1)*20ms)``
(``start`` = the multiple of 20 ms at or below the earlier first event),
every metric is computed per segment (:func:`edeflare.eval.metrics.segment_metrics`),
averaged over the segments of a file, and the file means are averaged over
files (each file weighs the same). NaN values (undefined distances, see
:mod:`edeflare.eval.metrics`) are left out of the means and counted.

That is the ``edeflare`` convention, the default. With ``convention="authors"``
each file is instead scored whole, as the authors' evaluation code behind the
paper's tables scores it (:mod:`edeflare.eval.authors`), and the file values
are averaged over files.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import zip_longest
from pathlib import Path

import numpy as np

from .._progress import progress_bar
from ..errors import EventFileError
from ..events import (
    SensorSize,
    check_events,
    empty_events,
    iter_time_windows,
    slice_time,
    window_start_for,
)
from ..io import EventSource, list_formats, open_events
from .authors import CONVENTIONS, AuthorsMetrics, authors_metrics, check_convention
from .metrics import METRICS, SegmentMetrics, segment_metrics

__all__ = [
    "CONVENTIONS",
    "Evaluation",
    "Summary",
    "combine_summaries",
    "convention_note",
    "evaluate",
    "evaluate_events",
    "evaluate_file_authors",
    "evaluate_files",
    "evaluate_streams",
    "pair_files",
    "summarize",
    "summarize_authors",
]


@dataclass(frozen=True)
class Summary:
    """Means of the eight metrics over segments (or files) and how many values were undefined.

    Attributes
    ----------
    means : dict
        Metric name -> mean over the defined values (NaN if none was defined).
    undefined : dict
        Metric name -> number of segments where the metric was undefined (NaN);
        in the authors' convention, of files.
    n_segments : int
        Segments that went into the means; in the authors' convention, the
        paired 20 ms chunks behind the voxel metrics.
    """

    means: dict[str, float]
    undefined: dict[str, int]
    n_segments: int

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (NaN becomes None)."""
        return {
            "means": {k: (None if math.isnan(v) else v) for k, v in self.means.items()},
            "undefined": dict(self.undefined),
            "n_segments": self.n_segments,
        }


def summarize(segments: Iterable[SegmentMetrics]) -> Summary:
    """Average each metric over the segments where it is defined.

    Examples
    --------
    >>> from edeflare.eval.metrics import SegmentMetrics
    >>> a = SegmentMetrics(1.0, 0.5, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0)
    >>> b = SegmentMetrics(float("nan"), float("nan"), 2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    >>> s = summarize([a, b])
    >>> s.means["chamfer"], s.undefined["chamfer"], s.means["mse"]
    (1.0, 1, 1.0)
    """
    table = np.array([[getattr(s, m) for m in METRICS] for s in segments], dtype=np.float64)
    if table.size == 0:
        table = np.empty((0, len(METRICS)))
    defined = ~np.isnan(table)
    means = {}
    for j, m in enumerate(METRICS):
        col = table[defined[:, j], j]
        means[m] = float(col.mean()) if col.size else math.nan
    undefined = {m: int((~defined[:, j]).sum()) for j, m in enumerate(METRICS)}
    return Summary(means, undefined, int(table.shape[0]))


_NOTES = {
    "edeflare": "Metrics in the edeflare convention: aligned 20 ms segments, coordinates "
    "scaled by the sensor and window (docs/evaluation.md).",
    "authors": "Metrics in the authors' convention, as the paper's tables: each file min-max "
    "scaled over itself, 20 ms chunks from each stream's first event (docs/evaluation.md).",
}


def convention_note(convention: str) -> str:
    """One line that says which convention a table's metrics follow (for reports).

    Examples
    --------
    >>> convention_note("authors").split(":")[0]
    "Metrics in the authors' convention, as the paper's tables"
    """
    return _NOTES[check_convention(convention)]


def summarize_authors(metrics: AuthorsMetrics) -> Summary:
    """A file's summary in the authors' convention: its eight values, NaN counted as undefined.

    Examples
    --------
    >>> from edeflare.eval.authors import AuthorsMetrics
    >>> nan = float("nan")
    >>> s = summarize_authors(AuthorsMetrics(nan, nan, 0.5, 0, 0, 1, 1, 1, n_chunks=3))
    >>> s.undefined["chamfer"], s.means["mse"], s.n_segments
    (1, 0.5, 3)
    """
    means = metrics.as_dict()
    undefined = {m: int(math.isnan(v)) for m, v in means.items()}
    return Summary(means, undefined, metrics.n_chunks)


def combine_summaries(summaries: Iterable[Summary], metrics: Sequence[str] = METRICS) -> Summary:
    """Mean over files of per-file means; undefined counts and segments add up.

    Examples
    --------
    >>> a = Summary({"chamfer": 1.0}, {"chamfer": 0}, 3)
    >>> b = Summary({"chamfer": 3.0}, {"chamfer": 1}, 1)
    >>> s = combine_summaries([a, b], metrics=("chamfer",))
    >>> s.means["chamfer"], s.undefined["chamfer"], s.n_segments
    (2.0, 1, 4)
    """
    summaries = list(summaries)
    means = {}
    for m in metrics:
        vals = [s.means[m] for s in summaries if not math.isnan(s.means[m])]
        means[m] = float(np.mean(vals)) if vals else math.nan
    undefined = {m: sum(s.undefined[m] for s in summaries) for m in metrics}
    return Summary(means, undefined, sum(s.n_segments for s in summaries))


def evaluate_streams(
    events_gt: np.ndarray,
    events_pred: np.ndarray,
    sensor_size: SensorSize,
    *,
    window_us: int = 20_000,
    bins: int = 8,
    start_us: int | None = None,
    end_us: int | None = None,
    workers: int = -1,
) -> list[tuple[int, SegmentMetrics]]:
    """Metrics of every aligned segment of two in-memory streams: ``[(start_us, metrics)]``.

    Segments cover both streams: from the window holding the earlier first
    event to the window holding the later last event (or ``start_us`` /
    ``end_us``).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> gt = make_events([1_000, 30_000], [0, 1], [0, 0], [1, 1])
    >>> [(s, m.n_gt) for s, m in evaluate_streams(gt, gt, (4, 4))]
    [(0, 1), (20000, 1)]
    """
    if start_us is None:
        firsts = [int(e["t"][0]) for e in (events_gt, events_pred) if e.size]
        if not firsts:
            return []
        start_us = window_start_for(min(firsts), window_us)
    if end_us is None:
        lasts = [int(e["t"][-1]) + 1 for e in (events_gt, events_pred) if e.size]
        end_us = max(lasts) if lasts else start_us
    out = []
    windows = zip(
        iter_time_windows(events_gt, window_us, start_us=start_us, end_us=end_us),
        iter_time_windows(events_pred, window_us, start_us=start_us, end_us=end_us),
        strict=True,
    )
    for (start, gt), (_, pred) in windows:
        out.append(
            (
                start,
                segment_metrics(
                    gt, pred, sensor_size, start, window_us, bins=bins, workers=workers
                ),
            )
        )
    return out


def evaluate_events(
    events_gt: np.ndarray,
    events_pred: np.ndarray,
    sensor_size: SensorSize,
    *,
    window_us: int = 20_000,
    bins: int = 8,
    start_us: int | None = None,
    end_us: int | None = None,
    convention: str = "edeflare",
) -> Summary:
    """Score a prediction against its ground truth: the paper's metrics, averaged over segments.

    :func:`evaluate_streams` (aligned segments of ``window_us``) then
    :func:`summarize` (means over segments), as ``edeflare evaluate`` does per file.
    With ``convention="authors"``, the two streams are one file scored as the
    authors' code scores it (:func:`edeflare.eval.authors.authors_metrics`).

    Parameters
    ----------
    events_gt, events_pred : numpy.ndarray
        Ground truth first, then the prediction (:data:`~edeflare.events.EVENT_DTYPE`).
    sensor_size : (width, height)
    window_us, bins : int
        Segment length and voxel bins of the metrics.
        The authors' convention fixes them (20 ms, 8 bins).
    start_us, end_us : int, optional
        The span to score (default: both streams' windows; in the authors'
        convention, the whole streams).
    convention : {"edeflare", "authors"}
        Whose definitions of the metrics (see :mod:`edeflare.eval.authors`).

    Returns
    -------
    Summary
        ``.means`` maps each metric to its mean; ``.n_segments`` counts segments
        (in the authors' convention: the paired 20 ms chunks).

    Raises
    ------
    ParameterError
        An unknown convention, or the authors' with another window or bins.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> gt = make_events([1_000, 30_000], [0, 1], [0, 0], [1, 1])
    >>> s = evaluate_events(gt, gt, (4, 4))
    >>> s.n_segments, s.means["chamfer"]
    (2, 0.0)
    >>> pred = make_events([1_000], [0], [0], [1])
    >>> s = evaluate_events(gt, pred, (4, 4), convention="authors")
    >>> s.n_segments, s.means["r_f1"]       # one chunk pair; (0, 0) ON matched
    (1, 1.0)
    """
    if check_convention(convention, window_us=window_us, bins=bins) == "authors":
        for events in (events_gt, events_pred):
            check_events(events, sensor_size)
        if start_us is not None or end_us is not None:
            lo = -(2**62) if start_us is None else start_us
            hi = 2**62 if end_us is None else end_us
            events_gt, events_pred = slice_time(events_gt, lo, hi), slice_time(events_pred, lo, hi)
        return summarize_authors(authors_metrics(events_gt, events_pred))
    segments = evaluate_streams(
        events_gt,
        events_pred,
        sensor_size,
        window_us=window_us,
        bins=bins,
        start_us=start_us,
        end_us=end_us,
    )
    return summarize(m for _, m in segments)


def _first_time(source) -> int | None:
    for chunk in source.chunks():
        return int(chunk["t"][0])
    return None


def _open_pair(
    gt_path: Path, pred_path: Path, sensor_size: SensorSize | None
) -> tuple[SensorSize, EventSource, EventSource]:
    """Open a ground-truth file and its restored file, with one sensor size (else an error)."""
    src_gt = open_events(gt_path, sensor_size)
    size = src_gt.sensor_size
    src_pred = open_events(pred_path, sensor_size)
    if sensor_size is None and src_pred.recorded_sensor_size is None:
        src_pred = open_events(pred_path, size)  # nothing recorded: take the ground truth's
    if src_pred.sensor_size != size:
        raise EventFileError(
            pred_path,
            f"sensor size {src_pred.sensor_size} differs from the ground truth's {size} "
            f"({gt_path})",
        )
    return size, src_gt, src_pred


def _paired_windows(
    gt_path: Path, pred_path: Path, sensor_size: SensorSize | None, window_us: int
) -> tuple[SensorSize, Iterator[tuple[int, np.ndarray, np.ndarray]]]:
    size, src_gt, src_pred = _open_pair(gt_path, pred_path, sensor_size)
    firsts = [t for t in (_first_time(src_gt), _first_time(src_pred)) if t is not None]

    def windows() -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        if not firsts:
            return
        start = window_start_for(min(firsts), window_us)
        none = empty_events()
        pairs = zip_longest(
            src_gt.windows(window_us, start_us=start),
            src_pred.windows(window_us, start_us=start),
        )
        for k, (a, b) in enumerate(pairs):
            yield start + k * window_us, (a[1] if a else none), (b[1] if b else none)

    return size, windows()


def evaluate_files(
    gt_path: str | os.PathLike[str],
    pred_path: str | os.PathLike[str],
    *,
    sensor_size: SensorSize | None = None,
    window_us: int = 20_000,
    bins: int = 8,
    workers: int = -1,
) -> list[tuple[int, SegmentMetrics]]:
    """Segment metrics of a restored file against its ground-truth file, streamed window by window.

    Both files are read in lockstep through aligned windows, so long
    recordings never load whole. The sensor size comes from the ground truth
    (or ``sensor_size``); a restored file of another size is an error.
    """
    size, windows = _paired_windows(Path(gt_path), Path(pred_path), sensor_size, window_us)
    return [
        (start, segment_metrics(gt, pred, size, start, window_us, bins=bins, workers=workers))
        for start, gt, pred in windows
    ]


def evaluate_file_authors(
    gt_path: str | os.PathLike[str],
    pred_path: str | os.PathLike[str],
    *,
    sensor_size: SensorSize | None = None,
    workers: int = -1,
) -> AuthorsMetrics:
    """The eight metrics of a restored file against its ground truth, in the authors' convention.

    Both files are read whole (the convention normalises over each whole
    stream); the sensor size is checked as in :func:`evaluate_files`.
    """
    _, src_gt, src_pred = _open_pair(Path(gt_path), Path(pred_path), sensor_size)
    return authors_metrics(src_gt.read(), src_pred.read(), workers=workers)


def _event_files(folder: Path) -> dict[str, Path]:
    known = set(list_formats())
    files: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        if path.is_file() and path.suffix.lower() in known and not path.name.startswith("."):
            if path.stem in files:
                raise EventFileError(path, f"two event files named {path.stem!r} in {folder}")
            files[path.stem] = path
    return files


def pair_files(
    gt: str | os.PathLike[str], pred: str | os.PathLike[str]
) -> list[tuple[str, Path, Path]]:
    """Pair ground-truth and restored files by name (stem, any suffix): ``[(name, gt, pred)]``.

    Either both are files, or both are folders; in folders every
    ground-truth file needs a restored file of the same stem.
    """
    gt, pred = Path(gt), Path(pred)
    if gt.is_file() and pred.is_file():
        return [(gt.stem, gt, pred)]
    if gt.is_dir() and pred.is_dir():
        gt_files, pred_files = _event_files(gt), _event_files(pred)
        if not gt_files:
            raise EventFileError(gt, "no event files in the ground-truth folder")
        missing = sorted(set(gt_files) - set(pred_files))
        if missing:
            raise EventFileError(pred, f"no restored file for {missing[:5]}")
        return [(name, gt_files[name], pred_files[name]) for name in gt_files]
    for p in (gt, pred):
        if not p.exists():
            raise EventFileError(p, "no such file or folder")
    raise EventFileError(pred, f"pair a file with a file or a folder with a folder (gt: {gt})")


@dataclass(frozen=True)
class Evaluation:
    """Results of :func:`evaluate`: per method, per file, and the method means over files.

    ``convention`` names whose definitions of the metrics made them
    (:data:`CONVENTIONS`).
    """

    per_file: dict[str, dict[str, Summary]] = field(default_factory=dict)
    methods: dict[str, Summary] = field(default_factory=dict)
    convention: str = "edeflare"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return {
            "convention": self.convention,
            "methods": {m: s.to_dict() for m, s in self.methods.items()},
            "per_file": {
                m: {f: s.to_dict() for f, s in files.items()} for m, files in self.per_file.items()
            },
        }


def evaluate(
    gt: str | os.PathLike[str],
    preds: Mapping[str, str | os.PathLike[str]],
    *,
    sensor_size: SensorSize | None = None,
    window_us: int = 20_000,
    bins: int = 8,
    workers: int = -1,
    progress: bool = True,
    convention: str = "edeflare",
) -> Evaluation:
    """Evaluate several methods against one ground truth (a file or a folder of files).

    Parameters
    ----------
    gt : path-like
        Ground-truth file, or folder of files.
    preds : mapping
        Method name -> restored file or folder (files paired with ``gt`` by stem).
        Name the unprocessed input ``raw`` to get the paper's "Raw Input" row.
    convention : {"edeflare", "authors"}
        ``edeflare``: files streamed through aligned segments of ``window_us``
        (:func:`evaluate_files`); ``authors``: each file read whole and scored
        as the authors' code scores it (:func:`evaluate_file_authors`;
        ``window_us`` and ``bins`` must keep their defaults).

    Returns
    -------
    Evaluation
        ``.methods[name]`` is the mean over files of the per-file means over
        20 ms segments; ``.per_file[name][file]`` the per-file summaries.

    Raises
    ------
    ParameterError
        An unknown convention, or the authors' with another window or bins.
    """
    check_convention(convention, window_us=window_us, bins=bins)
    per_file: dict[str, dict[str, Summary]] = {}
    jobs = [(name, pair) for name, path in preds.items() for pair in pair_files(gt, path)]
    with progress_bar(total=len(jobs), enabled=progress, unit="file", leave=False) as bar:
        for name, (stem, gt_path, pred_path) in jobs:
            bar.set_description(f"{name}: {stem}")
            if convention == "authors":
                file_metrics = evaluate_file_authors(
                    gt_path, pred_path, sensor_size=sensor_size, workers=workers
                )
                summary = summarize_authors(file_metrics)
            else:
                segments = evaluate_files(
                    gt_path,
                    pred_path,
                    sensor_size=sensor_size,
                    window_us=window_us,
                    bins=bins,
                    workers=workers,
                )
                summary = summarize(m for _, m in segments)
            per_file.setdefault(name, {})[stem] = summary
            bar.update(1)
    methods = {name: combine_summaries(files.values()) for name, files in per_file.items()}
    return Evaluation(per_file, methods, convention)
