r"""Fit a trained keep head further to annotated real recordings, beside simulated pairs.

A head learned from simulation alone meets real flare it never saw. A real recording has
no flare-free twin, but an annotation of its lights (:mod:`edeflare.lights`) says which of
its events a de-flarer should keep, as the scorer reads it (:func:`region_labels`): the
light's own events kept, its halo and ghost removed, the rest of the scene kept where the
annotation scores it; a recording without a light, every event kept. These labels are
weak (a halo's region also holds the scene lit under it), so they join the simulated
pairs' rows instead of replacing them:

1. **Real rows.** Each recording in the windowings its score runs
   (:data:`DELAYS_US`: the model's windows delayed by 0, 5, 10 and 15 ms), every event's
   head inputs (:meth:`~edeflare.models.infer.ModelDeflarer.head_inputs`); at most
   ``per_region`` rows per labelled region and recording are drawn.
2. **Simulated rows.** Drawn from the pairs' training split as ``train-head`` draws them,
   the head's context columns computed by the head itself.
3. **Weights.** The simulated rows keep ``train-head``'s weights (the two classes alike,
   mean 1); the real rows weigh ``real_weight`` times as much in all, each recording
   alike and each labelled region of a recording alike.
4. **Fit.** Only the perceptrons are fitted, from the head's own weights and
   standardisation (a context U-Net, frozen, gives their inputs), with Adam on the
   balanced cross-entropy of ``train-head``.

5. **Validation.** With ``validate_last``, the last share of each recording's span is left
   out of the fit (and a gap of a window and the largest delay before it, so that no
   window of any windowing holds events of both parts) and scored after it, beside the
   head before the fit (:func:`validation_scores`): labels of one window of a recording
   carried over to the rest of it where those of other recordings did not
   (``experiments/real-labels``), so that is what a user can check.

The layout of the head is unchanged: the tuned model runs, exports and streams as the one
it came from.

Examples
--------
>>> from edeflare.events import make_events
>>> from edeflare.lights import Lights, LightSource
>>> ev = make_events([0, 1, 2], [10, 16, 40], [10, 10, 10], [1, 1, 0])
>>> lights = Lights((LightSource.circle(10, 10, 2),), score_background=True)
>>> [REGIONS[c] for c in region_labels(ev, (64, 48), lights)]
['light', 'flare', 'scene']
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..data.folders import dataset_folders
from ..errors import EdeflareError
from ..events import SensorSize
from ..io._atomic import atomic_path
from ..io.sequence import file_sha256
from ..lights import Lights
from .event_head import EventHead, EventHeadEnsemble, head_logits
from .head_training import (
    LN3,
    HeadTrainingConfig,
    _optimise,
    check_thin,
    loss_weights,
    shuffled_batches,
)
from .two_view import view_windows

__all__ = [
    "DELAYS_US",
    "REGIONS",
    "LabelledRecording",
    "TuningConfig",
    "fit_members",
    "real_rows",
    "recording_inputs",
    "recording_scores",
    "region_labels",
    "time_split",
    "tune_head",
    "validation_gap_us",
    "validation_scores",
]

REGIONS = ("unlabelled", "light", "flare", "scene")
"""The codes of :func:`region_labels`: 0 unlabelled, 1 the light (kept), 2 its halo and
ghost (removed), 3 the scene (kept)."""

DELAYS_US = (0, 5_000, 10_000, 15_000)
"""The windowings a recording's rows are drawn from: those its score runs at four window
phases (``score_recording(phases=4)``) with a mask model's 5 ms second view."""


def region_labels(events: np.ndarray, sensor_size: SensorSize, lights: Lights | None) -> np.ndarray:
    """Each event's region code (:data:`REGIONS`) as the scorer reads the annotation
    (:func:`~edeflare.eval.score.classify_events`): light 1, halo and ghost 2, the rest
    of the scene 3 where the annotation scores it (else 0, unlabelled); every event 3
    without ``lights`` (a recording without a light)."""
    from ..eval.score import classify_events

    if lights is None:
        return np.full(events.size, 3, np.int8)
    regions = classify_events(events, lights, sensor_size)
    code = np.zeros(events.size, np.int8)
    if lights.score_background:
        code[regions.background] = 3
    code[regions.flare] = 2
    code[regions.light] = 1
    return code


def recording_inputs(
    deflarer: Any, events: np.ndarray, sensor_size: SensorSize, delays_us: Sequence[int]
) -> np.ndarray:
    """Every event's keep head inputs in each windowing ``delays_us``: ``(delays, n,
    columns)`` float32 (a mask model's windows delayed as :class:`TwoViewStreamer`'s second
    view is).

    ``deflarer``: a :class:`~edeflare.models.infer.ModelDeflarer` with a keep head.
    """
    t = events["t"].astype(np.int64)
    out: np.ndarray | None = None
    for v, delay in enumerate(delays_us):
        windows = view_windows(t, deflarer.window_us, int(delay))
        batch = [(start, events[i:k]) for start, i, k in windows]
        spans = [(i, k) for _, i, k in windows]
        for lo in range(0, len(batch), 8):
            columns = deflarer.head_inputs(batch[lo : lo + 8], sensor_size)
            for (a, b), c in zip(spans[lo : lo + 8], columns, strict=True):
                if out is None:
                    out = np.empty((len(delays_us), events.size, c.shape[1]), np.float32)
                out[v, a:b] = c
    if out is None:
        raise EdeflareError("a recording without events has no rows to learn from")
    return out


@dataclasses.dataclass(frozen=True)
class LabelledRecording:
    """A real recording's head inputs ``(delays, n, columns)`` and region codes ``(n,)``."""

    name: str
    inputs: np.ndarray
    codes: np.ndarray

    def __post_init__(self) -> None:
        if self.inputs.ndim != 3 or self.inputs.shape[1] != self.codes.size:
            raise EdeflareError(
                f"{self.name}: inputs {self.inputs.shape} do not match {self.codes.size} codes"
            )
        if not (self.codes > 0).any():
            raise EdeflareError(f"{self.name}: no labelled event (its annotation scores none)")


@dataclasses.dataclass(frozen=True)
class TuningConfig:
    """How a head is fitted further (recorded in the run's summary)."""

    real_weight: float = 1.0
    """The real rows' total weight, times the simulated rows'."""
    per_region: int = 50_000
    """Rows drawn per labelled region and recording (over its windowings)."""
    hold_simulated: bool = False
    """On the simulated rows, learn each member's own keep probabilities before the fit
    instead of their labels (the labels still weigh the classes): the head keeps what it
    did on simulation and learns the real rows' labels."""
    balance_classes: bool = False
    """Give the real rows' keep class and flare class half of their weight each (each
    class's rows keep their shares within it), as the simulated rows' classes are."""
    validate_last: float = 0.0
    """The share of each real recording's span, at its end, left out of the fit and scored
    after it (0: none)."""
    thin: float = 1.0
    """The simulated training rows' rate augmentation (:attr:`HeadTrainingConfig.thin`)."""
    epochs: int = 3
    lr: float = 1e-3
    batch_size: int = 4_096
    seed: int = 0

    def __post_init__(self) -> None:
        check_thin(self.thin)
        v = self.validate_last
        if not (isinstance(v, (int, float)) and 0.0 <= v < 1.0):
            raise EdeflareError(f"validate_last must be in [0, 1), got {v!r}")
        for name in ("real_weight", "lr"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise EdeflareError(f"{name} must be a positive number, got {value!r}")
        for name in ("per_region", "epochs", "batch_size"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise EdeflareError(f"{name} must be a positive integer, got {v!r}")


def time_split(t: np.ndarray, last: float, gap_us: int) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the events to fit and to validate on: the last ``last`` share of the span
    of times ``t`` (sorted) is validated on, and the events less than ``gap_us`` before it
    are in neither.

    Examples
    --------
    The span of 0-90 µs is [0, 91): the cut at 91 - 0.3 * 91 = 63.7, the gap from 48.7.

    >>> fit, val = time_split(np.arange(0, 100, 10), 0.3, 15)
    >>> np.arange(0, 100, 10)[fit].tolist(), np.arange(0, 100, 10)[val].tolist()
    ([0, 10, 20, 30, 40], [70, 80, 90])
    """
    t = np.asarray(t, np.int64)
    if not t.size:
        return np.zeros(0, bool), np.zeros(0, bool)
    start, end = int(t[0]), int(t[-1]) + 1
    cut = end - last * (end - start)
    val = t >= cut
    return t < cut - gap_us, val


def validation_gap_us(window_us: int) -> int:
    """What :func:`tune_head` leaves out before a validated part: a window and the largest
    delay, so that no window of any windowing of :data:`DELAYS_US` holds events of both.

    >>> validation_gap_us(20_000)
    35000
    """
    return int(window_us) + max(DELAYS_US)


def recording_scores(
    inputs: np.ndarray,
    codes: np.ndarray,
    params: dict[str, Any],
    thresholds: Sequence[float],
    lit: bool,
) -> np.ndarray:
    """A recording's scores ``(thresholds, 4)`` from its events' head inputs ``(DELAYS_US,
    n, columns)`` and region codes, for the head ``params``: flare removed, light kept,
    scene kept and combined (the share kept where not ``lit``), each the mean of the four
    window phases of the score's protocol (:func:`~edeflare.eval.phases.measure_phases`)."""
    from ..eval.phases import measure_phases, phase_views

    # DELAYS_US are the windowings of four phases of 20 ms windows with a 5 ms second view
    _, views = phase_views(20_000, 5_000, len(DELAYS_US))
    logits = [head_logits(params, x) for x in inputs]
    phases = [(logits[a] + logits[b]) / np.float32(2) for a, b in views]
    regions = (codes == 2, codes == 1, codes == 3) if lit else None
    return measure_phases(phases, regions, thresholds)


def validation_scores(
    inputs: np.ndarray,
    codes: np.ndarray,
    params: dict[str, Any],
    keep_threshold: float,
    lit: bool,
) -> dict[str, float]:
    """:func:`recording_scores` at ``keep_threshold``, by name
    (:data:`~edeflare.eval.phases.TERMS`)."""
    from ..eval.phases import TERMS

    row = recording_scores(inputs, codes, params, [keep_threshold], lit)[0]
    return {name: float(v) for name, v in zip(TERMS, row, strict=True)}


def real_rows(
    recordings: Sequence[LabelledRecording], total_weight: float, config: TuningConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The drawn rows of ``recordings`` (in that order), their labels (True: keep) and
    weights summing to ``total_weight``: each recording alike, each labelled region alike.

    Examples
    --------
    >>> rec = LabelledRecording("r", np.zeros((2, 3, 1), np.float32),
    ...                         np.array([1, 2, 2], np.int8))
    >>> x, y, w = real_rows([rec], 6.0, TuningConfig())
    >>> x.shape, y.tolist(), np.round(w, 3).tolist()   # 2 windowings x 1 light, x 2 flare
    ((6, 1), [True, True, False, False, False, False], [1.5, 1.5, 0.75, 0.75, 0.75, 0.75])
    >>> light = LabelledRecording("l", np.zeros((1, 2, 1), np.float32), np.array([1, 1], np.int8))
    >>> _, y, w = real_rows([rec, light], 6.0, TuningConfig(balance_classes=True))
    >>> float(w[y].sum()), float(w[~y].sum())     # 3/4 of the weight kept, made even
    (3.0, 3.0)
    """
    rng = np.random.default_rng(config.seed)
    xs, ys, ws = [], [], []
    for rec in recordings:
        present = [c for c in (1, 2, 3) if (rec.codes == c).any()]
        views = rec.inputs.shape[0]
        for c in present:
            idx = np.flatnonzero(rec.codes == c)
            n = min(config.per_region, idx.size * views)
            pick = rng.choice(idx.size * views, n, replace=False)  # (windowing, event)
            xs.append(rec.inputs[pick // idx.size, idx[pick % idx.size]])
            ys.append(np.full(n, c != 2))
            share = total_weight / len(recordings) / len(present) / n
            ws.append(np.full(n, share, np.float32))
    x, y, w = np.concatenate(xs), np.concatenate(ys), np.concatenate(ws)
    if config.balance_classes and y.any() and not y.all():
        for c in (False, True):
            w[y == c] *= np.float32(total_weight / 2 / w[y == c].sum(dtype=np.float64))
    return x, y, w


def fit_members(
    head: EventHead | EventHeadEnsemble,
    sim_x: np.ndarray,
    sim_y: np.ndarray,
    recordings: Sequence[LabelledRecording],
    config: TuningConfig,
    *,
    progress: bool = False,
) -> EventHead | EventHeadEnsemble:
    """``head``'s perceptrons fitted further (in place) on the simulated rows ``sim_x``
    (every input column, the context's included) with labels ``sim_y`` and on the
    ``recordings``' rows (:func:`real_rows`, ``config.real_weight`` of the simulated
    rows' weight); the context networks and the standardisation are left as they are."""
    w_sim = loss_weights(np.asarray(sim_y, bool), HeadTrainingConfig()).numpy()
    if recordings:
        rx, ry, rw = real_rows(recordings, config.real_weight * float(w_sim.sum()), config)
        x = np.concatenate([np.asarray(sim_x, np.float32), rx])
        y, w = np.concatenate([np.asarray(sim_y, bool), ry]), np.concatenate([w_sim, rw])
    else:
        x, y, w = np.asarray(sim_x, np.float32), np.asarray(sim_y, bool), w_sim
    if x.shape[1] != head.columns:
        raise EdeflareError(f"rows have {x.shape[1]} columns, the head reads {head.columns}")
    xt, yt = torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(y.astype(np.float32))
    wt = torch.from_numpy(w)
    ensemble = isinstance(head, EventHeadEnsemble)
    members = list(head.members) if ensemble else [head]
    steps = config.epochs * -(-len(yt) // config.batch_size)
    for i, member in enumerate(members):
        torch.manual_seed(config.seed + i)
        cols = head._member_columns(xt, i) if ensemble else xt
        gen = torch.Generator().manual_seed(config.seed + i)
        target = yt
        if config.hold_simulated:  # its own keep probabilities on the simulated rows
            with torch.no_grad():
                own = torch.sigmoid(member(cols[: len(sim_y)]) + LN3)
            target = torch.cat([own, yt[len(sim_y) :]])

        def loss(b: torch.Tensor, member: EventHead = member, cols: torch.Tensor = cols,
                 target: torch.Tensor = target) -> torch.Tensor:  # fmt: skip
            return torch.nn.functional.binary_cross_entropy_with_logits(
                member(cols[b]) + LN3, target[b], weight=wt[b]
            )

        # only the perceptron learns: the context network is not run, so it has no gradient
        batches = shuffled_batches(len(yt), config.batch_size, config.epochs, gen)
        _optimise(member, HeadTrainingConfig(lr=config.lr), steps, batches, loss, progress)
    return head


def _recording_key(weights: str, name: str, events: np.ndarray, lights: Lights | None) -> str:
    h = hashlib.sha256()
    h.update(file_sha256(Path(weights)).encode())
    h.update(json.dumps([name, list(DELAYS_US)]).encode())
    h.update(np.ascontiguousarray(events).tobytes())
    if lights is not None:
        h.update(repr(lights).encode())
    return h.hexdigest()[:16]


def tune_head(
    weights: str | os.PathLike[str],
    data: Sequence[str | os.PathLike[str]],
    recordings: Sequence[tuple[str, np.ndarray, SensorSize, Lights | None]],
    run_dir: str | os.PathLike[str],
    config: TuningConfig | None = None,
    *,
    keep_threshold: float | None = None,
    command: str = "",
    progress: bool = True,
    workers: int = 1,
) -> dict[str, Any]:
    """Fit the keep head of ``weights`` further on ``data``'s simulated training pairs and
    the annotated ``recordings`` ``(name, events, sensor_size, lights or None)``; write
    ``run_dir/model.safetensors`` and ``run_dir/tune.json``; return that summary.

    The keep threshold is ``keep_threshold``, or, without it, chosen on the data's test
    splits as ``train-head`` chooses it (never on a real recording). The rows are cached
    in ``run_dir``: a rerun after a kill goes on from them; ``workers`` processes draw
    them (the same rows at any number).
    """
    from .head_training import _group, choose_threshold, collect_sets, context_columns
    from .infer import ModelDeflarer
    from .weights import load_model, save_model

    config = config or TuningConfig()
    base = Path(weights)
    model, card = load_model(base)
    head = getattr(model, "head", None)
    if not isinstance(head, (EventHead, EventHeadEnsemble)):
        raise EdeflareError(f"{weights}: no keep head to fit further (train one with train-head)")
    if card.unlit_model:
        raise EdeflareError(
            f"{weights}: two experts (unlit_model {card.unlit_model!r}); fit each one apart "
            "and pair them again with edeflare bundle --card unlit_model=..."
        )
    if keep_threshold is not None and not 0.0 < keep_threshold < 1.0:
        raise EdeflareError(f"keep_threshold must be in (0, 1), got {keep_threshold}")
    names = [name for name, *_ in recordings]
    if len(set(names)) != len(names):
        raise EdeflareError(f"recordings need distinct names, got {names}")
    for name, events, *_ in recordings:
        if events is None or events.size == 0:
            raise EdeflareError(f"{name}: the recording holds no events to learn from")
    run = Path(run_dir)
    run.mkdir(parents=True, exist_ok=True)
    folders = [part for d in data for part in dataset_folders(d)]
    collect = HeadTrainingConfig(
        features=tuple(head.feature_names),
        context=head.context["channels"] if head.context else 0,
        thin=config.thin,
    )
    sets, files_of, _ = collect_sets(
        folders, base, run, collect, progress=progress, workers=workers
    )
    train, val = sets["train"], sets["test"]
    columns = {
        split: context_columns(head, rows) if head.context else rows["x"]
        for split, rows in sets.items()
    }
    deflarer = ModelDeflarer(base, runtime="torch", batch_windows=8)
    labelled, held = [], {}
    gap_us = validation_gap_us(deflarer.window_us)
    before_params = head.numpy_params() if config.validate_last else None
    # in the order of their names, so that the draws do not hang on the order given
    for name, events, size, lights in sorted(recordings, key=lambda r: r[0]):
        path = run / f"real-{name}-{_recording_key(str(base), name, events, lights)}.npz"
        if path.is_file():
            with np.load(path) as z:
                inputs, codes = z["inputs"], z["codes"]
        else:
            inputs = recording_inputs(deflarer, events, size, DELAYS_US)
            codes = region_labels(events, size, lights)
            with atomic_path(path) as tmp:
                with open(tmp, "wb") as f:
                    np.savez(f, inputs=inputs, codes=codes)
        if config.validate_last:
            fitted, checked = time_split(events["t"], config.validate_last, gap_us)
            share = f"{100 * config.validate_last:g} %"
            if not (codes[checked] > 0).any():
                raise EdeflareError(f"{name}: no labelled event in the last {share} of its span")
            if not (codes[fitted] > 0).any():
                raise EdeflareError(
                    f"{name}: no labelled event to fit before the last {share} of its span "
                    f"and the {gap_us / 1000:g} ms before it (too short to split)"
                )
            before = validation_scores(inputs[:, checked], codes[checked], before_params,
                                       card.keep_threshold, lights is not None)  # fmt: skip
            held[name] = (inputs[:, checked], codes[checked], lights is not None, before)
            inputs, codes = inputs[:, fitted], codes[fitted]
        labelled.append(LabelledRecording(name, inputs, codes))
    fit_members(head, columns["train"], train["y"], labelled, config, progress=progress)
    params = head.numpy_params()
    groups = np.array([_group(files_of["test"], int(i)) for i in val["source"]])
    sim_threshold, table = choose_threshold(head_logits(params, columns["test"]), val["y"], groups)
    threshold = sim_threshold if keep_threshold is None else float(keep_threshold)
    card = dataclasses.replace(
        card,
        keep_threshold=threshold,
        # the base's own recipe first: the tuned model is rebuilt from it
        command=(card.command + " && " if card.command else "")
        + (command or f"tune_head({str(weights)!r}, {[str(d) for d in data]!r}, ...)"),
        data=(card.data + "; " if card.data else "")
        + "tuned on "
        + " ".join([*(str(d) for d in folders), *names]),
        metrics={"head_validation_score": max(r["score"] for r in table)},
        notes=(card.notes + "; " if card.notes else "")
        + f"its perceptrons fitted further on annotated real recordings ({', '.join(names)}), "
        + (
            "its keep threshold given"
            if keep_threshold is not None
            else "its keep threshold chosen on the simulated test splits"
        ),
    )
    save_model(run / "model.safetensors", model, card)
    summary = {
        "keep_threshold": threshold,
        "threshold_chosen_on": "given" if keep_threshold is not None else "the test splits",
        "simulated_threshold": sim_threshold,
        "threshold_table": table,
        "recordings": {
            r.name: {REGIONS[c]: int((r.codes == c).sum()) for c in range(len(REGIONS))}
            for r in labelled
        },
        "validation": {
            name: {
                "events": int(c.size),
                "before": before,
                "tuned": validation_scores(x, c, params, threshold, lit),
            }
            for name, (x, c, lit, before) in held.items()
        },
        "train_events": int(train["y"].size),
        "config": dataclasses.asdict(config),
        "base_weights": str(base),
        "base_sha256": file_sha256(base),
    }
    with atomic_path(run / "tune.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=1) + "\n")
    return summary
