"""`learned` on the night recording with the annotated lights handed to its light features.

The light test finds no light in any window of the night recording (light_free.py), so
every light feature of `learned`'s head holds its no-light value there. Here the test is
replaced, window by window, by the annotation (`benchmarks/night_recording_lights.json`:
the night light and three small lights, each a disc at the window's middle) and the head's
decisions compared with its decisions as they are: one windowing (aligned 20 ms windows),
the head at its card's threshold. An upper bound on what a light test that found these
lights would give this head without retraining; it chooses nothing.

Run: python experiments/light-test/oracle.py FAERY_DATA   (writes results/oracle.json and
oracle.png: 100 ms at 9.0 s, the input and the head's output both ways)

With ``WEIGHTS NAME`` after FAERY_DATA, another head's weights in place of `learned`'s
(results/oracle_NAME.json and oracle_NAME.png): python experiments/light-test/oracle.py
FAERY_DATA RUNS/LET/model.safetensors LET
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import edeflare.lights.cells as cells_module
from edeflare.eval.score import classify_events
from edeflare.io import read_events
from edeflare.lights import load_lights
from edeflare.models.event_head import head_logits
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.viz import event_frame, grid, save_image

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
CELL = 8
PICTURE = (9_000_000, 100_000)  # from the recording's start, µs: the reference picture's part
CROP = (slice(60, 620), slice(200, 960))
_given: dict = {}  # the window's annotated discs, set before each window


def _annotated_cells(events, sensor_size, window_us, *, cell=CELL):
    width, height = sensor_size
    out = np.zeros((-(-height // cell), -(-width // cell)), bool)
    for cx, cy, r in _given["discs"]:
        y0, y1 = max(int(cy - r) // cell, 0), min(int(cy + r) // cell + 1, out.shape[0])
        x0, x1 = max(int(cx - r) // cell, 0), min(int(cx + r) // cell + 1, out.shape[1])
        out[y0:y1, x0:x1] = True
    return out


def _annotated_found(events, sensor_size, window_us, cell, lights):
    width, height = sensor_size
    if lights is None:
        lights = _annotated_cells(events, sensor_size, window_us, cell=cell)
    found = []
    for cx, cy, r in _given["discs"]:
        ys = slice(max(int(cy - r), 0), min(int(np.ceil(cy + r)) + 1, height))
        xs = slice(max(int(cx - r), 0), min(int(np.ceil(cx + r)) + 1, width))
        yy, xx = np.mgrid[ys, xs]
        found.append((ys, xs, np.hypot(xx - cx, yy - cy) <= r, float(r)))
    at = cells_module._Coords(events, (width, height), cell) if found else None
    return lights, found, at


def decide(d: ModelDeflarer, events, size, lights, oracle: bool) -> np.ndarray:
    """Keep decisions of aligned windows, with the light test or the annotation."""
    threshold = float(np.log(d.card.keep_threshold / (1 - d.card.keep_threshold)))
    keep = np.zeros(events.size, bool)
    t, w = events["t"], d.window_us
    saved = cells_module.window_lights, cells_module._find_lights
    try:
        if oracle:
            cells_module.window_lights = _annotated_cells
            cells_module._find_lights = _annotated_found
        for s in range(int(t[0]) // w * w, int(t[-1]) + 1, w):
            lo, hi = np.searchsorted(t, [s, s + w])
            if hi == lo:
                continue
            mid = np.array([s + w / 2])
            discs = [tuple(float(v[0]) for v in src.at(mid)) for src in lights.sources]
            _given["discs"] = [c for c in discs if np.isfinite(c).all()]
            (x,) = d.head_inputs([(s, events[lo:hi])], size)
            keep[lo:hi] = head_logits(d.head_params, x) > threshold
    finally:
        cells_module.window_lights, cells_module._find_lights = saved
    return keep


def main() -> None:
    path = Path(sys.argv[1]) / "evt3.raw"
    events, size = read_events(path)
    lights = load_lights(ROOT / "benchmarks" / "night_recording_lights.json", size)
    regions = classify_events(events, lights, size)
    weights, name = (sys.argv[2], sys.argv[3]) if len(sys.argv) > 3 else (None, "learned")
    d = ModelDeflarer(weights or bundled_weights("learned"), runtime="torch")
    suffix = "" if weights is None else f"_{name}"
    rows, frames, captions = [], [], []
    t = events["t"]
    lo, hi = np.searchsorted(t, int(t[0]) + PICTURE[0] + np.array([0, PICTURE[1]]))
    frames.append(event_frame(events[lo:hi], size)[CROP])
    captions.append("input, 9.0-9.1 s")
    for oracle in (False, True):
        keep = decide(d, events, size, lights, oracle)
        frames.append(event_frame(events[lo:hi][keep[lo:hi]], size)[CROP])
        captions.append(f"{name}, " + ("the annotated lights" if oracle else "its light test"))
        row = {"light test": "the annotation" if oracle else "as is (none found)"}
        for r in ("halo", "ghost"):
            row[f"{r} removed"] = round(1 - float(keep[regions.mask(r)].mean()), 4)
        flare = regions.mask("halo") | regions.mask("ghost")
        removed = 1 - float(keep[flare].mean())
        kept = float(keep[regions.mask("light")].mean())
        row.update({"flare removed": round(removed, 4), "light kept": round(kept, 4),
                    "stars kept": round(float(keep[regions.mask("background")].mean()), 4),
                    "combined": round(2 * removed * kept / (removed + kept), 4)})  # fmt: skip
        rows.append(row)
        print(row, flush=True)
    out = HERE / "results" / f"oracle{suffix}.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=1) + "\n")
    save_image(HERE / f"oracle{suffix}.png", grid(frames, ncols=3, captions=captions))


if __name__ == "__main__":
    main()
