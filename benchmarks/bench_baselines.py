"""Speed of the classical baselines, and what their switches change.

1. Throughput (single thread) of every registered method called on a few
   million events (``method(events, sensor_size)``: validation, EFR's bias
   pass and final sort included), next to ``raw`` on the same stream.
   Targets: EFR >= 1 M ev/s, PFD-A >= 2 M ev/s, PFD-B >= 3 M ev/s (the
   original C++ programs, built with optimisation, do about 0.5, 1.25 and
   2.3 M ev/s on this machine). Two streams:

   - ``flare scene``: the procedural flare scene of ``edeflare.demo`` at
     640x480 (moving bar, a 100 Hz lamp and its flare halo, background
     activity), the kind of input the baselines are meant for;
   - ``uniform``: events uniform over 640x480 and 1 s, about 13 events per
     pixel and second. The worst case for EFR, whose queues cycle once per
     period between a pixel's events (work grows with time, not events).

2. Quirk switches of PFD (``flip_against_previous``, ``real_valued_score``):
   events kept on the flare scene, each alone and both.

3. EFR's warm-up and shift-back options: events out, the first output time,
   the delay, and the paper's metrics (20 ms segments) against the scene's
   flare-free ground truth (``edeflare.eval.evaluate``), next to the raw input,
   so that the effect of each option on the tables is known.

Run: ``python benchmarks/bench_baselines.py [--events 4000000] [--quick]``
"""

from __future__ import annotations

import argparse

import numba
import numpy as np
from _common import best_of, random_events, report

from edeflare.baselines.efr import EFRFilter
from edeflare.data.toy import toy_flare_pair
from edeflare.methods import create_method, list_methods

SIZE = (640, 480)
TARGETS = {"efr": 1.0, "pfd-a": 2.0, "pfd-b": 3.0}
ORIGINAL_CPP = {"efr": 0.5, "pfd-a": 1.25, "pfd-b": 2.3}


def flare_scene(n_events: int, seed: int = 0):
    """The demo's flare scene at 640x480, long enough for about ``n_events`` events."""
    duration = max(100_000, int(n_events / 0.86))  # about 0.86 events per µs
    return toy_flare_pair(SIZE, duration, rng=seed)


def throughput(streams: dict[str, np.ndarray], repeat: int) -> list[dict[str, object]]:
    rows = []
    raw = create_method("raw")
    for stream_name, events in streams.items():
        t_raw = best_of(lambda ev=events: raw(ev, SIZE), repeat)
        for name in list_methods():
            method = create_method(name)
            seconds = best_of(lambda m=method, ev=events: m(ev, SIZE, rng=0), repeat)
            rate = events.size / seconds / 1e6
            rows.append(
                {
                    "stream": stream_name,
                    "method": name,
                    "events": events.size,
                    "seconds": seconds,
                    "Mev_per_s": rate,
                    "x_raw_time": seconds / t_raw,
                    "target_Mev_s": TARGETS.get(name, ""),
                    "original_cpp_Mev_s": ORIGINAL_CPP.get(name, ""),
                    "meets_target": (rate >= TARGETS[name]) if name in TARGETS else "",
                }
            )
    return rows


def quirks(events: np.ndarray) -> list[dict[str, object]]:
    rows = []
    variants = [
        ("original (default)", {}),
        ("flip_against_previous", {"flip_against_previous": True}),
        ("real_valued_score", {"real_valued_score": True}),
        ("both", {"flip_against_previous": True, "real_valued_score": True}),
    ]
    for name in ("pfd-a", "pfd-b"):
        base = None
        for label, switches in variants:
            kept = create_method(name, **switches)(events, SIZE).size
            base = kept if base is None else base
            rows.append(
                {
                    "method": name,
                    "variant": label,
                    "events_in": events.size,
                    "kept": kept,
                    "kept_fraction": kept / events.size,
                    "vs_original": kept / base,
                }
            )
    return rows


def efr_options(observed: np.ndarray, clean: np.ndarray, metrics: bool) -> list[dict[str, object]]:
    rows = []
    variants = [
        ("raw input (reference)", None),
        ("warm-up kept (default)", {}),
        ("no warm-up", {"keep_warmup": False}),
        ("shift back", {"shift_back": True}),
        ("shift back + warm-up", {"shift_back": True, "keep_warmup": True}),
    ]
    delay = EFRFilter((1, 1), 50).delay_us
    for label, options in variants:
        method = create_method("raw") if options is None else create_method("efr", **options)
        out = method(observed, SIZE)
        first_in = int(observed["t"][0])
        row: dict[str, object] = {
            "variant": label,
            "events_in": observed.size,
            "events_out": out.size,
            "first_output_us": int(out["t"][0]) - first_in if out.size else "",
            "delay_us": delay if options is not None else "",
        }
        if metrics:
            from edeflare.eval.evaluate import evaluate_streams, summarize

            segments = evaluate_streams(clean, out, SIZE, workers=1)
            for k, v in summarize(m for _, m in segments).means.items():
                row[k] = v
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--events", type=int, default=4_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--quick", action="store_true", help="one repetition, no metrics (a smoke run)"
    )
    args = parser.parse_args()
    numba.set_num_threads(1)  # single thread: validation and voxel kernels are parallel
    repeat = 1 if args.quick else args.repeat
    scene = flare_scene(args.events)
    streams = {
        "flare scene": scene.observed,
        "uniform": random_events(args.events, SIZE, 0, 1_000_000),
    }
    columns = ["stream", "method", "events", "seconds", "Mev_per_s", "x_raw_time"]
    columns += ["target_Mev_s", "original_cpp_Mev_s", "meets_target"]
    report("baselines", throughput(streams, repeat), columns)
    print()
    cols = ["method", "variant", "events_in", "kept", "kept_fraction", "vs_original"]
    report("baselines_pfd_switches", quirks(scene.observed), cols)
    print()
    short = flare_scene(min(args.events, 1_000_000), seed=1)  # metrics are slower
    rows = efr_options(short.observed, short.clean, metrics=not args.quick)
    cols = ["variant", "events_in", "events_out", "first_output_us", "delay_us"]
    if not args.quick:
        cols += ["chamfer", "gaussian", "mse", "pmse_2", "pmse_4", "r_f1", "t_f1", "tp_f1"]
    report("baselines_efr_options", rows, cols)


if __name__ == "__main__":
    main()
