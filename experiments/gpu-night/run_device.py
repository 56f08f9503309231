"""One short GPU session: voxel networks trained on the default's calibrated data.

Both voxel networks of this project failed on the real recordings. Both were trained on
the uncalibrated simulator's PNL-ES pairs (`eflare`, `paper`), while the default mask
model, which works on them, was trained on the calibrated night + day mix. This run
trains two voxel networks (they thin inside a pixel, which no keep/drop mask can) on
that same mix, so that the CPU can then tell data from architecture:

- ``unet2d.lite`` (`eflare`'s network, 146 k parameters: the speed target's reference);
- ``unet3d.paper`` (the paper's network, 7.07 M parameters).

Run on a CUDA machine (16 cores) from the repository root::

    PYTHONPATH=/tmp/site:src python3 experiments/gpu-night/run_device.py --out $OUT

Stages, each timed into ``results.json``:

1. the data: ``eflare-night`` (180 sequences, seed 0) and the day mix
   (``experiments/day-mix/gen_day.py``'s recipe, 72 sequences, seed 101), on every core;
2. the two trainings at once on the one GPU (``edeflare train``, full 346x260 frames,
   MSE of the 8-bin grids against the keep-only targets, flips and polarity swaps,
   mixed precision, a constant learning rate), each stopped by ``--time-limit`` before the deadline;
3. the weights (the paper's in float16) and the logs into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import torch

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES
from edeflare.models.weights import load_model, save_model

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "day-mix"))
from gen_day import DAY_SCENE  # the street lit as by day

RESULTS: dict = {}
RUNS = {
    # name: (preset, batch, lr)
    "lite": ("unet2d.lite", 16, 1e-3),
    "paper": ("unet3d.paper", 8, 3e-4),
}


def _stage(name: str, t0: float, out: Path, **values: object) -> None:
    RESULTS[name] = {"seconds": round(time.perf_counter() - t0, 2), **values}
    print(f"[{name}] {RESULTS[name]}", flush=True)
    (out / "results.json").write_text(json.dumps(RESULTS, indent=2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--work", type=Path, default=Path("/tmp/gpu-night"))
    parser.add_argument("--night", type=int, default=180)
    parser.add_argument("--day", type=int, default=72)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--deadline-s", type=float, default=520.0)
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--runs", default="lite,paper")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    RESULTS["machine"] = {
        "gpu": torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none",
        "torch": torch.__version__,
        "cores": os.cpu_count(),
    }

    t0 = time.perf_counter()
    night = RECIPES["eflare-night"].replace(
        sequences=args.night, test_sequences=min(12, args.night - 1)
    )
    day = RECIPES["eflare-night"].replace(
        name="eflare-day-mix",
        sequences=args.day,
        test_sequences=min(6, args.day - 1),
        scene=DAY_SCENE,
        seed=101,
    )
    generate_dataset(night, args.work / "NIGHT", workers=args.workers, progress=False)
    generate_dataset(day, args.work / "DAY", workers=args.workers, progress=False)
    mix = args.work / "MIX"
    for split in ("train", "test"):
        (mix / split).mkdir(parents=True, exist_ok=True)
        for part in ("NIGHT", "DAY"):
            for f in sorted((args.work / part / split).glob("seq_*.h5")):
                link = mix / split / f"{part.lower()}_{f.name}"
                if not link.exists():
                    link.symlink_to(f)
    _stage(
        "generate",
        t0,
        args.out,
        train=len(list((mix / "train").iterdir())),
        test=len(list((mix / "test").iterdir())),
    )

    t0 = time.perf_counter()
    # what is left, with 45 s kept for saving; each run also encodes its windows first
    minutes = max(0.5, (args.deadline_s - (time.perf_counter() - start) - 75.0) / 60.0)
    procs = {}
    for name in args.runs.split(","):
        preset, batch, lr = RUNS[name]
        cmd = [
            sys.executable, "-m", "edeflare", "train", str(mix),
            "--out", str(args.work / name), "--config", "cpu", "--preset", preset,
            "--crop", "260x346",
            "--loss", "mse", "--iterations", "100000", "--batch-size", str(batch),
            "--lr", str(lr), "--polarity-flip", "--precompute", "--device", args.device,
            "--val-every", "1000", "--checkpoint-every", "500",
            "--time-limit", f"{minutes:.2f}",
        ]  # fmt: skip
        log = open(args.out / f"{name}_log.txt", "w")  # closed below
        procs[name] = (subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT), log)
    codes = {}
    for name, (proc, log) in procs.items():
        codes[name] = proc.wait()
        log.close()
    _stage("train", t0, args.out, minutes=round(minutes, 2), returncodes=codes)

    t0 = time.perf_counter()
    saved = {}
    for name in procs:
        run = args.work / name
        weights = run / "model.safetensors"
        if not weights.exists():
            saved[name] = "no model.safetensors"
            continue
        model, card = load_model(weights)
        save_model(
            args.out / f"{name}.safetensors", model.half() if name == "paper" else model, card
        )
        saved[name] = card.metrics
        for csv in ("train_log.csv", "val_log.csv"):
            if (run / csv).exists():
                (args.out / f"{name}_{csv}").write_text((run / csv).read_text())
    _stage("save", t0, args.out, saved=saved)


if __name__ == "__main__":
    main()
