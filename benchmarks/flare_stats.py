"""Flare statistics, real against simulated, and the side-by-side figure.

Measures :func:`edeflare.eval.flare_stats.flare_statistics` on

- the annotated real recordings with lights (``../shared/data/real``, the
  annotations bundled in ``edeflare/assets/lights``; their first source),
- simulated datasets given as ``--sim NAME=FOLDER`` (sequence files of
  ``edeflare simulate``; the light source is the simulator's own ``light``
  stream, :func:`~edeflare.eval.flare_stats.lights_from_events`; the median
  over the folder's sequences is reported),

prints one table (a column per source), writes ``results/flare_stats.json`` (or
``--name``)
and, with ``--figure``, one picture: a 10 ms window of each, cropped to
``--crop`` pixels around the source at the same scale (one sensor pixel, one
picture pixel).

Run::

    python benchmarks/flare_stats.py --sim sim=/path/to/dataset/test \\
        --figure docs/figures/flare_real_vs_sim.png
"""

from __future__ import annotations

import argparse
import itertools
import math
from pathlib import Path

import numpy as np
from _common import REAL, report

from edeflare.eval.flare_stats import RING_EDGES, flare_statistics, lights_from_events
from edeflare.io import read_events
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.lights import bundled_lights, load_lights
from edeflare.viz import event_frame, grid, save_image

RECORDINGS = {  # file: short label of the figure
    "prophesee_gen3_rotating_light.raw": "real: Gen3 light",
    "davis346_flicker_lamps.aedat4": "real: DAVIS lamps",
}


def _rows(stats: dict[str, dict]) -> list[dict[str, object]]:
    names = list(stats)
    rings = [f"{a:g}-{b:g}" for a, b in itertools.pairwise(RING_EDGES)]
    rows: list[dict[str, object]] = []

    def add(label: str, get) -> None:
        rows.append({"statistic": label, **{n: get(stats[n]) for n in names}})

    add("radius (px)", lambda s: s["radius_px"])
    for i, ring in enumerate(rings):
        add(f"rate at {ring} r (light = 1)", lambda s, i=i: s["radial"][i])
    add("streak contrast (halo)", lambda s: s["streak_contrast"])
    for region in ("light", "halo", "background"):
        add(f"ON share, {region}", lambda s, region=region: s["on_fraction"][region])
    for region in ("light", "halo"):
        add(f"pixel interval, {region} (ms)", lambda s, region=region: s["interval_ms"][region])
    add("light rate (ev/px/s)", lambda s: s["light_rate"])
    add("halo rate (ev/px/s)", lambda s: s["halo_rate"])
    add("background rate (ev/px/s)", lambda s: s["background_rate"])
    add("ghost contrast", lambda s: s["ghost_contrast"])
    return rows


def _median(dicts: list[dict]) -> dict:
    """Element-wise median of equally shaped nested dicts / lists of numbers (None = NaN)."""
    first = dicts[0]
    if isinstance(first, dict):
        return {k: _median([d[k] for d in dicts]) for k in first}
    if isinstance(first, list):
        return [_median([d[i] for d in dicts]) for i in range(len(first))]
    values = [math.nan if v is None else float(v) for v in dicts]
    return float(np.nanmedian(values)) if not all(math.isnan(v) for v in values) else None


def _crop(events: np.ndarray, cx: float, cy: float, side: int, size) -> tuple[np.ndarray, tuple]:
    x0 = round(min(max(cx - side / 2, 0), max(size[0] - side, 0)))
    y0 = round(min(max(cy - side / 2, 0), max(size[1] - side, 0)))
    w, h = min(side, size[0]), min(side, size[1])
    x, y = events["x"], events["y"]
    sel = (x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)
    out = events[sel].copy()
    out["x"] -= x0
    out["y"] -= y0
    return out, (w, h)


def _window_image(events, lights, size, side: int, window_us: int = 10_000) -> np.ndarray:
    """A 10 ms window at the middle of the light's presence, cropped around the source."""
    t = events["t"]
    mid = int(t[0]) + (int(t[-1]) - int(t[0])) // 2
    win = events[(t >= mid) & (t < mid + window_us)]
    cx, cy, _ = lights.sources[0].at(np.array([mid + window_us // 2]))
    if not np.isfinite(cx[0]):
        cx, cy = np.array([size[0] / 2]), np.array([size[1] / 2])
    crop, crop_size = _crop(win, float(cx[0]), float(cy[0]), side, size)
    frame = event_frame(crop, crop_size)
    canvas = np.full((side, side, 3), 255, np.uint8)
    canvas[: frame.shape[0], : frame.shape[1]] = frame
    return canvas


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--real", type=Path, default=REAL)
    parser.add_argument("--sim", action="append", default=[], metavar="NAME=FOLDER")
    parser.add_argument("--figure", type=Path)
    parser.add_argument("--crop", type=int, default=240, help="figure: pixels around the source")
    parser.add_argument("--max-sequences", type=int, default=8)
    parser.add_argument(
        "--name", default="flare_stats", help="results/NAME.json (default flare_stats)"
    )
    args = parser.parse_args()
    stats: dict[str, dict] = {}
    images, labels = [], []
    for rec in RECORDINGS:
        path = args.real / rec
        if not path.is_file():
            print(f"skipped {rec}: not in {args.real}")
            continue
        recording = read_events(path)
        lights = load_lights(bundled_lights(rec), recording.sensor_size)
        name = rec.split(".")[0]
        stats[name] = flare_statistics(recording.events, lights, recording.sensor_size).to_dict()
        images.append(_window_image(recording.events, lights, recording.sensor_size, args.crop))
        labels.append(RECORDINGS[rec])
    for spec in args.sim:
        name, folder = spec.split("=", 1)
        per_sequence = []
        for k, seq in enumerate(list_sequences(folder)[: args.max_sequences]):
            light, size = read_dsec(seq, "light")
            if light.size == 0:
                continue
            events = read_dsec(seq, "input")[0]
            lights = lights_from_events(light)
            per_sequence.append(flare_statistics(events, lights, size).to_dict())
            if k == 0:
                images.append(_window_image(events, lights, size, args.crop))
                labels.append(f"sim: {name}")
        if per_sequence:
            stats[name] = _median(per_sequence)
    rows = _rows(stats)
    report(args.name, rows, ["statistic", *stats])
    if args.figure is not None and images:
        save_image(args.figure, grid(images, labels=labels, ncols=len(images)))
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
