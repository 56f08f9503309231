"""The embedded demo: simulate a flare scene, de-flare it with every method, picture and score it.

:func:`run_demo` (``edeflare demo``) needs nothing but the installed
package: the physics-driven simulator makes the scene, the baselines and the
bundled E-DeflareNet de-flare it, and the paper's metrics score it.
:func:`synthetic_flare_scene` is a cheaper procedural scene (a moving bar, a
100 Hz lamp, a six-spike flare halo) used by benchmarks and tests.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from .errors import EdeflareError
from .events import EVENT_DTYPE, SensorSize, merge_events, slice_time
from .io import write_events
from .viz import event_frame, grid, save_animation, save_image, voxel_montage
from .voxel import encode

__all__ = ["DemoScene", "run_demo", "synthetic_flare_scene"]


@dataclass(frozen=True)
class DemoScene:
    """A paired sample: ``observed`` (with flare) and ``clean`` (without), same sensor."""

    observed: np.ndarray
    clean: np.ndarray
    sensor_size: SensorSize


def _events(t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    ev = np.empty(t.size, dtype=EVENT_DTYPE)
    ev["t"], ev["x"], ev["y"], ev["p"] = t, x, y, p
    return ev[np.argsort(ev["t"], kind="stable")]


def synthetic_flare_scene(
    sensor_size: SensorSize = (346, 260),
    duration_us: int = 200_000,
    rng: np.random.Generator | int | None = 0,
) -> DemoScene:
    """Procedural paired scene: moving bar + 100 Hz lamp (clean) and a flare halo (observed only).

    Examples
    --------
    >>> scene = synthetic_flare_scene(duration_us=40_000, rng=1)
    >>> len(scene.observed) > len(scene.clean) > 0
    True
    """
    rng = np.random.default_rng(rng)
    width, height = sensor_size
    parts_clean = []
    # Moving bar: a vertical edge pair crossing the sensor, ON at the leading edge.
    n_bar = duration_us // 8
    t = rng.integers(0, duration_us, n_bar)
    lead = (20 + t * (width - 60) / duration_us).astype(np.int64)
    edge = rng.integers(0, 2, n_bar)  # 0 leading (ON), 1 trailing (OFF)
    x = np.clip(lead - edge * 24 + rng.integers(-1, 2, n_bar), 0, width - 1)
    y = rng.integers(height // 2, height - 20, n_bar)
    parts_clean.append(_events(t, x, y, 1 - edge))
    # Flickering lamp (100 Hz brightness ripple of mains light): ON on rise, OFF on fall.
    cx, cy, radius = int(width * 0.7), int(height * 0.3), 6
    phase = (np.arange(duration_us) % 10_000) / 10_000
    rate = np.abs(np.sin(2 * np.pi * phase))
    n_lamp = duration_us // 4
    t_lamp = np.sort(rng.choice(duration_us, n_lamp, p=rate / rate.sum()))
    ang = rng.uniform(0, 2 * np.pi, n_lamp)
    r = radius * np.sqrt(rng.uniform(0, 1, n_lamp))
    x = np.clip(cx + r * np.cos(ang), 0, width - 1).astype(np.int64)
    y = np.clip(cy + r * np.sin(ang), 0, height - 1).astype(np.int64)
    p = (phase[t_lamp] < 0.5).astype(np.uint8)
    parts_clean.append(_events(t_lamp, x, y, p))
    # Flare: a large halo with streaks, flickering with the lamp (observed only).
    n_flare = duration_us // 2
    t_fl = np.sort(rng.choice(duration_us, n_flare, p=rate / rate.sum()))
    ang = rng.uniform(0, 2 * np.pi, n_flare)
    streak = rng.random(n_flare) < 0.4
    ang[streak] = rng.integers(0, 6, streak.sum()) * np.pi / 3 + rng.normal(0, 0.02, streak.sum())
    r = radius + rng.exponential(np.where(streak, 70.0, 25.0))
    x = np.rint(cx + r * np.cos(ang)).astype(np.int64)
    y = np.rint(cy + r * np.sin(ang)).astype(np.int64)
    keep = (x >= 0) & (x < width) & (y >= 0) & (y < height)
    p = (phase[t_fl] < 0.5).astype(np.uint8)
    flare = _events(t_fl[keep], x[keep], y[keep], p[keep])
    # Background activity shared by both streams.
    n_bg = duration_us // 40
    noise = _events(
        np.sort(rng.integers(0, duration_us, n_bg)),
        rng.integers(0, width, n_bg),
        rng.integers(0, height, n_bg),
        rng.integers(0, 2, n_bg),
    )
    clean = merge_events(*parts_clean, noise)
    return DemoScene(merge_events(clean, flare), clean, (width, height))


DEMO_SEED = 20261122
"""Dataset seed of the demo scene (its sequences are not in the bundled model's data)."""


def _demo_methods() -> dict[str, Any]:
    """Rows of the demo: the baselines, and the bundled model when the package ships one."""
    from .deflare import create_method
    from .models.infer import bundled_weights

    methods = {name: create_method(name) for name in ("raw", "voxel", "efr", "pfd-a", "pfd-b")}
    try:
        bundled_weights()
    except EdeflareError:
        return methods
    methods["E-DeflareNet"] = create_method("model")
    return methods


def run_demo(
    out_dir: str | os.PathLike[str] = "demo",
    *,
    rng: int = 0,
    progress: bool = True,
) -> dict[str, str]:
    """Simulate a flare scene, de-flare it with every method, and write pictures and metrics.

    The scene is one 100 ms sequence of the ``eflare-mini`` recipe (346x260,
    physics-driven flare over a synthetic night street) drawn with the dataset
    seed :data:`DEMO_SEED` and index ``rng``. Writes to ``out_dir``:
    ``input.h5`` / ``ground_truth.h5`` and one ``<method>.h5`` per method,
    ``comparison.png`` (rows: 20 ms windows; columns: input, each method,
    ground truth), ``comparison.gif``, ``voxels.png`` (the input's 8 bins),
    ``metrics.md`` / ``metrics.json`` (the paper's table over the scene's
    20 ms segments) and ``summary.json``. Returns artefact name -> path.
    """
    import dataclasses

    from .data.generate import RECIPES, generate_sequence
    from .eval.evaluate import evaluate_streams, summarize
    from .eval.tables import ResultsTable

    out = Path(out_dir)
    recipe = dataclasses.replace(RECIPES["eflare-mini"], seed=DEMO_SEED)
    seq = generate_sequence(recipe, int(rng) % recipe.sequences)
    size, start, end = seq.sensor_size, seq.t_start_us, seq.t_end_us
    inp, gt = seq.streams["input"], seq.streams["gt"]
    outputs: dict[str, np.ndarray] = {}
    for name, method in tqdm(
        _demo_methods().items(), desc="methods", leave=False, disable=None if progress else True
    ):
        outputs[name] = method(inp, size, rng=rng)
    write_events(out / "input.h5", inp, size)
    write_events(out / "ground_truth.h5", gt, size)
    for name, events in outputs.items():
        write_events(out / f"{name}.h5", events, size)
    window = recipe.window_us
    summaries = {}
    for name, events in outputs.items():
        segments = evaluate_streams(gt, events, size, window_us=window, start_us=start, end_us=end)
        summaries[name] = summarize(m for _, m in segments)
    table = ResultsTable({name: s.means for name, s in summaries.items()})
    columns = ["input (flare)", *[n for n in outputs if n != "raw"], "ground truth"]
    streams = [inp, *[outputs[n] for n in outputs if n != "raw"], gt]
    frames, cells, row_labels = [], [], []
    for k, w_start in enumerate(range(start, end, window)):
        row = [event_frame(slice_time(ev, w_start, w_start + window), size) for ev in streams]
        frames.append(grid(row, labels=columns))
        if k < 3:
            cells.extend(row)
            row_labels.append(
                f"{(w_start - start) // 1000}-{(w_start - start + window) // 1000} ms"
            )
    paths = {
        "comparison": out / "comparison.png",
        "animation": out / "comparison.gif",
        "voxels": out / "voxels.png",
        "metrics": out / "metrics.md",
    }
    save_image(paths["comparison"], grid(cells, labels=columns, row_labels=row_labels))
    save_animation(paths["animation"], frames, fps=4)
    first = slice_time(inp, start, start + window)
    save_image(paths["voxels"], voxel_montage(encode(first, size, start, window), ncols=4))
    (out / "metrics.md").write_text(table.to_markdown())
    (out / "metrics.json").write_text(table.to_json())
    summary = {
        "scene": {
            "recipe": recipe.name,
            "seed": DEMO_SEED,
            "index": seq.index,
            "sensor_size": list(size),
            "span_us": [start, end],
        },
        "events": {
            "input": int(inp.size),
            "ground_truth": int(gt.size),
            **{n: int(e.size) for n, e in outputs.items()},
        },
        **{k: str(v) for k, v in paths.items()},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return {k: str(v) for k, v in paths.items()}
