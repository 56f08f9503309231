"""The authors' convention: the eight metrics as the paper's own evaluation code computes them.

The paper's tables were made with the authors' public evaluation code, which
computes the eight metrics differently from :mod:`edeflare.eval.metrics` (the
``edeflare`` convention, the default). This module implements their
behaviour, so that numbers reported next to the paper's compare like with
like. Each **file** (a 100 ms stream in the paper's test sets) is scored alone:

- **Loading.** Times count from each stream's own first event; polarity is
  +1 where ``p == 1``, else -1.
- **Chamfer, Gaussian.** ``t`` (seconds), ``x``, ``y`` and the signed
  polarity of each stream are min-max scaled to ``[0, 100]`` over that
  stream itself: ``(v - min) * 100 / (max - min + 1e-8)``
  (:func:`minmax_points`); a column with a single value becomes 0. A k-d tree
  of the ground truth is queried with the estimate (one-sided): Chamfer is
  the mean distance, Gaussian ``mean(1 - exp(-d^2 / 0.4))``.
- **Chunks.** Each stream is cut into 20 ms chunks
  ``[t0 + 20k ms, t0 + 20(k+1) ms)`` from its own first event ``t0``; empty
  chunks are dropped and the two lists are paired in order, up to the
  shorter one (:func:`authors_chunks`).
- **Voxels.** A chunk becomes a ``(8, 480, 640)`` grid of signed polarity
  sums, bin ``clip((t - t_first) // 2.5 ms, 0, 7)`` with ``t_first`` the
  chunk's first event; events beyond 640 x 480 are ignored
  (:func:`authors_voxel`).
- **Voxel metrics.** MSE of the grids; PMSE-k the MSE after ``k x k`` average
  pooling of the positive and negative parts ``(2, 8, H, W)``; R-F1, T-F1
  and TP-F1 on the parts thresholded at ``> 0.001`` (the full parts, their sum
  over bins, their sum over polarity and bins), with ``F1 = 0`` when there is
  no true positive (:func:`authors_voxel_scores`). Each is averaged over the
  chunk pairs of the file.
- **Files.** The file values are averaged over files
  (:func:`edeflare.eval.evaluate.combine_summaries`).

Times are exact integer microseconds here: an event lying, to the
microsecond, on a chunk or bin boundary falls in the later chunk or bin,
where floating-point seconds could round it either way.

Cases the description leaves open, decided here: with no estimated events
the Chamfer and Gaussian distances are NaN (a mean over nothing); with
estimated events but no ground truth the Chamfer distance is NaN (unbounded)
and the Gaussian distance 1 (its limit), as in the ``edeflare`` convention. A
file without a chunk pair (either stream empty) has NaN voxel metrics. NaN
values are left out of the means over files and counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import ParameterError
from ..events import SensorSize, check_events, check_sensor_size
from .metrics import THRESHOLD, SegmentMetrics, _pool, _same_shape

__all__ = [
    "BINS",
    "BIN_US",
    "CHUNK_US",
    "CONVENTIONS",
    "GAUSSIAN_DIVISOR",
    "GRID_SIZE",
    "AuthorsMetrics",
    "authors_chunks",
    "authors_event_distances",
    "authors_f1",
    "authors_metrics",
    "authors_voxel",
    "authors_voxel_scores",
    "check_convention",
    "minmax_points",
    "polarity_parts",
]

CONVENTIONS = ("edeflare", "authors")
"""Metric conventions: ``edeflare`` (the default, :mod:`edeflare.eval.metrics`) and
``authors`` (this module)."""
GRID_SIZE: SensorSize = (640, 480)
"""``(width, height)`` of the authors' voxel grids, whatever the sensor."""
CHUNK_US = 20_000
"""Chunk length: 20 ms."""
BINS = 8
"""Time bins of a chunk's grid."""
BIN_US = 2_500
"""Bin length: 2.5 ms, counted from the chunk's first event."""
GAUSSIAN_DIVISOR = 0.4
"""The Gaussian distance is ``mean(1 - exp(-d^2 / 0.4))``."""
_EPS = 1e-8


def check_convention(convention: str, *, window_us: int = CHUNK_US, bins: int = BINS) -> str:
    """Return ``convention`` if it is one of :data:`CONVENTIONS` and fits the window, else raise.

    The authors' convention fixes 20 ms chunks of 8 bins: ``window_us`` and
    ``bins`` (what a caller would score with) must be those.

    Raises
    ------
    ParameterError
        Naming the valid conventions, or the fixed window and bins.

    Examples
    --------
    >>> check_convention("authors")
    'authors'
    >>> check_convention("authors", window_us=10_000)
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: the authors' convention fixes 20 ms chunks of 8 bins: \
window_us must be 20000 and bins 8, got 10000 and 8
    """
    if convention not in CONVENTIONS:
        raise ParameterError(
            f"convention must be one of {', '.join(CONVENTIONS)}, got {convention!r}"
        )
    if convention == "authors" and (int(window_us), int(bins)) != (CHUNK_US, BINS):
        raise ParameterError(
            "the authors' convention fixes 20 ms chunks of 8 bins: "
            f"window_us must be {CHUNK_US} and bins {BINS}, got {window_us} and {bins}"
        )
    return convention


def minmax_points(events: np.ndarray) -> np.ndarray:
    """Events as 4-D points ``(t, x, y, p)``, each column min-max scaled to ``[0, 100]``.

    ``t`` in seconds from the stream's first event, ``p`` in {-1, +1}; each
    column ``v`` becomes ``(v - min) * 100 / (max - min + 1e-8)`` over the
    stream itself, so a column with one value (one polarity, one row) is all 0.

    Returns
    -------
    numpy.ndarray
        float64 ``(N, 4)``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([1000, 1500, 3000], [10, 20, 30], [5, 5, 5], [1, 0, 1])
    >>> minmax_points(ev).round(4).tolist()   # 1e-8 is not small next to 0.002 s
    [[0.0, 0.0, 0.0, 100.0], [24.9999, 50.0, 0.0, 0.0], [99.9995, 100.0, 0.0, 100.0]]
    """
    points = np.empty((events.size, 4), dtype=np.float64)
    if events.size == 0:
        return points
    t = events["t"].astype(np.int64)
    points[:, 0] = (t - t[0]) / 1e6
    points[:, 1] = events["x"]
    points[:, 2] = events["y"]
    points[:, 3] = np.where(events["p"] == 1, 1.0, -1.0)
    lo, hi = points.min(axis=0), points.max(axis=0)
    return (points - lo) * 100.0 / (hi - lo + _EPS)


def authors_event_distances(
    events_gt: np.ndarray, events_pred: np.ndarray, *, workers: int = -1
) -> tuple[float, float]:
    """``(chamfer, gaussian)`` of two whole streams, each min-max scaled over itself.

    Notes
    -----
    With ``d_i`` the distance from estimated point ``i`` to its nearest
    ground-truth point (:func:`minmax_points`, :class:`scipy.spatial.cKDTree`):
    ``CD = mean(d_i)`` and ``GD = mean(1 - exp(-d_i^2 / 0.4))``. NaN for both
    without estimated events; ``(NaN, 1.0)`` without ground-truth events.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> gt = make_events([0, 1000], [0, 100], [0, 0], [1, 1])
    >>> pred = make_events([0, 1000], [0, 50], [0, 0], [1, 1])  # spans x 0..50: scaled to 100
    >>> [round(v, 6) for v in authors_event_distances(gt, pred)]   # 1e-8 apart
    [0.0, 0.0]
    """
    if events_pred.size == 0:
        return math.nan, math.nan
    if events_gt.size == 0:
        return math.nan, 1.0
    tree = cKDTree(minmax_points(events_gt))
    d, _ = tree.query(minmax_points(events_pred), k=1, workers=workers)
    return float(d.mean()), float(np.mean(-np.expm1(-(d * d) / GAUSSIAN_DIVISOR)))


def authors_chunks(events: np.ndarray, chunk_us: int = CHUNK_US) -> list[np.ndarray]:
    """The non-empty chunks ``[t0 + k*chunk_us, t0 + (k+1)*chunk_us)`` of a stream, in order.

    ``t0`` is the stream's own first event. The chunks are views of ``events``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([5_000, 24_999, 25_000, 70_000], [0] * 4, [0] * 4, [1] * 4)
    >>> [c["t"].tolist() for c in authors_chunks(ev)]   # [45, 65) ms is empty: dropped
    [[5000, 24999], [25000], [70000]]
    """
    if events.size == 0:
        return []
    t = events["t"].astype(np.int64)
    k = (t - t[0]) // int(chunk_us)
    return np.split(events, np.flatnonzero(np.diff(k)) + 1)


def _bins(t: np.ndarray) -> np.ndarray:
    t = t.astype(np.int64)
    return np.clip((t - t[0]) // BIN_US, 0, BINS - 1) if t.size else t


def authors_voxel(chunk: np.ndarray, *, grid_size: SensorSize = GRID_SIZE) -> np.ndarray:
    """A chunk's signed voxel grid ``(8, H, W)``, bins counted from its first event.

    Cell ``(b, y, x)`` sums +1 per ON and -1 per OFF event with
    ``b = clip((t - t_first) // 2500 us, 0, 7)``, so ON and OFF events of one
    cell cancel. Events at ``x >= W`` or ``y >= H`` are ignored.

    Returns
    -------
    numpy.ndarray
        float64 ``(8, H, W)``, ``(W, H) = grid_size`` (640 x 480).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([100, 200, 2_700, 30_000], [0, 0, 1, 1], [0, 0, 0, 0], [1, 0, 1, 0])
    >>> v = authors_voxel(ev, grid_size=(2, 1))          # bins 0, 0, 1, 7 (clipped)
    >>> v[:, 0, :].tolist()[:2], v[7, 0, :].tolist()     # ON and OFF of cell (0, 0, 0) cancel
    ([[0.0, 0.0], [0.0, 1.0]], [0.0, -1.0])
    """
    width, height = check_sensor_size(grid_size)
    grid = np.zeros(BINS * height * width)
    if chunk.size:
        x, y = chunk["x"].astype(np.int64), chunk["y"].astype(np.int64)
        inside = (x < width) & (y < height)
        cell = ((_bins(chunk["t"]) * height + y) * width + x)[inside]
        sign = np.where(chunk["p"] == 1, 1.0, -1.0)[inside]
        grid = np.bincount(cell, weights=sign, minlength=grid.size)
    return grid.reshape(BINS, height, width)


def polarity_parts(voxel: np.ndarray) -> np.ndarray:
    """The positive and negative parts of a signed grid: ``(2, ...)``, both ``>= 0``.

    Examples
    --------
    >>> polarity_parts(np.array([2.0, -1.0, 0.0])).tolist()
    [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    """
    voxel = np.asarray(voxel, dtype=np.float64)
    return np.stack([np.maximum(voxel, 0.0), np.maximum(-voxel, 0.0)])


def authors_f1(binary_gt: np.ndarray, binary_pred: np.ndarray) -> float:
    """F1 of two boolean grids, ``2 TP / (2 TP + FP + FN)``, and 0 when there is no true positive.

    Examples
    --------
    >>> authors_f1(np.array([1, 1, 0, 0], bool), np.array([1, 0, 1, 0], bool))
    0.5
    >>> authors_f1(np.zeros(4, bool), np.zeros(4, bool))    # both empty: 0, not 1
    0.0
    """
    binary_gt, binary_pred = _same_shape(binary_gt, binary_pred)
    tp = int(np.count_nonzero(binary_gt & binary_pred))
    if tp == 0:
        return 0.0
    return 2.0 * tp / (int(np.count_nonzero(binary_gt)) + int(np.count_nonzero(binary_pred)))


def authors_voxel_scores(
    voxel_gt: np.ndarray, voxel_pred: np.ndarray
) -> tuple[float, float, float, float, float, float]:
    """``(mse, pmse_2, pmse_4, r_f1, t_f1, tp_f1)`` of two signed grids ``(B, H, W)``.

    The readable reference; :func:`authors_metrics` computes the same from the
    occupied cells only.

    Notes
    -----
    MSE is ``mean((V_pred - V_gt)^2)``. With ``P`` the parts ``(2, B, H, W)``
    (:func:`polarity_parts`), PMSE-k is ``mean((Pool_k(P_pred) - Pool_k(P_gt))^2)``
    with ``Pool_k`` a ``k x k`` average pooling of stride ``k`` (remainder rows
    and columns dropped, as ``torch.nn.functional.avg_pool2d``); NaN when the
    grid is smaller than ``k``. R-F1 is :func:`authors_f1` of ``P > 0.001``,
    T-F1 of ``P.sum(bins) > 0.001``, TP-F1 of ``P.sum(polarity, bins) > 0.001``.

    Examples
    --------
    >>> gt = np.zeros((2, 1, 2)); gt[0, 0, 0] = 1            # ON in bin 0
    >>> pred = np.zeros((2, 1, 2)); pred[1, 0, 0] = 1        # ON in bin 1
    >>> [round(v, 4) for v in authors_voxel_scores(gt, pred)]
    [0.5, nan, nan, 0.0, 1.0, 1.0]
    """
    voxel_gt, voxel_pred = _same_shape(voxel_gt, voxel_pred)
    diff = voxel_pred.astype(np.float64) - voxel_gt
    mse = float(np.mean(diff * diff))
    parts_gt, parts_pred = polarity_parts(voxel_gt), polarity_parts(voxel_pred)
    pmse = []
    for k in (2, 4):
        d = _pool(parts_pred, k) - _pool(parts_gt, k)
        pmse.append(float(np.mean(d * d)) if d.size else math.nan)
    r_f1 = authors_f1(parts_gt > THRESHOLD, parts_pred > THRESHOLD)
    t_gt, t_pred = parts_gt.sum(axis=1), parts_pred.sum(axis=1)
    t_f1 = authors_f1(t_gt > THRESHOLD, t_pred > THRESHOLD)
    tp_f1 = authors_f1(t_gt.sum(axis=0) > THRESHOLD, t_pred.sum(axis=0) > THRESHOLD)
    return mse, pmse[0], pmse[1], r_f1, t_f1, tp_f1


def _cells(chunk: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat grid index ``(b * H + y) * W + x`` and sign of each event on the grid."""
    x, y = chunk["x"].astype(np.int64), chunk["y"].astype(np.int64)
    inside = (x < width) & (y < height)
    cell = ((_bins(chunk["t"]) * height + y) * width + x)[inside]
    return cell, np.where(chunk["p"] == 1, 1.0, -1.0)[inside]


def _f1_counts(gt: np.ndarray, pred: np.ndarray) -> float:
    tp = int(np.count_nonzero(gt & pred))
    return 0.0 if tp == 0 else 2.0 * tp / (int(np.count_nonzero(gt)) + int(np.count_nonzero(pred)))


def _group_sums(keys: np.ndarray, values: np.ndarray, n_keys: int) -> np.ndarray:
    """Sums of each row of ``values`` ``(C, N)`` per key in ``[0, n_keys)``: ``(C, K)``.

    Keys that occur nowhere are left out (or are zeros): the callers only sum
    squares and count values above the threshold, which zeros do not change.
    Few keys are renumbered first, so a small chunk never allocates whole grids.
    """
    if keys.size * 8 < n_keys:
        _, keys = np.unique(keys, return_inverse=True)
        n_keys = int(keys.max()) + 1 if keys.size else 0
    return np.stack([np.bincount(keys, v, minlength=n_keys) for v in values])


def _chunk_scores(
    chunk_gt: np.ndarray, chunk_pred: np.ndarray, width: int, height: int
) -> tuple[float, float, float, float, float, float]:
    """:func:`authors_voxel_scores` of two chunks' grids, from the cells events reach.

    Every metric is a sum over cells where a grid is non-zero, so only those
    cells are gathered (sorted flat indices); pooled blocks and pixels are sums
    of them (:func:`_group_sums`). A test checks this equals the dense reference.
    """
    n_cells = BINS * height * width
    cell_gt, sign_gt = _cells(chunk_gt, width, height)
    cell_pred, sign_pred = _cells(chunk_pred, width, height)
    reached = np.zeros(n_cells, dtype=bool)
    reached[cell_gt] = True
    reached[cell_pred] = True
    cells = np.flatnonzero(reached)
    gt = np.bincount(np.searchsorted(cells, cell_gt), sign_gt, minlength=cells.size)
    pred = np.bincount(np.searchsorted(cells, cell_pred), sign_pred, minlength=cells.size)
    diff = pred - gt
    mse = float(np.dot(diff, diff)) / n_cells
    parts_gt, parts_pred = polarity_parts(gt), polarity_parts(pred)
    b, rest = np.divmod(cells, height * width)
    y, x = np.divmod(rest, width)
    pmse = []
    for k in (2, 4):
        hk, wk = height // k, width // k
        if hk == 0 or wk == 0:
            pmse.append(math.nan)
            continue
        inside = (y < hk * k) & (x < wk * k)
        block = (b[inside] * hk + y[inside] // k) * wk + x[inside] // k
        d = _group_sums(block, (parts_pred - parts_gt)[:, inside], BINS * hk * wk) / (k * k)
        pmse.append(float(np.sum(d * d)) / (2 * BINS * hk * wk))
    r_f1 = _f1_counts(parts_gt > THRESHOLD, parts_pred > THRESHOLD)
    pixel = y * width + x
    sums = _group_sums(pixel, np.concatenate([parts_gt, parts_pred]), height * width)
    t_gt, t_pred = sums[:2], sums[2:]
    t_f1 = _f1_counts(t_gt > THRESHOLD, t_pred > THRESHOLD)
    tp_f1 = _f1_counts(t_gt.sum(axis=0) > THRESHOLD, t_pred.sum(axis=0) > THRESHOLD)
    return mse, pmse[0], pmse[1], r_f1, t_f1, tp_f1


@dataclass(frozen=True)
class AuthorsMetrics(SegmentMetrics):
    """The eight metrics of one file in the authors' convention (NaN where undefined).

    ``n_chunks`` counts the chunk pairs the six voxel metrics average over;
    ``n_gt`` and ``n_pred`` the events of the two streams.
    """

    n_chunks: int = 0


def authors_metrics(
    events_gt: np.ndarray,
    events_pred: np.ndarray,
    *,
    grid_size: SensorSize = GRID_SIZE,
    workers: int = -1,
) -> AuthorsMetrics:
    """All eight metrics of one file (two whole streams), as the authors' code computes them.

    Parameters
    ----------
    events_gt, events_pred : numpy.ndarray
        Ground truth first, then the estimate: whole files
        (:data:`~edeflare.events.EVENT_DTYPE`, sorted).
    grid_size : (width, height)
        Voxel grid size (the authors': 640 x 480, whatever the sensor).
    workers : int
        Threads of the k-d tree query (-1: all).

    Returns
    -------
    AuthorsMetrics
        Chamfer and Gaussian of the whole streams; the voxel metrics averaged
        over the paired 20 ms chunks (NaN without a pair).

    Raises
    ------
    EventsError
        A stream of another dtype, or not sorted in time.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> gt = make_events([0, 5_000, 25_000], [1, 2, 3], [1, 1, 1], [1, 0, 1])
    >>> m = authors_metrics(gt, gt)
    >>> (m.chamfer, m.mse, m.r_f1, m.tp_f1, m.n_chunks)
    (0.0, 0.0, 1.0, 1.0, 2)
    """
    check_events(events_gt)
    check_events(events_pred)
    width, height = check_sensor_size(grid_size)
    chamfer, gaussian = authors_event_distances(events_gt, events_pred, workers=workers)
    pairs = list(zip(authors_chunks(events_gt), authors_chunks(events_pred), strict=False))
    if pairs:
        scores = np.mean([_chunk_scores(a, b, width, height) for a, b in pairs], axis=0)
    else:
        scores = np.full(6, math.nan)
    mse, pmse_2, pmse_4, r_f1, t_f1, tp_f1 = (float(v) for v in scores)
    return AuthorsMetrics(
        chamfer=chamfer,
        gaussian=gaussian,
        mse=mse,
        pmse_2=pmse_2,
        pmse_4=pmse_4,
        r_f1=r_f1,
        t_f1=t_f1,
        tp_f1=tp_f1,
        n_gt=int(events_gt.size),
        n_pred=int(events_pred.size),
        n_chunks=len(pairs),
    )
