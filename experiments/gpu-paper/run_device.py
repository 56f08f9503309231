"""One short GPU session: train ``unet3d.paper`` on simulated E-Flare-2.7K pairs, time it.

Run on a CUDA machine (16 cores) from the repository root, as the session's one device
call did (see README.md beside this file)::

    PYTHONPATH=.devsite:src python3 experiments/gpu-paper/run_device.py --out $OUT

Stages, each timed into ``results.json``:

1. the test suite's CUDA-only test (AMP resume), in the background;
2. the training data: ``eflare-2.7k`` sequences, PNL-ES (seed 0) and the full forward
   model (seed 1), 640x480, simulated on every core;
3. the network's speed on full 480x640 frames (random input), to size the schedule;
4. training: the paper's network and loss (MSE of 8-bin voxel grids) on full frames,
   mixed precision, Adam, the learning rate x0.2 for the last quarter, a time limit;
5. inference speed on the GPU: ``ModelDeflarer`` end to end (encode, network, decode)
   on 640x480 windows, this model and the bundled default, and the bare network in
   float32 and float16;
6. the weights in float16 (half the size; ``load_model`` casts them back) and the logs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

from edeflare.data.generate import RECIPES, generate_dataset
from edeflare.io.sequence import list_sequences
from edeflare.models import create_model
from edeflare.models.weights import load_model, save_model
from edeflare.train import TrainConfig, train

RESULTS: dict = {}
CUDA = torch.cuda.is_available()
DEVICE = "cuda" if CUDA else "cpu"  # the CPU path is for a smoke test of this script


def _sync() -> None:
    if CUDA:
        torch.cuda.synchronize()


def _stage(name: str, t0: float, **values: object) -> None:
    RESULTS[name] = {"seconds": round(time.perf_counter() - t0, 2), **values}
    print(f"[{name}] {RESULTS[name]}", flush=True)


def _save(out: Path) -> None:
    (out / "results.json").write_text(json.dumps(RESULTS, indent=2))


def _network_speed(preset: str, batch: int, shape: tuple[int, ...], steps: int) -> float:
    """Seconds per training iteration of ``preset`` on random grids (AMP, Adam)."""
    model = create_model(preset).to(DEVICE)
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)
    scaler = torch.amp.GradScaler(DEVICE, enabled=CUDA)
    x = torch.randn(batch, *shape, device=DEVICE)
    times = []
    for _ in range(steps):
        _sync()
        t = time.perf_counter()
        with torch.autocast(DEVICE, enabled=CUDA):
            loss = torch.nn.functional.mse_loss(model(x), x)
        opt.zero_grad(set_to_none=True)
        scaler.scale(loss).backward()
        scaler.step(opt)
        scaler.update()
        _sync()
        times.append(time.perf_counter() - t)
    del model, opt
    if CUDA:
        torch.cuda.empty_cache()
    return float(np.median(times[3:]))


def _forward_speed(model: torch.nn.Module, shape: tuple[int, ...], half: bool) -> float:
    x = torch.randn(1, *shape, device=DEVICE)
    with torch.inference_mode(), torch.autocast(DEVICE, enabled=half and CUDA):
        for _ in range(3):
            model(x)
        _sync()
        t = time.perf_counter()
        for _ in range(10):
            model(x)
        _sync()
    return (time.perf_counter() - t) / 10


def _deflare_speed(weights: str, path: Path) -> dict:
    """``edeflare.deflare`` with a model on one sequence, end to end (encode, network, decode)."""
    from edeflare.deflare import create_method
    from edeflare.io.dsec import read_dsec

    events, size = read_dsec(path, "input")
    method = create_method("model", weights=weights, device=DEVICE)
    method(events, size, rng=0)  # warm-up (cuDNN autotune, allocations)
    _sync()
    t = time.perf_counter()
    repeats = 3
    for _ in range(repeats):
        out = method(events, size, rng=0)
    _sync()
    seconds = (time.perf_counter() - t) / repeats
    span_s = (int(events["t"][-1]) - int(events["t"][0])) / 1e6
    return {
        "events": len(events),
        "events_out": len(out),
        "span_s": round(span_s, 4),
        "seconds": round(seconds, 4),
        "real_time_factor": round(seconds / span_s, 3),
        "windows_per_s": round(span_s / 0.02 / seconds, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--work", type=Path, default=Path("/tmp/gpu-paper"))
    parser.add_argument("--physical", type=int, default=96, help="PNL-ES training sequences")
    parser.add_argument("--forward", type=int, default=48, help="forward-model sequences")
    parser.add_argument("--val", type=int, default=8, help="PNL-ES validation sequences")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--train-s", type=float, default=270.0, help="training time to plan for")
    parser.add_argument(
        "--deadline-s", type=float, default=560.0, help="the whole script's wall-clock budget"
    )
    parser.add_argument("--preset", default="unet3d.paper")
    parser.add_argument("--skip-test", action="store_true")
    parser.add_argument("--sensor", default="640x480", help="WxH of the simulated sequences")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    torch.backends.cudnn.benchmark = True
    RESULTS["machine"] = {
        "gpu": torch.cuda.get_device_name(0) if CUDA else "none",
        "torch": torch.__version__,
        "cores": os.cpu_count(),
    }
    test = None
    if not args.skip_test:
        test = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pytest",
                "-q",
                "-p",
                "no:cacheprovider",
                "-o",
                "addopts=",
                "tests/test_train.py",
                "-k",
                "amp_resume",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )

    t0 = time.perf_counter()
    data = args.work / "data"
    width, height = (int(v) for v in args.sensor.split("x"))
    shape = (1, 8, height, width)  # the network's input: one signed channel, 8 bins
    base = RECIPES["eflare-2.7k"].replace(components=False, sensor_size=(width, height))
    physical = base.replace(sequences=args.physical + args.val, test_sequences=args.val)
    forward = base.replace(sequences=args.forward, test_sequences=0, variant="forward", seed=1)
    generate_dataset(physical, data / "physical", workers=args.workers, progress=False)
    generate_dataset(forward, data / "forward", workers=args.workers, progress=False)
    train_paths = list_sequences(data / "physical" / "train") + list_sequences(
        data / "forward" / "train"
    )
    val_paths = list_sequences(data / "physical" / "test")
    _stage("generate", t0, train_sequences=len(train_paths), val_sequences=len(val_paths))
    _save(args.out)

    t0 = time.perf_counter()
    s_per_it = _network_speed(args.preset, args.batch, shape, 8)
    windows = len(train_paths) * 5
    # what is left once the grids are encoded (about 0.06 s a window) and 70 s kept for the rest
    left = args.deadline_s - (time.perf_counter() - start) - 0.06 * windows - 70.0
    train_s = min(args.train_s, left)
    iterations = max(50, int(train_s / s_per_it))
    epoch_len = windows // args.batch
    decay_epoch = max(1, int(0.75 * iterations / epoch_len))
    _stage(
        "probe",
        t0,
        s_per_iteration=round(s_per_it, 4),
        train_s=round(train_s, 1),
        iterations=iterations,
        epoch_len=epoch_len,
        decay_epoch=decay_epoch,
    )
    _save(args.out)

    t0 = time.perf_counter()
    config = dataclasses.replace(
        TrainConfig(),
        preset=args.preset,
        iterations=iterations,
        batch_size=args.batch,
        lr=args.lr,
        milestones=(decay_epoch,),
        flip=True,
        polarity_flip=True,
        val_every=max(1, iterations // 2),
        val_windows=16,
        checkpoint_every=max(100, iterations // 4),
        precompute=True,
        data=f"eflare-2.7k 640x480: {args.physical} PNL-ES (seed 0) + {args.forward} forward "
        f"model (seed 1) sequences; validation {args.val} PNL-ES",
        time_limit_min=max(0.5, train_s + 30.0) / 60.0,
    )
    run = args.work / "run"
    final = train(
        config,
        train_paths,
        run,
        val_paths=val_paths,
        progress=False,
        command="experiments/gpu-paper/run_device.py " + " ".join(sys.argv[1:]),
    )
    _, card = load_model(final)
    log = (run / "train_log.csv").read_text().splitlines()
    _stage(
        "train",
        t0,
        iterations_done=card.metrics["iteration"],
        last_log=log[-1],
        val=(run / "val_log.csv").read_text() if (run / "val_log.csv").exists() else "",
    )
    for name in ("train_log.csv", "val_log.csv", "config.json"):
        if (run / name).exists():
            shutil.copy(run / name, args.out / name)
    model, card = load_model(final)
    save_model(args.out / "paper_fp16.safetensors", model.half(), card)
    if (run / "best.safetensors").exists():
        best, best_card = load_model(run / "best.safetensors")
        save_model(args.out / "paper_best_fp16.safetensors", best.half(), best_card)
    _save(args.out)

    t0 = time.perf_counter()
    speed: dict = {}
    probe_file = val_paths[0]
    for name, weights in (("paper", str(final)), ("night (default)", "night")):
        try:
            speed[name] = _deflare_speed(weights, probe_file)
        except Exception as exc:  # report and go on: the weights are already saved
            speed[name] = {"error": repr(exc)}
    net, _ = load_model(final, DEVICE)
    speed["network float32, s/window"] = round(_forward_speed(net, shape, False), 4)
    speed["network autocast float16, s/window"] = round(_forward_speed(net, shape, True), 4)
    _stage("inference", t0, **speed)
    if test is not None:
        try:
            output, _ = test.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            test.kill()
            output = "timed out"
        RESULTS["cuda_test"] = {"returncode": test.returncode, "tail": output[-1500:]}
    _save(args.out)
    print(json.dumps(RESULTS, indent=2))


if __name__ == "__main__":
    main()
