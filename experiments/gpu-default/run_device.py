"""The default model on a GPU, once: CUDA against CPU decisions, speed, the test suite.

Run on a CUDA machine from the repository root (see README.md beside this file)::

    python3 experiments/gpu-default/run_device.py --out $OUT [--sim DIR] [--real DIR]

Stages, each timed into ``results.json`` (written after every stage, so a run killed
at its limit still leaves what it finished):

1. the real recordings (``--real``): the bundled default ``night`` (priors on, as
   ``edeflare deflare`` runs it) on the CPU and on CUDA; which events each keeps, how
   many decisions differ, the best of ``--repeat`` timings of each, and the annotated
   recordings' scores from the CUDA output;
2. simulated recordings at the sensor sizes (``--sim``: event files, the ``input``
   group of one ``eflare-night`` test sequence per size): the same timings, plus CUDA
   with every prior off (what the network and the per-event features cost alone);
3. the bare networks (``paper`` on a 640x480 grid, ``night`` on 1280x720 features) on
   CUDA with cuDNN's default TF32 and in full precision (``_full_precision``): time and
   the largest difference from the CPU's output;
4. a profile of the densest case on CUDA (``profile.txt``: the 25 costliest calls).

The CPU path runs this script's smoke test on a machine without a GPU.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import json
import os
import pstats
import sys
import time
from pathlib import Path

import numpy as np
import torch

from edeflare.deflare import create_method
from edeflare.eval.score import load_lights, score_events
from edeflare.events import event_keys, make_events
from edeflare.io import read_events
from edeflare.models.flaremask import event_features
from edeflare.models.infer import _full_precision, bundled_weights
from edeflare.models.weights import load_model

RESULTS: dict = {}
CUDA = torch.cuda.is_available()
LIGHTS = Path("src/edeflare/assets/lights")
PRIORS_OFF = {"halo_shift": 0.0, "ghost_shift": 0.0, "streak_shift": 0.0, "light_free_shift": 0.0}


def _sync() -> None:
    if CUDA:
        torch.cuda.synchronize()


def _save(out: Path) -> None:
    (out / "results.json").write_text(json.dumps(RESULTS, indent=2))


def _timed(method, events, size, repeat):
    """The method's output and its best wall time over ``repeat`` calls (after one warm-up)."""
    out = method(events, size)
    best = float("inf")
    for _ in range(repeat):
        _sync()
        t0 = time.perf_counter()
        out = method(events, size)
        _sync()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _compare(events, size, repeat, devices, **params):
    """Per device: events kept, seconds, real-time factor; and the decisions that differ."""
    span_s = max(float(events["t"][-1] - events["t"][0]) * 1e-6, 1e-9)
    row: dict = {"events": int(events.size), "span_s": round(span_s, 4)}
    outs = {}
    for dev in devices:
        method = create_method("model", device=dev, **params)
        out, sec = _timed(method, events, size, repeat)
        outs[dev] = out
        row[dev] = {
            "kept": int(out.size),
            "seconds": round(sec, 4),
            "real_time_factor": round(sec / span_s, 3),
            "M_events_per_s": round(events.size / sec * 1e-6, 2),
        }
    if len(outs) == 2:
        a, b = (np.unique(event_keys(o, size)) for o in outs.values())
        row["decisions_differ"] = int(np.setxor1d(a, b, assume_unique=True).size)
    return row, outs


def stage_real(real: Path, repeat: int, devices: list[str]) -> None:
    t0 = time.perf_counter()
    rows = {}
    for path in sorted(real.iterdir()):
        if path.suffix not in (".raw", ".aedat4"):
            continue
        rec = read_events(path)
        row, outs = _compare(rec.events, rec.sensor_size, repeat, devices)
        annotation = LIGHTS / (path.stem + ".json")
        if annotation.exists():
            lights = load_lights(annotation, rec.sensor_size)
            scores = score_events(rec.events, outs, lights, rec.sensor_size)
            row["score"] = {
                s.method: [round(s.flare_removed, 4), round(s.light_kept, 4), round(s.combined, 4)]
                for s in scores
            }
        rows[path.name] = row
        print(f"[real] {path.name} {row}", flush=True)
    RESULTS["real"] = {"seconds": round(time.perf_counter() - t0, 1), "rows": rows}


def stage_sim(sims: list[Path], repeat: int, devices: list[str]) -> None:
    t0 = time.perf_counter()
    rows = {}
    for path in sims:
        rec = read_events(path)
        row, _ = _compare(rec.events, rec.sensor_size, repeat, devices)
        off, _ = _compare(rec.events, rec.sensor_size, repeat, devices[-1:], **PRIORS_OFF)
        row["priors_off_" + devices[-1]] = off[devices[-1]]
        rows[path.name] = row
        print(f"[sim] {path.name} {row}", flush=True)
    RESULTS["sim"] = {"seconds": round(time.perf_counter() - t0, 1), "rows": rows}


def _network_input(name: str, model, rng) -> tuple[torch.Tensor, object]:
    """One window's input and the call that runs it: a grid (voxel) or features (mask)."""
    if name.startswith("paper"):
        return torch.from_numpy(rng.random((1, 1, 8, 480, 640), dtype=np.float32)), model
    n = 1_000_000
    t = np.sort(rng.integers(0, 20_000, n))
    ev = make_events(t, rng.integers(0, 1280, n), rng.integers(0, 720, n), rng.integers(0, 2, n))
    x = event_features(ev, (1280, 720), 0, 20_000, model.bins, model.scale)
    return torch.from_numpy(np.ascontiguousarray(x[None])), model.logits


def stage_network(repeat: int, device: str) -> None:
    """The bare networks on one window: with cuDNN's default (TF32) and in full precision."""
    t0 = time.perf_counter()
    dev = torch.device(device)
    rows = {}
    rng = np.random.default_rng(0)
    for name in ("paper 640x480", "night 1280x720"):
        model, _ = load_model(bundled_weights(name.split()[0]))
        x, run = _network_input(name, model.eval(), rng)
        with torch.inference_mode():
            y_cpu = run(x).numpy()
        model.to(dev)
        x = x.to(dev)
        for mode in ("tf32", "full"):
            ctx = _full_precision(dev) if mode == "full" else contextlib.nullcontext()
            with torch.inference_mode(), ctx:
                run(x)
                best = float("inf")
                for _ in range(repeat + 2):
                    _sync()
                    t1 = time.perf_counter()
                    y = run(x)
                    _sync()
                    best = min(best, time.perf_counter() - t1)
            rows[f"{name} {mode} s"] = round(best, 5)
            rows[f"{name} {mode} max |dev - cpu|"] = float(np.abs(y.cpu().numpy() - y_cpu).max())
    RESULTS["network"] = {"seconds": round(time.perf_counter() - t0, 1), **rows}
    print(f"[network] {RESULTS['network']}", flush=True)


def stage_profile(out: Path, events, size, device: str) -> None:
    method = create_method("model", device=device)
    method(events, size)  # warm-up: compilation, the network on the device
    prof = cProfile.Profile()
    prof.enable()
    method(events, size)
    prof.disable()
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats("cumulative").print_stats(25)
    (out / "profile.txt").write_text(text.getvalue())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--real", type=Path, default=None)
    parser.add_argument("--sim", type=Path, nargs="*", default=[])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--smoke", action="store_true", help="the network stage on the CPU too")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    devices = ["cpu", "cuda"] if CUDA else ["cpu"]
    RESULTS["machine"] = {
        "gpu": torch.cuda.get_device_name() if CUDA else None,
        "torch": torch.__version__,
        "cores": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "python": sys.version.split()[0],
    }
    print(RESULTS["machine"], flush=True)
    if args.real:
        stage_real(args.real, args.repeat, devices)
        _save(args.out)
    if args.sim:
        stage_sim(args.sim, args.repeat, devices)
        _save(args.out)
    if CUDA or args.smoke:
        stage_network(args.repeat, devices[-1])
        _save(args.out)
    if args.real and (args.real / "prophesee_gen41_street.raw").exists():
        rec = read_events(args.real / "prophesee_gen41_street.raw")
        stage_profile(args.out, rec.events, rec.sensor_size, devices[-1])
    _save(args.out)


if __name__ == "__main__":
    main()
