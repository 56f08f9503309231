"""Train the reconstructor on simulated street clips, resumably, on CPU.

A fixed pool of clips (:func:`edeflare.recon.clips.draw_clip`, half night,
half day, seeded by ``seed`` and the clip's index) is simulated once; each
iteration takes a batch of clips (random flips), runs the network through
the clip's windows from a zero state, and minimises the L1 error of the
images and of their spatial gradients after a burn-in of two windows (the
first windows have seen too few events to know the scene). A checkpoint
(``checkpoint.pt``, read back with ``torch.load(weights_only=True)``) is
written every ``checkpoint_every`` iterations; rerunning the same command
resumes from it, and a larger ``iterations`` continues training.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch

from .._progress import progress_bar
from ..errors import EdeflareError
from ..io._atomic import atomic_path
from ..train import _append_csv, _truncate_csv
from .clips import BURN_IN, draw_clip
from .network import FireNet
from .weights import ReconCard, save_reconstructor

__all__ = ["ReconTrainConfig", "held_out_error", "train_reconstructor"]

HELD_OUT = ((10_001, False), (10_002, True), (10_003, False))
"""Seeds and day/night of the held-out clips (far from the pool's seed sequences)."""


@dataclass(frozen=True)
class ReconTrainConfig:
    """Settings of a reconstructor training run (all but ``iterations`` fixed on resume)."""

    iterations: int = 2500
    batch_size: int = 4
    clips: int = 256
    windows: int = 10
    width: int = 128
    height: int = 96
    window_us: int = 20_000
    bins: int = 5
    features: int = 16
    lr: float = 1e-3
    gradient_weight: float = 0.5
    seed: int = 0
    checkpoint_every: int = 100


def _clip_pool(config: ReconTrainConfig, progress: bool) -> tuple[torch.Tensor, torch.Tensor]:
    voxels, images = [], []
    seeds = np.random.SeedSequence(config.seed).spawn(config.clips)
    for k in progress_bar(range(config.clips), enabled=progress, desc="simulating clips"):
        clip = draw_clip(
            (config.width, config.height),
            config.windows,
            window_us=config.window_us,
            bins=config.bins,
            day=k % 2 == 1,
            rng=np.random.default_rng(seeds[k]),
        )
        voxels.append(clip.voxels)
        images.append(clip.images)
    return torch.from_numpy(np.stack(voxels)), torch.from_numpy(np.stack(images))


def _gradients(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    return x[..., 1:, :] - x[..., :-1, :], x[..., :, 1:] - x[..., :, :-1]


def clip_loss(
    model: FireNet, voxels: torch.Tensor, images: torch.Tensor, gradient_weight: float = 1.0
) -> torch.Tensor:
    """Mean loss of a batch of clips: ``voxels (N, T, bins, H, W)``, ``images (N, T, 1, H, W)``."""
    state = None
    total = voxels.new_zeros(())
    steps = 0
    for t in range(voxels.shape[1]):
        pred, state = model(voxels[:, t], state)
        if t < BURN_IN:
            continue
        target = images[:, t]
        loss = (pred - target).abs().mean()
        if gradient_weight:
            for a, b in zip(_gradients(pred), _gradients(target), strict=True):
                loss = loss + gradient_weight * (a - b).abs().mean()
        total = total + loss
        steps += 1
    return total / max(steps, 1)


def held_out_error(model: FireNet, size: tuple[int, int] = (160, 120)) -> dict[str, float]:
    """Mean absolute error on held-out clips (:data:`HELD_OUT`, 8 windows, burn-in excluded).

    Returns ``{"held_out_l1", "flat_gray_l1", "ratio"}``: the network's error,
    that of a flat gray image (0.5, the centred images' mean), and their ratio
    (below 1: better than knowing nothing).
    """
    errors, flat = [], []
    model.eval()
    for seed, day in HELD_OUT:
        clip = draw_clip(size, 8, day=day, rng=seed)
        state = None
        with torch.no_grad():
            for t in range(clip.voxels.shape[0]):
                image, state = model(torch.from_numpy(clip.voxels[t : t + 1]), state)
                if t >= BURN_IN:
                    target = clip.images[t, 0]
                    errors.append(float(np.abs(image[0, 0].numpy() - target).mean()))
                    flat.append(float(np.abs(0.5 - target).mean()))
    l1, gray = float(np.mean(errors)), float(np.mean(flat))
    return {"held_out_l1": l1, "flat_gray_l1": gray, "ratio": l1 / gray}


def train_reconstructor(
    out: str | Path, config: ReconTrainConfig | None = None, *, progress: bool = True
) -> Path:
    """Train (or resume) in ``out``; write ``out/model.safetensors``. Returns its path."""
    config = config or ReconTrainConfig()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(config.seed)
    model = FireNet(config.bins, config.features)
    opt = torch.optim.Adam(model.parameters(), lr=config.lr)
    ckpt = out / "checkpoint.pt"
    start, elapsed = 0, 0.0
    if ckpt.exists():
        state = torch.load(ckpt, weights_only=True)
        saved = json.loads(state["config"])
        now = asdict(config)
        changed = sorted(
            k for k in saved.keys() | now.keys() if k != "iterations" and saved.get(k) != now.get(k)
        )
        if changed:
            raise EdeflareError(f"{ckpt}: written with other values of {changed}; use a new folder")
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"])
        start, elapsed = int(state["iteration"]), float(state["seconds"])
    _truncate_csv(out / "train_log.csv", start)
    with atomic_path(out / "config.json") as tmp:
        tmp.write_text(json.dumps(asdict(config), indent=2))
    voxels, images = _clip_pool(config, progress)
    # A schedule that depends on the iteration only: a resumed run draws the same batches.
    schedule = np.random.default_rng(config.seed + 1)
    plan = [
        schedule.choice(config.clips, config.batch_size, replace=False)
        for _ in range(config.iterations)
    ]
    flips = np.random.default_rng(config.seed + 2).integers(0, 4, size=config.iterations)
    model.train()
    t0 = time.perf_counter()
    bar = progress_bar(range(start, config.iterations), enabled=progress, desc="training")
    for it in bar:
        idx = torch.from_numpy(plan[it])
        v, im = voxels[idx], images[idx]
        if flips[it] & 1:
            v, im = v.flip(-1), im.flip(-1)
        if flips[it] & 2:
            v, im = v.flip(-2), im.flip(-2)
        lr = config.lr * 0.5 * (1 + math.cos(math.pi * it / config.iterations))
        for group in opt.param_groups:
            group["lr"] = lr
        loss = clip_loss(model, v, im, config.gradient_weight)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        seconds = elapsed + time.perf_counter() - t0
        _append_csv(
            out / "train_log.csv",
            ["iteration", "loss", "lr", "seconds"],
            [it + 1, f"{loss.item():.6f}", f"{lr:.3e}", f"{seconds:.1f}"],
        )
        bar.set_postfix(loss=f"{loss.item():.4f}")
        if (it + 1) % config.checkpoint_every == 0 or it + 1 == config.iterations:
            with atomic_path(ckpt) as tmp:
                torch.save(
                    {
                        "model": model.state_dict(),
                        "optimizer": opt.state_dict(),
                        "iteration": it + 1,
                        "config": json.dumps(asdict(config)),
                        "torch_rng": torch.get_rng_state(),
                        "seconds": seconds,
                    },
                    tmp,
                )
    card = ReconCard(
        bins=config.bins,
        features=config.features,
        window_us=config.window_us,
        iterations=config.iterations,
        command="edeflare.recon.train.train_reconstructor",
        data=json.dumps(asdict(config)),
        seed=config.seed,
    )
    path = out / "model.safetensors"
    save_reconstructor(path, model.eval(), card)
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m edeflare.recon.train OUT [--iterations N] [--seed S]`` (resumes in OUT).

    The card of ``OUT/model.safetensors`` then holds the command and the
    held-out score (:func:`held_out_error`): ``edeflare bundle`` copies it as
    it is.
    """
    import argparse
    import shlex
    import sys

    from .weights import load_reconstructor

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out")
    for f, default in asdict(ReconTrainConfig()).items():
        parser.add_argument(f"--{f.replace('_', '-')}", type=type(default), default=default)
    words = sys.argv[1:] if argv is None else argv
    args = vars(parser.parse_args(words))
    out = args.pop("out")
    path = train_reconstructor(out, ReconTrainConfig(**args))
    model, card = load_reconstructor(path)
    command = " ".join(["python -m edeflare.recon.train", *map(shlex.quote, words)])
    card = replace(
        card,
        command=f"{command} (edeflare.recon.train.train_reconstructor)",
        metrics={**card.metrics, **held_out_error(model)},
    )
    save_reconstructor(path, model, card)
    print(path)
    print(json.dumps(card.metrics))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
