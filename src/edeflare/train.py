"""Training E-DeflareNet: one CPU, one GPU, or many through ``torchrun`` (DDP).

The loop is iteration-based with the paper's optimiser (Adam, lr 2e-4,
weight decay 1e-5), MSE on voxel grids, and a step schedule (x0.2 at epochs
10/20/30; an epoch is one pass over the training windows). Everything a
sample depends on is derived from ``(seed, epoch, position)``: which windows
form a global batch, and each window's crop and flips. Hence

- ``torchrun --nproc_per_node N`` with per-process batch ``b`` trains the
  same model (up to float summation order) as one process with batch ``N*b``;
- a run killed at any moment resumes from its last checkpoint exactly as if
  it had never stopped (the logs are cut back to the checkpoint, so no row
  is lost or duplicated).

Checkpoints hold tensors and numbers only and are loaded with
``torch.load(weights_only=True)``; final weights are safetensors with a
model card (:mod:`edeflare.models.weights`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
from torch import nn
from torch.nn.parallel import DistributedDataParallel

from ._progress import progress_bar
from ._registry import Registry
from .data.folders import sequence_files
from .data.pairs import PairedWindows
from .errors import EdeflareError
from .io._atomic import atomic_path
from .models import create_model, get_preset
from .models.flaremask import FlareMaskNet
from .models.infer import resolve_weights
from .models.mask_loss import keep_loss
from .models.weights import ModelCard, init_from, save_model

__all__ = ["LOSSES", "TRAIN_PRESETS", "TrainConfig", "train"]

LOSSES = ("mse", "keep")


@dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (saved as ``config.json`` beside it).

    Examples
    --------
    >>> cfg = TrainConfig.from_dict({"preset": "unet2d.lite", "iterations": 10})
    >>> cfg.iterations, cfg.lr
    (10, 0.0002)
    """

    preset: str = "unet3d.paper"
    iterations: int = 40_000
    batch_size: int = 2  # per process
    lr: float = 2e-4
    weight_decay: float = 1e-5
    milestones: tuple[int, ...] = (10, 20, 30)  # epochs
    gamma: float = 0.2
    window_us: int = 20_000
    bins: int = 8
    crop: tuple[int, int] | None = None  # (height, width) random crops
    flip: bool = False
    time_shift: bool = False  # shift windows by whole bins: no learning where in a window
    polarity_flip: bool = False  # swap ON and OFF in half the windows
    seed: int = 0
    log_every: int = 10
    val_every: int = 1000
    val_windows: int = 8
    checkpoint_every: int = 500
    amp: bool = True  # mixed precision, on CUDA only
    num_workers: int = 0
    precompute: bool = False  # encode every training window once, keep int16 grids in memory
    device: str = "auto"
    data: str = ""  # description of the training data, for the model card
    loss: str = "mse"  # "mse" of the voxel grids, or "keep": per-event decisions (mask presets)
    keep_weight: float = 0.5  # loss "keep": the share of the loss on the events to keep
    keep_cells: str = "bin"  # loss "keep": match counts per bin, or per pixel over the window
    init: str | None = None  # weights to start from (a path or a bundled name): fine-tuning
    freeze_init: bool = False  # with init: train only the layers the preset adds to it
    time_limit_min: float | None = None  # stop (checkpointed, resumable) after this many minutes

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        """Build from a dict (e.g. ``config.json``), rejecting unknown keys."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise EdeflareError(f"unknown training options {unknown}; known: {sorted(known)}")
        data = dict(data)
        for key in ("milestones", "crop"):
            if data.get(key) is not None:
                data[key] = tuple(int(v) for v in data[key])
        return cls(**data)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        return dataclasses.asdict(self)

    def lr_at(self, iteration: int, epoch_len: int) -> float:
        """Learning rate at ``iteration`` (MultiStepLR over epochs, without state)."""
        epoch = iteration // max(1, epoch_len)
        return self.lr * self.gamma ** sum(epoch >= m for m in self.milestones)


# Options that do not change what is learned up to a given iteration: a resumed run may change them.
_FREE_ON_RESUME = frozenset(
    {
        "iterations",
        "log_every",
        "val_every",
        "val_windows",
        "checkpoint_every",
        "num_workers",
        "precompute",
        "device",
        "data",
        "time_limit_min",
    }
)

TRAIN_PRESETS: Registry[TrainConfig] = Registry("training preset")
TRAIN_PRESETS.register("paper", TrainConfig())
TRAIN_PRESETS.register(
    "cpu",
    TrainConfig(
        preset="unet2d.lite",
        iterations=3000,
        batch_size=8,
        lr=1e-3,
        milestones=(),
        crop=(128, 128),
        flip=True,
        val_every=500,
        checkpoint_every=250,
    ),
)
"""``paper``: Appendix D's configuration; ``cpu``: a light preset for 2-core machines."""


@dataclass
class _Dist:
    world: int = 1
    rank: int = 0
    local_rank: int = 0

    @property
    def main(self) -> bool:
        return self.rank == 0


class _WithLoss(nn.Module):
    """A model and its training loss as one module: ``forward(x, y)`` is the loss."""

    def __init__(
        self, model: nn.Module, loss: str, keep_weight: float = 0.5, keep_cells: str = "bin"
    ) -> None:
        super().__init__()
        self.model = model
        self.loss = loss
        self.keep_weight = keep_weight
        self.keep_cells = keep_cells

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        if self.loss == "keep":
            return keep_loss(self.model, x, y, self.keep_weight, self.keep_cells)  # type: ignore[arg-type]
        return nn.functional.mse_loss(self.model(x), y)


def _dist_env() -> _Dist:
    env = _Dist(
        int(os.environ.get("WORLD_SIZE", "1")),
        int(os.environ.get("RANK", "0")),
        int(os.environ.get("LOCAL_RANK", "0")),
    )
    if env.world > 1 and not dist.is_initialized():
        if torch.cuda.is_available():  # one GPU per process, set before NCCL starts
            torch.cuda.set_device(env.local_rank)
        dist.init_process_group(backend="nccl" if torch.cuda.is_available() else "gloo")
    return env


def _device(config: TrainConfig, env: _Dist) -> torch.device:
    if config.device != "auto":
        return torch.device(config.device)
    if torch.cuda.is_available():
        return torch.device("cuda", env.local_rank)
    return torch.device("cpu")


def _batches(
    n_items: int, config: TrainConfig, env: _Dist, start: int
) -> Iterator[tuple[int, list[tuple[int, int]]]]:
    """``(iteration, [(index, epoch), ...])`` of this rank from iteration ``start`` on."""
    global_batch = config.batch_size * env.world
    epoch_len = n_items // global_batch
    perm_epoch, perm = -1, np.empty(0, dtype=np.int64)
    for it in range(start, config.iterations):
        epoch, k = divmod(it, epoch_len)
        if epoch != perm_epoch:
            perm = np.random.default_rng((config.seed, epoch)).permutation(n_items)
            perm_epoch = epoch
        chunk = perm[k * global_batch : (k + 1) * global_batch]
        mine = chunk[env.rank * config.batch_size : (env.rank + 1) * config.batch_size]
        yield it, [(int(i), epoch) for i in mine]


def _stack(pairs: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[torch.Tensor, torch.Tensor]:
    xs, ys = zip(*pairs, strict=True)
    return torch.from_numpy(np.stack(xs)), torch.from_numpy(np.stack(ys))


class _BatchPlan:
    """The batches of this rank from ``start`` on, as a DataLoader ``batch_sampler``."""

    def __init__(self, n_items: int, config: TrainConfig, env: _Dist, start: int) -> None:
        self.args = (n_items, config, env, start)
        self.length = max(0, config.iterations - start)

    def __iter__(self) -> Iterator[list[tuple[int, int]]]:
        return (items for _, items in _batches(*self.args))

    def __len__(self) -> int:
        return self.length


def _loader(dataset: PairedWindows, config: TrainConfig, env: _Dist, start: int) -> Iterator:
    """Yield ``(iteration, (x, y))``; with workers, windows are read in background processes."""
    plan = _BatchPlan(len(dataset), config, env, start)
    if config.num_workers > 0:
        batches = torch.utils.data.DataLoader(
            dataset,
            batch_sampler=plan,
            num_workers=config.num_workers,
            collate_fn=_stack,
            persistent_workers=False,
        )
    else:
        batches = (_stack([dataset[item] for item in items]) for items in plan)
    return zip(range(start, config.iterations), batches, strict=False)


def _complete_lines(path: Path) -> str:
    """The file's text up to its last newline: a line torn by a kill is dropped."""
    with open(path, newline="") as f:
        text = f.read()
    return text[: text.rfind("\n") + 1]


def _truncate_csv(path: Path, iteration: int) -> None:
    """Keep the header and the rows up to ``iteration`` (a resumed run rewrites the rest).

    A torn last line (the process was killed while appending it) and any row
    whose width differs from the header's are dropped.
    """
    if not path.exists():
        return
    rows = list(csv.reader(io.StringIO(_complete_lines(path))))
    width = len(rows[0]) if rows else 0
    kept = rows[:1] + [
        r for r in rows[1:] if len(r) == width and r[0].isdigit() and int(r[0]) <= iteration
    ]
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        csv.writer(f).writerows(kept)


def _append_csv(path: Path, header: Sequence[str], row: Sequence[object]) -> None:
    """Append one row (and the header to a new file) in one ``write``, after whole lines only.

    A kill can tear at most the line being written; the next append (or the
    resume's :func:`_truncate_csv`) starts after the last complete line.
    """
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    if not path.exists() or path.stat().st_size == 0:
        writer.writerow(header)
    else:
        with open(path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            torn = f.read(1) != b"\n"
        if torn:
            with atomic_path(path) as tmp:
                tmp.write_text(_complete_lines(path), newline="")
    writer.writerow(row)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        os.write(fd, buf.getvalue().encode())
    finally:
        os.close(fd)


def _save_checkpoint(
    path: Path,
    model: torch.nn.Module,
    opt: torch.optim.Optimizer,
    iteration: int,
    config: TrainConfig,
    best_val_mse: float,
    seconds: float,
    scaler: torch.amp.GradScaler | None = None,
) -> None:
    state = {
        "model": model.state_dict(),
        "optimizer": opt.state_dict(),
        # AMP's loss scale and its growth tracker: a resumed GPU run continues them exactly.
        "scaler": scaler.state_dict() if scaler is not None else {},
        "iteration": iteration,
        "config": json.dumps(config.to_dict()),
        "torch_rng": torch.get_rng_state(),
        "best_val_mse": best_val_mse,  # so a resumed run keeps best.safetensors' meaning
        "seconds": seconds,  # training time so far, continued by train_log.csv
    }
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def _validate(
    model: torch.nn.Module, dataset: PairedWindows, config: TrainConfig, device: torch.device
) -> dict[str, float]:
    """Voxel MSE of the model and of the identity on evenly spaced windows, plus event metrics.

    Events are decoded with the ``keep`` decoder, as ``edeflare deflare`` does by default.
    """
    from .eval.metrics import segment_metrics
    from .voxel import decode_keep

    n = len(dataset)
    picks = np.unique(np.linspace(0, n - 1, min(n, config.val_windows)).round().astype(int))
    sums = {"val_mse": 0.0, "input_mse": 0.0, "chamfer": 0.0, "r_f1": 0.0}
    defined = 0
    model.eval()
    with torch.no_grad():
        for i in picks:
            x, y = dataset.grids(int(i))
            out = model(torch.from_numpy(x)[None, None].to(device))[0, 0].float().cpu().numpy()
            sums["val_mse"] += float(np.mean((out - y) ** 2))
            sums["input_mse"] += float(np.mean((x - y) ** 2))
            ref = dataset.windows[int(i)]
            gt = dataset.target_events(int(i))
            pred = decode_keep(
                out, dataset.input_events(int(i)), ref.start_us, config.window_us, rng=int(i)
            )
            m = segment_metrics(
                gt,
                pred,
                ref.sensor_size or dataset.sensor_size,
                ref.start_us,
                config.window_us,
                bins=config.bins,
            )
            sums["r_f1"] += m.r_f1
            if not math.isnan(m.chamfer):
                sums["chamfer"] += m.chamfer
                defined += 1
    model.train()
    result = {k: v / len(picks) for k, v in sums.items() if k != "chamfer"}
    result["chamfer"] = sums["chamfer"] / defined if defined else math.nan
    return result


def train(
    config: TrainConfig,
    train_paths: Sequence[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    *,
    val_paths: Sequence[str | os.PathLike[str]] | None = None,
    command: str = "",
    progress: bool = True,
) -> Path:
    """Train (or resume) a model; return the path of the final ``model.safetensors``.

    ``train_paths`` and ``val_paths`` hold sequence files or folders: a dataset
    folder stands for its ``train/`` files in ``train_paths`` and its ``test/``
    files in ``val_paths``, a mix folder (``eflare-mix``) for its parts' in the
    mix's order, any other folder for the files in it
    (:func:`edeflare.data.folders.sequence_files`).

    ``out_dir`` receives ``config.json``, ``checkpoint.pt`` (latest, atomic),
    ``train_log.csv``, ``val_log.csv``, ``best.safetensors`` (lowest
    validation MSE) and ``model.safetensors`` (last iteration). If
    ``checkpoint.pt`` exists the run resumes from it; the configuration must
    then equal the saved one.
    """
    get_preset(config.preset)
    if config.loss not in LOSSES:
        raise EdeflareError(f"unknown loss {config.loss!r}; known: {list(LOSSES)}")
    if not 0.0 < config.keep_weight < 1.0:
        raise EdeflareError(f"keep_weight must be in (0, 1), got {config.keep_weight}")
    if config.keep_cells not in ("bin", "window"):
        raise EdeflareError(f"keep_cells must be 'bin' or 'window', got {config.keep_cells!r}")
    if config.loss == "keep" and not isinstance(create_model(config.preset), FlareMaskNet):
        raise EdeflareError(f"loss 'keep' trains mask presets (mask.*), not {config.preset!r}")
    train_paths = sequence_files(train_paths, "train")
    val_paths = sequence_files(val_paths, "test") if val_paths else val_paths
    env = _dist_env()
    device = _device(config, env)
    out = Path(out_dir)
    torch.manual_seed(config.seed)
    train_set = PairedWindows(
        train_paths,
        window_us=config.window_us,
        bins=config.bins,
        crop=config.crop,
        flip=config.flip,
        time_shift=config.time_shift,
        polarity_flip=config.polarity_flip,
        seed=config.seed,
        precompute=config.precompute,
    )
    if len(train_set.sizes) > 1 and config.crop is None:
        sizes = ", ".join(f"{w}x{h}" for w, h in train_set.sizes)
        raise EdeflareError(
            f"the training sequences have several sensor sizes ({sizes}): give a crop no "
            f"larger than {train_set.sensor_size[1]}x{train_set.sensor_size[0]} (--crop HxW)"
        )
    val_set = (
        PairedWindows(val_paths, window_us=config.window_us, bins=config.bins)
        if val_paths
        else None
    )
    global_batch = config.batch_size * env.world
    if len(train_set) < global_batch:
        raise EdeflareError(
            f"{len(train_set)} training windows are fewer than one global batch ({global_batch})"
        )
    epoch_len = len(train_set) // global_batch
    model = create_model(config.preset).to(device)
    if config.freeze_init and config.init is None:
        raise EdeflareError("freeze_init needs init (the weights to start from and keep)")
    if config.init is not None:
        # a resumed run loads its checkpoint below; the init only says which layers are new
        fresh = init_from(model, resolve_weights(config.init))
        if env.main and fresh and not (out / "checkpoint.pt").exists():
            print(f"started from {config.init}; new: {', '.join(fresh)}", file=sys.stderr)
        if config.freeze_init:
            if not fresh:
                raise EdeflareError(
                    f"freeze_init: {config.init} holds every layer of {config.preset}; "
                    "nothing would be trained"
                )
            for name, param in model.named_parameters():
                param.requires_grad_(name in fresh)
    trained = [p for p in model.parameters() if p.requires_grad]
    opt = torch.optim.Adam(trained, lr=config.lr, weight_decay=config.weight_decay)
    ckpt_path = out / "checkpoint.pt"
    start = 0
    best, elapsed = math.inf, 0.0
    scaler_state: dict[str, Any] = {}
    if env.main:
        out.mkdir(parents=True, exist_ok=True)
    if ckpt_path.exists():
        state = torch.load(ckpt_path, map_location=device, weights_only=True)
        saved = TrainConfig.from_dict(json.loads(state["config"]))
        changed = sorted(
            k
            for k, v in saved.to_dict().items()
            if k not in _FREE_ON_RESUME and v != getattr(config, k)
        )
        if changed:
            raise EdeflareError(
                f"{ckpt_path}: was written with other values of {changed}; "
                "use a new output folder (only the iteration count and logging may change)"
            )
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"].cpu())  # map_location moved it
        start = int(state["iteration"])
        best = float(state.get("best_val_mse", math.inf))
        elapsed = float(state.get("seconds", 0.0))
        scaler_state = state.get("scaler") or {}
    if env.main:
        with atomic_path(out / "config.json") as tmp:
            tmp.write_text(json.dumps(config.to_dict(), indent=2))
        for name in ("train_log.csv", "val_log.csv"):
            _truncate_csv(out / name, start)
    # The loss is computed inside the module that DDP wraps, so that its gradients are synced.
    net: nn.Module = _WithLoss(model, config.loss, config.keep_weight, config.keep_cells)
    if env.world > 1:
        net = DistributedDataParallel(
            net, device_ids=[device.index] if device.type == "cuda" else None
        )
    use_amp = config.amp and device.type == "cuda"
    scaler = torch.amp.GradScaler("cuda", enabled=use_amp)
    if use_amp and scaler_state:  # empty when the checkpoint comes from a run without AMP
        scaler.load_state_dict(scaler_state)
    model.train()
    t0 = time.perf_counter() - elapsed
    # wall-clock budget of this process (a resumed run gets a fresh one)
    deadline = (
        time.perf_counter() + 60.0 * config.time_limit_min
        if config.time_limit_min is not None
        else math.inf
    )
    stopped_at: int | None = None
    bar = progress_bar(
        total=config.iterations, initial=start, unit="it", enabled=progress and env.main
    )
    for it, batch in _loader(train_set, config, env, start):
        lr = config.lr_at(it, epoch_len)
        for group in opt.param_groups:
            group["lr"] = lr
        x, y = (t.to(device, non_blocking=True) for t in batch)
        with torch.autocast(device_type=device.type, enabled=use_amp):
            loss = net(x, y)
        opt.zero_grad(set_to_none=True)
        scaler.scale(loss).backward()
        scaler.step(opt)
        scaler.update()
        done = it + 1
        bar.update(1)
        if env.main and (done % config.log_every == 0 or done == config.iterations):
            bar.set_postfix(loss=f"{loss.item():.4g}", lr=f"{lr:.2g}")
            _append_csv(
                out / "train_log.csv",
                ["iteration", "epoch", "lr", "loss", "seconds"],
                [done, it // epoch_len, lr, loss.item(), round(time.perf_counter() - t0, 3)],
            )
        if (
            val_set is not None
            and env.main
            and (done % config.val_every == 0 or done == config.iterations)
        ):
            scores = _validate(model, val_set, config, device)
            _append_csv(out / "val_log.csv", ["iteration", *scores], [done, *scores.values()])
            if scores["val_mse"] < best:
                best = scores["val_mse"]
                save_model(out / "best.safetensors", model, _card(config, command, scores, done))
        out_of_time = done < config.iterations and _past(deadline, env)
        if done % config.checkpoint_every == 0 or done == config.iterations or out_of_time:
            if env.main:
                _save_checkpoint(
                    ckpt_path, model, opt, done, config, best, time.perf_counter() - t0, scaler
                )
            if env.world > 1:
                dist.barrier()
        if out_of_time:
            stopped_at = done
            break
    bar.close()
    final = out / "model.safetensors"
    if env.main:
        save_model(final, model, _card(config, command, {}, stopped_at or config.iterations))
        if stopped_at is not None:
            print(
                f"time limit of {config.time_limit_min:g} min reached at iteration {stopped_at} "
                f"of {config.iterations}; {final.name} holds that iteration's weights, and "
                "rerunning the same command resumes from the checkpoint",
                file=sys.stderr,
            )
    if env.world > 1:
        dist.barrier()
    return final


def _past(deadline: float, env: _Dist) -> bool:
    """Whether the time budget is spent; under DDP rank 0's clock decides for every rank."""
    if math.isinf(deadline):
        return False
    over = time.perf_counter() >= deadline
    if env.world > 1:
        on_gpu = dist.get_backend() == "nccl"
        flag = torch.tensor([float(over)], device="cuda" if on_gpu else "cpu")
        dist.broadcast(flag, src=0)
        over = bool(flag.item())
    return over


def _card(
    config: TrainConfig, command: str, metrics: dict[str, float], iteration: int
) -> ModelCard:
    return ModelCard(
        preset=config.preset,
        bins=config.bins,
        window_us=config.window_us,
        command=command,
        data=config.data,
        seed=config.seed,
        metrics={
            **{k: (None if math.isnan(v) else v) for k, v in metrics.items()},
            "iteration": iteration,
        },
        notes=json.dumps(config.to_dict()),
    )
