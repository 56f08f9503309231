"""Speed of the dataset generator, and how close PNL-ES comes to the full forward model.

1. Throughput (``results/generate.json``): the first N sequences of ``eflare-2.7k``
   (640x480) and ``eflare-mini`` (346x260), synthetic backgrounds, generated
   with 2 workers into a temporary folder. Reports sequences/hour on the wall
   clock (pool start-up included) and per stage (background, render,
   simulate, compose, write): ``workers * 3600 / mean seconds of the stage per
   sequence``, i.e. the rate if that stage alone ran; and the projected time of
   the whole recipe. Target: all of ``eflare-2.7k`` within 3 hours here.
2. PNL-ES vs the full forward model (``results/generate_compare.json``): K
   synthetic ``eflare-mini`` sequences simulated with the forward model
   (events of I_bg + I_f and I_bg + I_light, Eq. 5-6) as the reference. On the
   same script, background and camera, each composition's input and ground
   truth are scored against the reference's with the paper's metrics
   (20 ms windows), plus the ratio of event counts: a second forward run with
   other sensor noise (the floor: physics against itself), PNL-ES with the
   true intensities, with the accumulation estimate of the background, with
   the authors' whole-window counts, the ``+random`` jitter and a plain merge.
   Also the mean absolute error of the estimated background keep probability
   against the true one.

Run: ``python benchmarks/bench_generate.py [--sequences 12] [--compare 8]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import tempfile
import time

import numpy as np
from _common import RESULTS, report

from edeflare.data.generate import (
    RECIPES,
    STAGES,
    draw_inputs,
    generate_dataset,
    generate_sequence,
)
from edeflare.eval.evaluate import evaluate_streams, summarize
from edeflare.eval.metrics import METRICS
from edeflare.sim.background import camera_simulator
from edeflare.sim.compose import (
    AccumulatedIntensity,
    Components,
    CountIntensity,
    compose_pair,
    forward_pair,
    fusion_weights,
)
from edeflare.sim.render import Renderer


def throughput(name: str, n: int, workers: int) -> dict[str, object]:
    recipe = dataclasses.replace(RECIPES[name], sequences=n, test_sequences=0)
    with tempfile.TemporaryDirectory() as tmp:
        rep = generate_dataset(recipe, tmp, workers=workers, progress=False)
        size_mb = sum(f["bytes"] for f in rep.manifest["files"]) / n / 2**20
        events = np.mean([sum(f["events"].values()) for f in rep.manifest["files"]])
    rate = n / rep.wall_seconds * 3600
    row: dict[str, object] = {
        "recipe": name,
        "size": "x".join(map(str, recipe.sensor_size)),
        "sequences": n,
        "workers": workers,
        "wall_s": rep.wall_seconds,
        "seq_per_hour": rate,
        "full_recipe_h": RECIPES[name].sequences / rate,  # the whole named recipe
        "MiB_per_seq": size_mb,
        "events_per_seq": float(events),
    }
    for stage in STAGES:
        mean = rep.stage_seconds[stage] / n
        row[f"{stage}_s"] = mean
        row[f"{stage}_seq_per_hour"] = workers * 3600 / mean if mean > 0 else math.inf
    return row


def second_forward(recipe, index: int) -> tuple[np.ndarray, np.ndarray]:
    """The forward model again, same script and background, other sensor noise."""
    inputs = draw_inputs(recipe, index)
    size, spec = recipe.sensor_size, inputs.script.sensor
    sims = [
        camera_simulator(spec, size, rng=np.random.default_rng([999, index, k])) for k in (0, 1)
    ]
    video = inputs.background.video
    frames = ((t, video(t), flare, light) for t, flare, light in Renderer(inputs.script, size))
    ob, gt = forward_pair(frames, *sims)
    d = recipe.duration_us
    return ob[ob["t"] < d], gt[gt["t"] < d]


def with_background(comp: Components, field) -> Components:
    """The same components with the background intensity taken from ``field``."""
    inten = {c: dict(v) for c, v in comp.intensity.items()}
    inten["background"] = {s: field.sample(comp.events[s]) for s in comp.events}
    return Components(comp.events, inten, comp.t_start_us, comp.t_end_us)


def bg_weight(comp: Components) -> np.ndarray:
    """Keep probability of each background event in the input fusion."""
    return fusion_weights(comp.samples(["background", "flare"])[0], 0)


def compare(k: int) -> list[dict[str, object]]:
    recipe = RECIPES["eflare-mini"].replace(variant="forward")
    size, d = recipe.sensor_size, recipe.duration_us
    scores: dict[tuple[str, str], list[dict[str, float]]] = {}
    weight_err: dict[str, list[float]] = {}
    for i in range(k):
        t0 = time.perf_counter()
        data = generate_sequence(recipe, i)
        ref = {"input": data.streams["input"], "gt": data.streams["gt"]}
        comp = data.components  # true intensities (rendered videos and the scene)
        ev = comp.events
        acc = with_background(comp, AccumulatedIntensity(ev["background"], size, 0, d))
        counts = Components.from_fields(ev, {s: CountIntensity(ev[s], size) for s in ev}, 0, d)
        w_true = bg_weight(comp)
        weight_err.setdefault("accumulation", []).append(
            float(np.abs(bg_weight(acc) - w_true).mean())
        )
        weight_err.setdefault("counts", []).append(float(np.abs(bg_weight(counts) - w_true).mean()))
        rng = lambda i=i: np.random.default_rng([7, i])  # noqa: E731
        methods = {
            "forward, 2nd sensor draw": second_forward(recipe, i),
            "PNL-ES, true intensities": compose_pair(comp, "physical", rng=rng()),
            "PNL-ES, accumulation": compose_pair(acc, "physical", rng=rng()),
            "PNL-ES, window counts": compose_pair(counts, "physical", rng=rng()),
            "PNL-ES + random (1 ms)": compose_pair(comp, "physical+random", rng=rng()),
            "simple merge": compose_pair(comp, "simple", rng=rng()),
            "simple + random (1 ms)": compose_pair(comp, "simple+random", rng=rng()),
        }
        for name, pair in methods.items():
            for side, events in zip(("input", "gt"), pair, strict=True):
                segments = evaluate_streams(ref[side], events, size, start_us=0, end_us=d)
                row = dict(summarize(m for _, m in segments).means)
                row["count_ratio"] = events.size / max(ref[side].size, 1)
                scores.setdefault((name, side), []).append(row)
        print(f"sequence {i}: {time.perf_counter() - t0:.1f} s", flush=True)
    rows = []
    for (name, side), per_seq in scores.items():
        row: dict[str, object] = {"method": name, "stream": side}
        for m in (*METRICS, "count_ratio"):
            vals = [r[m] for r in per_seq if not math.isnan(r[m])]
            row[m] = float(np.mean(vals)) if vals else math.nan
        rows.append(row)
    rows.sort(key=lambda r: r["stream"] != "input")  # stable: methods keep their order
    for key, vals in weight_err.items():
        print(f"mean |w_bg estimate - w_bg true| at background events, {key}: {np.mean(vals):.3f}")
    (RESULTS / "generate_weights.json").write_text(
        json.dumps({k: float(np.mean(v)) for k, v in weight_err.items()}, indent=2)
    )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sequences", type=int, default=12, help="eflare-2.7k sequences timed")
    parser.add_argument("--mini-sequences", type=int, default=24, help="eflare-mini sequences")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--compare", type=int, default=8, help="sequences for the comparison")
    parser.add_argument("--skip-throughput", action="store_true")
    args = parser.parse_args()
    if not args.skip_throughput:
        rows = [
            throughput("eflare-2.7k", args.sequences, args.workers),
            throughput("eflare-mini", args.mini_sequences, args.workers),
        ]
        columns = ["recipe", "size", "sequences", "workers", "seq_per_hour", "full_recipe_h"]
        columns += [f"{s}_seq_per_hour" for s in STAGES] + ["MiB_per_seq", "events_per_seq"]
        report("generate", rows, columns)
    if args.compare:
        rows = compare(args.compare)
        report("generate_compare", rows, ["method", "stream", *METRICS, "count_ratio"])


if __name__ == "__main__":
    main()
