r"""Train a learned keep head on simulated pairs, and choose its threshold on held-out ones.

The recipe (``edeflare train-head``):

1. **Labels.** Each input event of a training pair is *scene* where the ground
   truth holds an event of the same pixel and polarity within ``tolerance_us``
   (matched one to one, in time order: :func:`keep_labels`), or where the
   pair's ``light`` stream (the source through the clean lens, where the
   simulator stored it) does; *flare* otherwise. For keep-only targets (``gt`` a
   subset of ``input``) this is membership.
2. **Features.** The pair's input is cut into the model's windows; the base mask
   network gives each event its keep logit (no rules) and
   :func:`~edeflare.models.event_features.window_features` its evidence.
   Up to ``per_window`` events of each class are drawn per window, so every window
   (sparse or dense, small sensor or large) weighs alike. Where a pair stores the scene
   alone (its ``background`` stream), its windows are learned from too, every event
   kept: real recordings often hold no light, and simulated pairs always do.
3. **Fit.** :class:`~edeflare.models.event_head.EventHead`, standardised on its
   training events, trained with Adam on the balanced cross-entropy of
   :math:`\sigma(h + \ln 3)` (the mask's keep probability) against the labels, or,
   distilled, against a trained teacher head's keep probabilities
   (:func:`teacher_targets`).
4. **Threshold.** On the test splits of the same datasets (sequences never
   trained on; never a real recording) the keep threshold is the one with the best
   mean, over the datasets, of the harmonic mean of flare removed and scene kept.

The collected features are cached in the run folder (``features-*.npz``, written
atomically, named by what made them), so a rerun after a kill goes on from there.

Examples
--------
>>> from edeflare.events import make_events
>>> inp = make_events([0, 10, 20, 30], [1, 1, 2, 3], [0, 0, 0, 0], [1, 1, 0, 1])
>>> gt = make_events([12, 31], [1, 3], [0, 0], [1, 1])
>>> keep_labels(inp, gt, tolerance_us=5).tolist()   # one gt event for the two at (1, 0)
[False, True, False, True]
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numba
import numpy as np
import torch

from .._progress import progress_bar
from ..data.folders import dataset_folders
from ..errors import EdeflareError, ParameterError
from ..events import SensorSize
from ..io._atomic import atomic_path
from ..io.sequence import file_sha256, list_sequences, read_sequence
from ..lights.cells import covered_us
from ..rules import WindowContext
from .event_features import DEFAULT_FEATURES, window_features
from .event_head import EventHead, EventHeadEnsemble, event_cells, head_logits

__all__ = [
    "HeadTrainingConfig",
    "NetworkLogits",
    "check_thin",
    "choose_threshold",
    "collect_features",
    "collect_sets",
    "context_at",
    "context_columns",
    "fit_context_head",
    "fit_device",
    "fit_head",
    "keep_labels",
    "load_teacher",
    "loss_weights",
    "rows_in_windows",
    "shuffled_batches",
    "teacher_targets",
    "thinned",
    "train_head",
]

LN3 = math.log(3.0)


# ----------------------------------------------------------------------------- labels


@numba.njit(cache=True)
def _match(key_i, t_i, key_g, t_g, tol):  # pragma: no cover - compiled
    """Inputs (sorted by key, time) matched one to one to gt events (sorted alike)."""
    out = np.zeros(key_i.size, np.bool_)
    j = 0
    for i in range(key_i.size):
        while j < key_g.size and (
            key_g[j] < key_i[i] or (key_g[j] == key_i[i] and t_g[j] < t_i[i] - tol)
        ):
            j += 1
        if j < key_g.size and key_g[j] == key_i[i] and t_g[j] <= t_i[i] + tol:
            out[i] = True
            j += 1
    return out


@numba.njit(cache=True)
def _by_key(key, n_keys):  # pragma: no cover - compiled
    """A stable counting sort: the indices grouped by ``key`` (in ``[0, n_keys)``), each
    group in the order given, and where each group starts (``n_keys + 1``)."""
    start = np.zeros(n_keys + 1, np.int64)
    for k in key:
        start[k + 1] += 1
    for k in range(n_keys):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(key.size, np.int64)
    for i in range(key.size):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    return order, start


@numba.njit(cache=True)
def _match_time_sorted(key_i, t_i, key_g, t_g, n_keys, tol):  # pragma: no cover - compiled
    """:func:`_match` for streams in time order: each pixel and polarity's events in their
    time order by a counting sort (linear, where sorting by key and time is not)."""
    order_i, start_i = _by_key(key_i, n_keys)
    order_g, start_g = _by_key(key_g, n_keys)
    out = np.zeros(key_i.size, np.bool_)
    for k in range(n_keys):
        j, stop = start_g[k], start_g[k + 1]
        for a in range(start_i[k], start_i[k + 1]):
            i = order_i[a]
            while j < stop and t_g[order_g[j]] < t_i[i] - tol:
                j += 1
            if j < stop and t_g[order_g[j]] <= t_i[i] + tol:
                out[i] = True
                j += 1
    return out


def keep_labels(inp: np.ndarray, gt: np.ndarray, tolerance_us: int = 1_000) -> np.ndarray:
    """Which input events the ground truth holds: one gt event of the same pixel and
    polarity within ``tolerance_us`` each, matched in time order (True: scene, keep)."""
    if not inp.size or not gt.size:
        return np.zeros(inp.size, bool)
    ki, ti, kg, tg = _keys_and_times(inp, gt)
    if (np.diff(ti) >= 0).all() and (np.diff(tg) >= 0).all():  # as every stream is stored
        n_keys = int(max(ki.max(), kg.max())) + 1
        return _match_time_sorted(ki, ti, kg, tg, n_keys, int(tolerance_us))
    return _match_sorted_by_key(ki, ti, kg, tg, int(tolerance_us))


def _keys_and_times(
    inp: np.ndarray, gt: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each event's pixel and polarity as one key (the same numbering for both streams)
    and its time, as int64: ``(input keys, input times, gt keys, gt times)``."""
    width = int(max(inp["x"].max(), gt["x"].max())) + 1

    def keys(ev: np.ndarray) -> np.ndarray:
        return (ev["y"].astype(np.int64) * width + ev["x"]) * 2 + (ev["p"] != 0)

    return keys(inp), inp["t"].astype(np.int64), keys(gt), gt["t"].astype(np.int64)


def _match_sorted_by_key(
    ki: np.ndarray, ti: np.ndarray, kg: np.ndarray, tg: np.ndarray, tolerance_us: int
) -> np.ndarray:
    """:func:`keep_labels` of streams in any order (keys and times given): both sorted by
    key and time, then matched (``benchmarks/bench_labels.py``'s reference)."""
    oi = np.lexsort((ti, ki))
    og = np.lexsort((tg, kg))
    out = np.empty(ki.size, bool)
    out[oi] = _match(ki[oi], ti[oi], kg[og], tg[og], int(tolerance_us))
    return out


# ----------------------------------------------------------------------------- data


@dataclasses.dataclass(frozen=True)
class HeadTrainingConfig:
    """How a head is trained (recorded in the card's command and the caches' names)."""

    features: tuple[str, ...] = DEFAULT_FEATURES
    hidden: tuple[int, ...] = (32, 16)
    per_window: int = 2_000
    """Events of each class drawn per training window."""
    val_per_window: int = 20_000
    """Events drawn per validation window (classes as they come)."""
    tolerance_us: int = 1_000
    light_free_windows: bool = True
    """Also learn from the windows of the scene alone (a pair's ``background`` stream,
    where the simulator stored it), every event kept: a recording without a light."""
    flare_free_windows: bool = False
    """Also learn from the windows of each pair's ground truth alone, every event kept: a
    flare-free recording of the same scene, its light included (every pair has one)."""
    light_weight: float = 1.0
    """Loss weight of the light's own events (a pair's input events matched to its
    ``light`` stream, the source through the clean lens), times their class's weight: the
    real targets ask more of a light (95 % kept) than of its flare (85 % removed)."""
    scene_weight: float = 1.0
    """Loss weight of the events of the scene alone (``light_free_windows``: a recording
    without a light, every event kept), times their class's weight."""
    thin: float = 1.0
    """Rate augmentation: a random half of the training windows is thinned before its
    features are computed, each event kept with one probability per window drawn
    log-uniformly in ``[thin, 1]`` (1: none). A real light or scene seen with another
    sensor, bias or brightness fires at another rate than any simulated one."""
    context: int = 0
    """Channels of a learned whole-frame context (0: none): a cell U-Net on the network's
    inputs and keep logits, trained with the head (:class:`EventHead`)."""
    context_widths: tuple[int, ...] = (16, 32, 64, 64)
    """Level widths of the context's U-Net."""
    relative_context: bool = False
    """The context reads the cells' event counts relative to the window's mean count
    (``relative_counts`` of :class:`EventHead`): the same at any rate, as the
    ``rel_*`` features are."""
    epochs: int = 8
    batch_size: int = 4_096
    """Events per step (a head without a context)."""
    batch_windows: int = 8
    """Windows per step (a head with a context: their events together)."""
    lr: float = 3e-3
    seed: int = 0
    members: int = 1
    """Heads fitted from seeds ``seed``, ``seed + 1``, ... on the same drawn events, their
    keep logits averaged (:class:`EventHeadEnsemble`; 1: one head)."""
    windows: str = "all"
    """Which windows' rows the head is fitted on and its threshold chosen on: ``"all"``,
    ``"lit"`` (where the light test finds a light) or ``"unlit"`` (where it finds none),
    read from the rows' ``light_free`` feature (which the head must then read). The rows
    drawn are the same at any value (the filter acts after the draw): the expert of a pair
    (a card's ``unlit_model``) learns only the windows it will judge."""

    def __post_init__(self) -> None:
        if isinstance(self.members, bool) or not isinstance(self.members, int):
            raise EdeflareError(f"members must be a positive integer, got {self.members!r}")
        if self.members < 1:
            raise EdeflareError(f"members must be at least 1, got {self.members}")
        for name in ("light_weight", "scene_weight"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise EdeflareError(f"{name} must be a positive number, got {value!r}")
        check_thin(self.thin)
        _check_windows(self.windows)
        if self.windows != "all" and "light_free" not in self.features:
            raise ParameterError(
                f"windows={self.windows!r} reads the rows' light_free feature: add light_free "
                "to the features"
            )


WINDOW_SETS = ("all", "lit", "unlit")
"""The values of :attr:`HeadTrainingConfig.windows`."""


def _check_windows(windows: object) -> None:
    if windows not in WINDOW_SETS:
        raise ParameterError(f"windows must be one of {', '.join(WINDOW_SETS)}, got {windows!r}")


def _in_windows(windows: str, lead: str) -> str:
    """``lead`` and which windows ``windows`` names, for cards and messages ("" for all)."""
    found = {"lit": "a light", "unlit": "no light"}.get(windows)
    return "" if found is None else f"{lead} the windows where the light test finds {found}"


def rows_in_windows(
    data: dict[str, np.ndarray], features: Sequence[str], windows: str
) -> dict[str, np.ndarray]:
    """The rows of :func:`collect_features`' ``data`` (drawn with ``features``) from the
    windows where the light test finds a light (``windows="lit"``), finds none
    (``"unlit"``), or all of them (``"all"``: ``data`` itself). With a context, only those
    windows' cells are kept, renumbered in order.

    Examples
    --------
    >>> data = {"x": np.array([[0.0], [1.0], [0.0]]), "y": np.array([True, False, True]),
    ...         "light": np.zeros(3, bool), "source": np.array([0, 0, -1])}
    >>> rows_in_windows(data, ["light_free"], "unlit")["source"].tolist()
    [0]
    >>> rows_in_windows(data, ["light_free"], "lit")["y"].tolist()
    [True, True]
    """
    _check_windows(windows)
    if windows == "all":
        return data
    column = data["x"][:, list(features).index("light_free")]
    take = column == (1.0 if windows == "unlit" else 0.0)
    out = {key: data[key][take] for key in (*_ROW_KEYS, "window", "cell") if key in data}
    if "sizes" in data:  # the windows kept, their cells renumbered 0, 1, ...
        kept = np.unique(data["window"][take])
        out["window"] = np.searchsorted(kept, out["window"]).astype(data["window"].dtype)
        out["sizes"] = data["sizes"][kept]
        out.update({f"cells_{j:06d}": data[f"cells_{int(i):06d}"] for j, i in enumerate(kept)})
    return out


def check_thin(thin: object) -> float:
    """A rate augmentation's lowest share kept (:attr:`HeadTrainingConfig.thin`), checked.

    Examples
    --------
    >>> check_thin(0.25)
    0.25
    >>> check_thin(0.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: thin must be in (0, 1] (the lowest share ...), got 0.0
    """
    if isinstance(thin, bool) or not isinstance(thin, (int, float)) or not 0.0 < thin <= 1.0:
        raise ParameterError(
            f"thin must be in (0, 1] (the lowest share of a window's events kept), got {thin!r}"
        )
    return float(thin)


def thinned(rng: np.random.Generator, n: int, thin: float) -> np.ndarray | None:
    """Which of a window's ``n`` events a rate augmentation keeps: None (all) for half of
    the windows, else each event with one probability drawn log-uniformly in
    ``[thin, 1]`` (:attr:`HeadTrainingConfig.thin`; 1: always None, no draw).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> [None if k is None else round(float(k.mean()), 2) for k in
    ...  (thinned(rng, 10_000, 0.25) for _ in range(6))]
    [0.36, 0.79, 0.69, 0.52, None, None]
    >>> thinned(rng, 10, 1.0) is None
    True
    """
    if thin >= 1.0 or rng.random() < 0.5:
        return None
    share = math.exp(rng.uniform(math.log(thin), 0.0))
    return rng.random(n) < share


def _windows(events: np.ndarray, start: int, end: int, window_us: int):
    """``(window_start, slice)`` of a sorted stream cut into the model's windows (slices, not
    the events of :func:`~edeflare.events.iter_time_windows`: the labels are cut alike)."""
    t = events["t"]
    for s in range(int(start), int(end), int(window_us)):
        lo, hi = np.searchsorted(t, [s, s + window_us])
        if hi > lo:
            yield s, slice(int(lo), int(hi))


class NetworkLogits:
    """A mask model's network: the per-event keep logits of a batch of windows, its rules
    off and any head of its own left out (what a keep head is trained over).

    Loaded where it is first called and pickled as its weights' path alone, so that each
    worker of :func:`collect_features` loads its own copy.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.models import create_model
    >>> from edeflare.models.weights import ModelCard, save_model
    >>> from edeflare.events import make_events
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "m.safetensors"
    >>> save_model(p, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    >>> logits = NetworkLogits(p)
    >>> [v.tolist() for v in logits([(0, make_events([10], [1], [1], [1]))], (8, 8))]
    [[0.0]]
    >>> logits.window_us
    20000
    """

    def __init__(self, weights: str | os.PathLike[str]) -> None:
        self.weights = Path(weights)
        self._deflarer: Any = None

    @property
    def deflarer(self) -> Any:
        """The :class:`~edeflare.models.infer.ModelDeflarer` (torch, rules off, no head, no
        second expert: the network's own logits in every window)."""
        if self._deflarer is None:
            from .infer import ModelDeflarer
            from .weights import read_card

            card = read_card(self.weights)
            rules_off = {k: 0 for k in card.rules}
            deflarer = ModelDeflarer(self.weights, runtime="torch", batch_windows=1, **rules_off)
            deflarer.head_params = None
            deflarer.unlit = None
            self._deflarer = deflarer
        return self._deflarer

    @property
    def window_us(self) -> int:
        """The network's window in microseconds."""
        return int(self.deflarer.window_us)

    def __call__(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        *,
        cells: list[np.ndarray] | None = None,
    ) -> list[np.ndarray]:
        return self.deflarer.window_logits(batch, sensor_size, cells=cells)

    def __getstate__(self) -> dict[str, Any]:
        return {"weights": self.weights}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["weights"])


_ROW_KEYS = ("x", "y", "light", "source")


def _file_rows(
    path: Path,
    k: int,
    rng: np.random.Generator,
    window_logits: Callable[..., list[np.ndarray]] | None,
    window_us: int,
    config: HeadTrainingConfig,
    balanced: bool,
    cell_scale: int,
) -> dict[str, list[Any]]:
    """The rows drawn from one sequence (file ``k`` of the run), ``rng`` advanced past them.

    ``window_logits`` None: only the draws (which events of which windows; they hang on the
    labels and the windows' sizes, never on the features), so the generator's state
    before each file is known without its features: :func:`collect_features`' workers start
    each file from that state and draw the rows one process alone would.
    """
    out: dict[str, list[Any]] = {key: [] for key in (*_ROW_KEYS, "window", "cell", "cells")}
    inp, gt, size, start, end = read_sequence(path)
    labels = keep_labels(inp, gt, config.tolerance_us)
    light = _component(path, "light")
    of_light = np.zeros(inp.size, bool)
    if light is not None:  # the light source itself is scene, not flare
        of_light = keep_labels(inp, light, config.tolerance_us)
        labels |= of_light
    streams = [(inp, labels, of_light, k)]
    scene = _component(path, "background") if config.light_free_windows else None
    if scene is not None:  # the scene alone, as a recording without a light sees it
        streams.append((scene, np.ones(scene.size, bool), np.zeros(scene.size, bool), -1 - k))
    if config.flare_free_windows:  # the clean lens's recording of the same scene
        streams.append((gt, np.ones(gt.size, bool), np.zeros(gt.size, bool),
                        FLARE_FREE_SOURCE - k))  # fmt: skip
    for events, truth, lit, source in streams:
        for s, part in _windows(events, start, end, window_us):
            keep = thinned(rng, part.stop - part.start, config.thin) if balanced else None
            if keep is not None:  # the window as a sparser sensor would see it
                part = np.arange(part.start, part.stop)[keep]
                if not part.size:
                    continue
            y = truth[part]
            if balanced:
                take = np.concatenate(
                    [_draw(rng, np.flatnonzero(y == c), config.per_window) for c in (0, 1)]
                )
            else:
                take = _draw(rng, np.arange(y.size), config.val_per_window)
            if window_logits is None:
                continue
            ev = events[part]
            window_cells: list[np.ndarray] | None = None
            if config.context:  # the cells the context reads, with the logits
                window_cells = []
                logit = window_logits([(s, ev)], size, cells=window_cells)[0]
            else:
                logit = window_logits([(s, ev)], size)[0]
            ctx = WindowContext(ev, size, covered_us(ev, s, window_us))
            f = window_features(ctx, logit, config.features, window_us=window_us)
            out["x"].append(f[take])
            out["y"].append(y[take])
            out["light"].append(lit[part][take])
            out["source"].append(np.full(take.size, source, np.int32))
            if window_cells is not None:  # the window's index within this file
                out["window"].append(np.full(take.size, len(out["cells"]), np.int32))
                cells_wide = window_cells[0].shape[2]
                out["cell"].append(event_cells(ev[take], cell_scale, cells_wide).astype(np.int32))
                out["cells"].append((window_cells[0].astype(np.float16), size))
    return out


def _rows_in_worker(
    path: Path,
    k: int,
    state: dict[str, Any],
    window_logits: Callable[..., list[np.ndarray]],
    window_us: int,
    config: HeadTrainingConfig,
    balanced: bool,
    cell_scale: int,
) -> dict[str, list[Any]]:
    """:func:`_file_rows` in a pool worker, its generator started from ``state``."""
    rng = np.random.default_rng()
    rng.bit_generator.state = state
    return _file_rows(path, k, rng, window_logits, window_us, config, balanced, cell_scale)


def _init_row_worker(parent: int, threads: int) -> None:
    from .._parallel import init_worker

    init_worker(parent, threads)
    torch.set_num_threads(threads)


def _rows_in_pool(
    files: Sequence[Path],
    rng: np.random.Generator,
    window_logits: Callable[..., list[np.ndarray]],
    window_us: int,
    config: HeadTrainingConfig,
    balanced: bool,
    cell_scale: int,
    workers: int,
    bar: Any,
) -> Iterator[dict[str, list[Any]]]:
    """Each file's rows, in order, drawn by ``workers`` processes: this one draws ahead
    without features (:func:`_file_rows`) to hand each file its generator's state."""
    from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
    from multiprocessing import get_context

    from .._interrupt import check_interrupt, sigint_blocked
    from .._parallel import stop_workers

    threads = max(1, (os.cpu_count() or 1) // workers)
    done_rows: dict[int, dict[str, list[Any]]] = {}
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=get_context("spawn"),
        initializer=_init_row_worker,
        initargs=(os.getpid(), threads),
    ) as pool:
        pending: dict[Future[Any], int] = {}
        queued, handed = 0, 0
        try:
            while handed < len(files):
                while queued < len(files) and len(pending) < 2 * workers:
                    state = rng.bit_generator.state
                    _file_rows(files[queued], queued, rng, None, window_us, config,
                               balanced, cell_scale)  # fmt: skip
                    with sigint_blocked():  # a worker started here starts deaf to Ctrl-C
                        task = (files[queued], queued, state, window_logits, window_us,
                                config, balanced, cell_scale)  # fmt: skip
                        pending[pool.submit(_rows_in_worker, *task)] = queued
                    queued += 1
                done, _ = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                check_interrupt()
                for fut in done:
                    done_rows[pending.pop(fut)] = fut.result()
                    bar.update(1)
                while handed in done_rows:  # in the files' order
                    yield done_rows.pop(handed)
                    handed += 1
        except Exception:
            for fut in pending:
                fut.cancel()
            raise
        except BaseException:  # Ctrl-C: the files in flight stop too
            stop_workers(pool)
            raise


def collect_features(
    files: Sequence[Path],
    window_logits: Callable[..., list[np.ndarray]],
    window_us: int,
    config: HeadTrainingConfig,
    *,
    balanced: bool,
    progress: bool = True,
    desc: str = "features",
    cell_scale: int = 8,
    workers: int = 1,
) -> dict[str, np.ndarray]:
    """Features, labels and each row's file index of the events drawn from ``files``
    (``x``, ``y``, ``source``), and which rows are the light's own events (``light``).

    ``window_logits`` is the base network's per-event keep logits of a batch of
    windows (:class:`NetworkLogits`, or
    :meth:`~edeflare.models.infer.ModelDeflarer.window_logits` with no rules).
    With a context (``config.context``), also each window's cells (``cells_NNNNNN``: the
    network's inputs and keep logits), its sensor (``sizes``) and each row's window and
    cell of ``cell_scale`` pixels (``window``, ``cell``).

    ``workers`` > 1 draws the files in that many processes (``window_logits`` must then
    pickle, as :class:`NetworkLogits` does): the same rows as one process, in the same
    order.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be a positive integer, got {workers!r}")
    rng = np.random.default_rng(config.seed)
    rows: dict[str, list[np.ndarray]] = {key: [] for key in (*_ROW_KEYS, "window", "cell")}
    cells: list[np.ndarray] = []
    sizes: list[SensorSize] = []
    pooled = workers > 1 and len(files) > 1  # (the pool moves the bar as files finish)
    bar = progress_bar(total=len(files), enabled=progress, desc=desc, unit="file")
    with bar:
        if pooled:
            per_file: Iterable[dict[str, list[Any]]] = _rows_in_pool(
                files, rng, window_logits, window_us, config, balanced, cell_scale,
                min(workers, len(files)), bar,
            )  # fmt: skip
        else:
            per_file = (
                _file_rows(f, k, rng, window_logits, window_us, config, balanced, cell_scale)
                for k, f in enumerate(files)
            )
        for got in per_file:
            for key in _ROW_KEYS:
                rows[key] += got[key]
            rows["window"] += [w + len(cells) for w in got["window"]]
            rows["cell"] += got["cell"]
            cells += [c for c, _ in got["cells"]]
            sizes += [size for _, size in got["cells"]]
            if not pooled:
                bar.update(1)
    if not rows["x"]:
        raise EdeflareError("no events to learn from in " + ", ".join(map(str, files[:3])))
    out = {key: np.concatenate(rows[key]) for key in _ROW_KEYS}
    if config.context:
        out.update(window=np.concatenate(rows["window"]), cell=np.concatenate(rows["cell"]))
        out["sizes"] = np.asarray(sizes, np.int32).reshape(-1, 2)
        out.update({f"cells_{i:06d}": c for i, c in enumerate(cells)})
    return out


def _component(path: Path, group: str) -> np.ndarray | None:
    """A stream the simulator stored beside the pair (``light``: the source through the
    clean lens; ``background``: the scene without the light), if the file has it."""
    import h5py

    from ..io.dsec import DsecReader

    with h5py.File(path, "r") as f:
        if f"{group}/events" not in f:
            return None
    with DsecReader(path, group=f"{group}/events") as reader:
        return reader.read()


def _group(files: Sequence[str], source: int) -> str:
    """The validation group of a row: its dataset (a mix's part), the scene without a
    light, or the flare-free recordings."""
    if source >= 0:
        return Path(files[source]).parent.parent.name
    return "flare-free recording" if source <= FLARE_FREE_SOURCE else "scene without a light"


def _draw(rng: np.random.Generator, idx: np.ndarray, n: int) -> np.ndarray:
    return idx if idx.size <= n else np.sort(rng.choice(idx, n, replace=False))


# ----------------------------------------------------------------------------- fit


def loss_weights(
    y: np.ndarray,
    config: HeadTrainingConfig,
    *,
    light: np.ndarray | None = None,
    source: np.ndarray | None = None,
) -> torch.Tensor:
    """Each training row's loss weight: its class's (the two classes weigh alike), times
    ``config.light_weight`` for the light's own events (``light``) and
    ``config.scene_weight`` for the scene alone's (``source`` < 0, not a flare-free
    recording's: :data:`FLARE_FREE_SOURCE`).

    Examples
    --------
    >>> cfg = HeadTrainingConfig(light_weight=4.0, scene_weight=2.0)
    >>> y = np.array([False, True, True, True])
    >>> w = loss_weights(y, cfg, light=np.array([False, True, False, False]),
    ...                  source=np.array([0, 0, 0, -1]))
    >>> np.round(w.numpy(), 3).tolist()   # flare 0.5/0.25, keep 0.5/0.75; x4 light, x2 alone
    [2.0, 2.667, 0.667, 1.333]
    """
    keep_share = float(np.mean(y))
    if not 0.0 < keep_share < 1.0:
        raise EdeflareError("the training events are all of one class (all flare or all scene)")
    w = np.where(y, 0.5 / keep_share, 0.5 / (1.0 - keep_share))
    if config.light_weight != 1.0:
        if light is None:
            raise EdeflareError("light_weight needs the rows' light flags (collected features)")
        w = np.where(light, w * config.light_weight, w)
    if config.scene_weight != 1.0:
        if source is None:
            raise EdeflareError("scene_weight needs the rows' sources (collected features)")
        alone = (source < 0) & (source > FLARE_FREE_SOURCE)
        w = np.where(alone, w * config.scene_weight, w)
    return torch.from_numpy(w.astype(np.float32))


def _window_cells(data: dict[str, np.ndarray], ids: Sequence[int]) -> torch.Tensor:
    return torch.from_numpy(np.stack([data[f"cells_{i:06d}"] for i in ids]).astype(np.float32))


def _window_batches(
    data: dict[str, np.ndarray], per_batch: int, rng: np.random.Generator | None
) -> list[list[int]]:
    """Windows in batches of one sensor size (shuffled with ``rng``)."""
    by_size: dict[tuple[int, int], list[int]] = {}
    for i, size in enumerate(map(tuple, data["sizes"])):
        by_size.setdefault(size, []).append(i)
    out = []
    for ids in by_size.values():
        order = list(rng.permutation(ids)) if rng is not None else ids
        out += [[int(i) for i in order[j : j + per_batch]] for j in range(0, len(order), per_batch)]
    return [out[i] for i in rng.permutation(len(out))] if rng is not None else out


def _rows_of(data: dict[str, np.ndarray]) -> list[np.ndarray]:
    """Each window's rows (indices into ``x``)."""
    order = np.argsort(data["window"], kind="stable")
    bounds = np.searchsorted(data["window"][order], np.arange(len(data["sizes"]) + 1))
    return [order[a:b] for a, b in itertools.pairwise(bounds)]


def context_at(maps: torch.Tensor, window: torch.Tensor, cell: torch.Tensor) -> torch.Tensor:
    """The values ``(n, k)`` of windows' maps ``(N, k, h, w)`` at each row's ``window`` (an
    index into ``N``) and flat ``cell`` (``y * w + x``), as ``maps.reshape(N, k, -1)[window,
    :, cell]`` gives them, with a backward that adds the rows' gradients in a fixed order.

    Advanced indexing's backward adds them from several threads in no fixed order: two fits
    of one command on the same drawn rows ended apart (validation 0.852 and 0.873).
    ``index_select``'s adds them in a fixed order, so a fit is the same to the bit.

    Examples
    --------
    >>> maps = torch.arange(2 * 3 * 4, dtype=torch.float32).reshape(2, 3, 2, 2)
    >>> context_at(maps, torch.tensor([1, 0]), torch.tensor([3, 0])).tolist()
    [[15.0, 19.0, 23.0], [0.0, 4.0, 8.0]]
    """
    n, k, h, w = maps.shape
    return maps.permute(0, 2, 3, 1).reshape(n * h * w, k).index_select(0, window * (h * w) + cell)


def _context_batch(
    head: EventHead | EventHeadEnsemble,
    data: dict[str, np.ndarray],
    rows: list[np.ndarray],
    ids: list[int],
) -> tuple[torch.Tensor, np.ndarray]:
    """The features with their context columns of the rows of windows ``ids`` (on the
    head's device), and the rows."""
    device = next(head.parameters()).device
    maps = head.context_maps(_window_cells(data, ids).to(device))  # (B, k, h, w)
    idx = np.concatenate([rows[i] for i in ids])
    which = torch.from_numpy(np.concatenate([np.full(rows[i].size, j) for j, i in enumerate(ids)]))
    cell = torch.from_numpy(data["cell"][idx].astype(np.int64))
    ctx = context_at(maps, which.to(device), cell.to(device))
    x = torch.from_numpy(np.ascontiguousarray(data["x"][idx], np.float32)).to(device)
    return torch.cat([x, ctx], 1), idx


def context_columns(head: EventHead | EventHeadEnsemble, data: dict[str, np.ndarray]) -> np.ndarray:
    """Every row's features and context columns ``(n, features + k)`` (float32), as
    :meth:`~edeflare.models.infer.ModelDeflarer.window_logits` gives them to the head."""
    out = np.empty((data["x"].shape[0], head.columns), np.float32)
    rows = _rows_of(data)
    with torch.no_grad():
        for ids in _window_batches(data, 8, None):
            z, idx = _context_batch(head, data, rows, ids)
            out[idx] = z.numpy()
    return out


def load_teacher(
    teacher: str | os.PathLike[str],
    base: str | os.PathLike[str],
    features: Sequence[str],
    *,
    context: bool,
) -> EventHead | EventHeadEnsemble:
    """The keep head of ``teacher``, checked to fit a student over ``base``'s network that
    reads ``features`` (with a ``context`` of the windows' cells, or not)."""
    from .weights import load_model

    model, _ = load_model(teacher)
    head = getattr(model, "head", None)
    if head is None:
        raise EdeflareError(f"{teacher}: the teacher has no keep head (train one with train-head)")
    if list(head.feature_names) != list(features):
        raise EdeflareError(
            f"{teacher}: the teacher reads the features {list(head.feature_names)}, the "
            f"student {list(features)}: they must be the same"
        )
    net, _ = load_model(base)
    mine = model.state_dict()
    for name, value in net.state_dict().items():
        other = mine.get(name)
        if not name.startswith("head.") and (other is None or not torch.equal(value, other)):
            raise EdeflareError(
                f"{teacher}: the teacher's network differs from that of {base} ({name}): its "
                "head reads another network's logits"
            )
    if head.context and not context:
        raise EdeflareError(
            f"{teacher}: the teacher reads a context of the windows' cells: train the student "
            "with a context too (--context K)"
        )
    return head


def teacher_targets(
    teacher: str | os.PathLike[str],
    base: str | os.PathLike[str],
    features: Sequence[str],
    data: dict[str, np.ndarray],
) -> np.ndarray:
    """The keep probability that ``teacher``, a trained head (or ensemble) over the network of
    ``base``, gives each row of ``data``: what a distilled head learns instead of the labels.

    The teacher must read ``features`` (in that order) and the same network as ``base``
    (the rows' features and cells come from it); where it has a context, ``data`` must hold
    the windows' cells (:func:`load_teacher` checks).
    """
    has_cells = any(k.startswith("cells_") for k in data)
    return _head_probabilities(load_teacher(teacher, base, features, context=has_cells), data)


def _head_probabilities(
    head: EventHead | EventHeadEnsemble, data: dict[str, np.ndarray]
) -> np.ndarray:
    """``head``'s keep probability of each row of ``data`` (float32)."""
    columns = context_columns(head, data) if head.context else data["x"]
    return _keep_probability(head_logits(head.numpy_params(), columns)).astype(np.float32)


def _keep_probability(logits: np.ndarray) -> np.ndarray:
    """A head's keep probability of its keep ``logits``: :math:`\\sigma(h + \\ln 3)`, the
    mask's (float64).

    Examples
    --------
    >>> _keep_probability(np.array([-math.log(3.0)])).tolist()
    [0.5]
    """
    return 1.0 / (1.0 + np.exp(-(np.asarray(logits, np.float64) + LN3)))


def fit_head(
    x: np.ndarray,
    y: np.ndarray,
    config: HeadTrainingConfig,
    *,
    targets: np.ndarray | None = None,
    light: np.ndarray | None = None,
    source: np.ndarray | None = None,
    progress: bool = True,
    device: str = "auto",
) -> EventHead:
    """A head fitted to features ``x`` and labels ``y`` (True: keep), rows weighed by
    :func:`loss_weights` (``light``, ``source``: the collected rows' flags) (without a
    context: :func:`fit_context_head` learns one). ``targets``: keep probabilities to learn
    instead of the labels (a teacher's, :func:`teacher_targets`); the labels still weigh
    the classes. ``device``: where it is fitted (:func:`fit_device`); returned on the CPU."""
    dev = fit_device(device)
    torch.manual_seed(config.seed)
    head = EventHead(config.features, config.hidden)
    xt = torch.from_numpy(np.ascontiguousarray(x, np.float32))
    weight = loss_weights(np.asarray(y, bool), config, light=light, source=source).to(dev)
    yt = torch.from_numpy(np.asarray(y if targets is None else targets, np.float32)).to(dev)
    head.standardise_on(xt)
    head.to(dev)
    xt = xt.to(dev)
    gen = torch.Generator().manual_seed(config.seed)
    size = config.batch_size

    def loss(b: torch.Tensor) -> torch.Tensor:
        b = b.to(dev)
        return torch.nn.functional.binary_cross_entropy_with_logits(
            head(xt[b]) + LN3, yt[b], weight=weight[b]
        )

    steps = config.epochs * max(1, -(-len(yt) // size))
    return _optimise(head, config, steps, shuffled_batches(len(yt), size, config.epochs, gen),
                     loss, progress).cpu()  # fmt: skip


def fit_device(device: str = "auto") -> torch.device:
    """The torch device a head is fitted on: ``"auto"`` (CUDA where available, else the
    CPU), ``"cpu"``, ``"cuda"``, ``"cuda:1"``...

    Examples
    --------
    >>> fit_device("cpu")
    device(type='cpu')
    >>> fit_device("tpu")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: device must be auto, cpu, cuda or cuda:N, got 'tpu'...
    """
    from .infer import _device

    try:
        dev = _device(device)  # "auto": CUDA where available, as the network's own device
    except (RuntimeError, TypeError):
        dev = None
    if dev is None or dev.type not in ("cpu", "cuda"):
        raise ParameterError(f"device must be auto, cpu, cuda or cuda:N, got {device!r}")
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ParameterError(f"device {device!r}: torch sees no CUDA device here")
    return dev


def shuffled_batches(
    n: int, size: int, epochs: int, gen: torch.Generator
) -> Iterator[Iterator[torch.Tensor]]:
    """Each epoch's batches of row indices: ``0 .. n-1`` shuffled by ``gen`` (drawn as the
    epoch starts), cut into batches of ``size``.

    Examples
    --------
    >>> gen = torch.Generator().manual_seed(0)
    >>> [[b.tolist() for b in e] for e in shuffled_batches(3, 2, 1, gen)]
    [[[2, 0], [1]]]
    """
    for _ in range(epochs):
        order = torch.randperm(n, generator=gen)
        yield (order[lo : lo + size] for lo in range(0, n, size))


def _optimise(
    head: EventHead,
    config: HeadTrainingConfig,
    steps: int,
    epochs: Iterable[Iterable[Any]],
    loss: Callable[[Any], torch.Tensor],
    progress: bool,
) -> EventHead:
    """Adam with a one-cycle schedule over ``steps`` batches (``epochs``: each epoch's
    batches, ``loss``: a batch's loss); the head in eval mode."""
    opt = torch.optim.Adam(head.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=steps)
    bar = progress_bar(total=steps, enabled=progress, desc="fit", unit="step")
    head.train()
    for batches in epochs:
        for batch in batches:
            value = loss(batch)
            opt.zero_grad()
            value.backward()
            opt.step()
            sched.step()
            bar.update()
    bar.close()
    return head.eval()


def fit_context_head(
    data: dict[str, np.ndarray],
    config: HeadTrainingConfig,
    *,
    targets: np.ndarray | None = None,
    progress: bool = True,
    count_channels: int = 0,
    device: str = "auto",
) -> EventHead:
    """A head with a context of ``config.context`` maps fitted to :func:`collect_features`'
    output (the rows with their windows' cells): each step learns from the drawn events of
    ``config.batch_windows`` windows of one sensor size, rows weighed by
    :func:`loss_weights`. ``targets``: keep probabilities to learn instead of the labels,
    as :func:`fit_head`. ``count_channels``: the cells' leading event-count channels, read
    relative to the window's mean where ``config.relative_context``. ``device``: where it is
    fitted (:func:`fit_device`); returned on the CPU."""
    dev = fit_device(device)
    torch.manual_seed(config.seed)
    y = data["y"]
    cells0 = data["cells_000000"]
    context = {"channels": config.context, "inputs": int(cells0.shape[0]),
               "widths": list(config.context_widths)}  # fmt: skip
    if config.relative_context:
        if not 0 < count_channels <= context["inputs"]:
            raise EdeflareError(
                f"a relative context needs the cells' count channels, got {count_channels}"
            )
        context["relative_counts"] = count_channels
    head = EventHead(config.features, config.hidden, context)
    n = len(data["sizes"])

    def read(i: int) -> np.ndarray:  # a window's cells as the context reads them
        cells = torch.from_numpy(data[f"cells_{i:06d}"].astype(np.float32))[None]
        return head.context_input(cells)[0].numpy()

    sample = [read(i) for i in range(0, n, max(1, n // 64))]
    flat = np.concatenate([c.reshape(c.shape[0], -1) for c in sample], 1).astype(np.float32)
    head.standardise_on(  # the cells of windows of every size, as (1, channels, 1, cells)
        torch.from_numpy(np.asarray(data["x"], np.float32)), torch.from_numpy(flat)[None, :, None]
    )
    weight = loss_weights(
        np.asarray(y, bool), config, light=data.get("light"), source=data.get("source")
    ).to(dev)
    yt = torch.from_numpy(np.asarray(y if targets is None else targets, np.float32)).to(dev)
    head.to(dev)
    rows = _rows_of(data)
    rng = np.random.default_rng(config.seed)

    def epochs() -> Iterator[list[list[int]]]:
        for _ in range(config.epochs):
            yield _window_batches(data, config.batch_windows, rng)

    def loss(ids: list[int]) -> torch.Tensor:
        z, idx = _context_batch(head, data, rows, ids)
        b = torch.from_numpy(idx).to(dev)
        return torch.nn.functional.binary_cross_entropy_with_logits(
            head(z) + LN3, yt[b], weight=weight[b]
        )

    steps = config.epochs * len(_window_batches(data, config.batch_windows, None))
    return _optimise(head, config, steps, epochs(), loss, progress).cpu()


def choose_threshold(
    logits: np.ndarray, y: np.ndarray, groups: np.ndarray
) -> tuple[float, list[dict[str, float]]]:
    """The keep threshold with the best mean over ``groups`` of the harmonic mean of flare
    removed and scene kept, and the table of every candidate (0.05 to 0.95).

    Examples
    --------
    >>> logits = np.array([-3.0, -2.5, 0.0, 1.0])     # keep probability sigma(l + ln 3)
    >>> thr, _ = choose_threshold(logits, np.array([False, False, True, True]), np.zeros(4))
    >>> 0.1 < thr < 0.75
    True
    """
    from ..eval.score import combined_score  # the scorer's harmonic mean of defined terms

    prob = _keep_probability(logits)
    table = []
    for thr in np.round(np.arange(0.05, 0.951, 0.05), 2):
        kept = prob > thr
        scores = []
        for g in np.unique(groups):
            sel = groups == g
            flare, scene = sel & ~y, sel & y
            removed = 1.0 - kept[flare].mean() if flare.any() else np.nan
            scene_kept = kept[scene].mean() if scene.any() else np.nan
            scores.append(combined_score(removed, scene_kept, np.nan))
        table.append({"threshold": float(thr), "score": float(np.mean(scores))})
    best = max(table, key=lambda r: r["score"])
    return best["threshold"], table


# ----------------------------------------------------------------------------- the run


_FEATURE_FIELDS = ("features", "per_window", "val_per_window", "tolerance_us",
                   "light_free_windows", "flare_free_windows", "thin", "seed")  # fmt: skip
"""The config fields the collected features depend on (not the fit's: a head of another
size or schedule reuses a run's features)."""

FLARE_FREE_SOURCE = -1_000_001
"""The ``source`` of rows drawn from a pair's ground truth alone: this minus the file's
index (the scene alone's rows are ``-1 - index``; a pair's own rows, the index)."""


def _identity(files: Sequence[Path], base: Path, config: HeadTrainingConfig, kind: str) -> str:
    h = hashlib.sha256()
    h.update(file_sha256(base).encode())
    fields = {k: v for k, v in dataclasses.asdict(config).items() if k in _FEATURE_FIELDS}
    if not fields["flare_free_windows"]:  # runs from before the option keep their features
        del fields["flare_free_windows"]
    if fields["thin"] == 1.0 or kind == "test":  # likewise; the test rows are never thinned
        del fields["thin"]
    if config.context:  # the windows' cells are collected too
        fields["cells"] = True
    h.update(json.dumps([fields, kind, "gt|light", "light rows"], sort_keys=True).encode())
    for f in files:
        h.update(f"{f.parent.parent.name}/{f.parent.name}/{f.name}:{f.stat().st_size}".encode())
    return h.hexdigest()[:16]


def _cached(path: Path, make: Callable[[], dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    if path.is_file():
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    data = make()
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **data)
    return data


def collect_sets(
    folders: Sequence[Path],
    base: Path,
    run: Path,
    config: HeadTrainingConfig,
    *,
    progress: bool = True,
    workers: int = 1,
) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, list[str]], torch.nn.Module]:
    """The rows of the dataset ``folders``' training (balanced) and test splits over the
    network of ``base`` (its own keep logits: its rules off, any head of its own left
    out), cached in ``run``; the files of each split; and the network (a torch module,
    ``base``'s head still on it where it has one). ``workers``: processes drawing the rows
    (the same rows at any number)."""
    logits = NetworkLogits(base)
    net = logits.deflarer.model
    files_of: dict[str, list[str]] = {}
    sets = {}
    for split, balanced in (("train", True), ("test", False)):
        files = [f for d in folders if (d / split).is_dir() for f in list_sequences(d / split)]
        if not files:
            raise EdeflareError(f"no {split} sequences in {', '.join(map(str, folders))}")
        files_of[split] = [str(f) for f in files]
        key = _identity(files, base, config, split)
        sets[split] = _cached(
            run / f"features-{split}-{key}.npz",
            lambda files=files, balanced=balanced, split=split: collect_features(
                files, logits, logits.window_us, config, balanced=balanced,
                progress=progress, desc=split, cell_scale=net.scale, workers=workers,
            ),
        )  # fmt: skip
    return sets, files_of, net


def train_head(
    data: Sequence[str | os.PathLike[str]],
    base_weights: str | os.PathLike[str],
    run_dir: str | os.PathLike[str],
    config: HeadTrainingConfig | None = None,
    *,
    command: str = "",
    teacher: str | os.PathLike[str] | None = None,
    progress: bool = True,
    workers: int = 1,
    device: str = "auto",
) -> dict[str, Any]:
    """Train a keep head on ``data``'s training splits over the ``base_weights`` mask
    network; write ``run_dir/model.safetensors`` (network, head, card with the threshold
    chosen on the test splits) and ``run_dir/head.json``; return that summary.

    ``teacher``: a trained head's weights over the same network (an ensemble, typically):
    the head learns the teacher's keep probabilities instead of the labels (distillation:
    one small head that decides like many).

    ``workers``: processes drawing the training rows (the same rows at any number).
    ``device``: where the heads are fitted (:func:`fit_device`).
    """
    from .weights import read_card, save_model

    config = config or HeadTrainingConfig()
    base = Path(base_weights)
    fit_device(device)  # checked before anything is read or written
    teacher_head = (
        None
        if teacher is None
        else load_teacher(teacher, base, config.features, context=bool(config.context))
    )
    run = Path(run_dir)
    run.mkdir(parents=True, exist_ok=True)
    folders = [part for d in data for part in dataset_folders(d)]
    card = read_card(base)
    sets, summary_files, net = collect_sets(
        folders, base, run, config, progress=progress, workers=workers
    )
    if getattr(net, "head", None) is not None:
        del net.head  # a fresh head over the same network
    train, val = (rows_in_windows(sets[k], config.features, config.windows) for k in sets)
    for split, rows in (("training", train), ("test", val)):
        if not rows["y"].size:
            raise EdeflareError(
                f"no {split} rows{_in_windows(config.windows, ' in')} (windows="
                f"{config.windows!r}) in {', '.join(map(str, folders))}"
            )
    targets = None if teacher_head is None else _head_probabilities(teacher_head, train)
    heads = [
        fit_context_head(
            train,
            member,
            targets=targets,
            progress=progress,
            count_channels=2 * card.bins,
            device=device,
        )  # the cells: log counts of each bin and polarity, the firing share, the logits
        if config.context
        else fit_head(
            train["x"],
            train["y"],
            member,
            targets=targets,
            light=train.get("light"),
            source=train["source"],
            progress=progress,
            device=device,
        )
        for member in (
            dataclasses.replace(config, seed=config.seed + i) for i in range(config.members)
        )
    ]
    head = heads[0] if len(heads) == 1 else EventHeadEnsemble(heads)
    val_files = summary_files["test"]
    groups = np.array([_group(val_files, int(i)) for i in val["source"]])
    columns = context_columns(head, val) if config.context else val["x"]
    logits = head_logits(head.numpy_params(), columns)
    threshold, table = choose_threshold(logits, val["y"], groups)
    net.head = head
    card = dataclasses.replace(
        card,
        head=head.spec(),
        rules={},
        unlit_model="",  # the new head judges every window
        keep_threshold=threshold,
        command=command or f"train_head({[str(d) for d in data]!r}, {str(base)!r})",
        data=" ".join(str(d) for d in folders),
        metrics={"head_validation_score": max(r["score"] for r in table)},
        notes=f"a learned keep head over the network of {base.name}"
        + ("" if teacher is None else f", distilled from {Path(teacher).name}")
        + _in_windows(config.windows, ", fitted on")
        + ", threshold chosen on the data's test splits",
    )
    save_model(run / "model.safetensors", net, card)
    summary = {
        "keep_threshold": threshold,
        "threshold_table": table,
        "chosen_on": "the datasets' test splits: "
        + ", ".join(sorted(set(groups)))
        + _in_windows(config.windows, ", in"),
        "train_events": int(train["y"].size),
        "train_keep_share": float(train["y"].mean()),
        "val_events": int(val["y"].size),
        "config": dataclasses.asdict(config),
        "base_weights": str(base),
        "base_sha256": file_sha256(base),
    }
    if teacher is not None:
        summary["teacher"] = str(teacher)
        summary["teacher_sha256"] = file_sha256(Path(teacher))
    with atomic_path(run / "head.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=1) + "\n")
    return summary
