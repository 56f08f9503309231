"""The embedded demo: a small synthetic flare scene, written, read back, encoded and pictured.

Until the physics-driven simulator lands, the scene is procedural: a bar
moving across a dark street (the real signal), a mains-powered lamp
flickering at 100 Hz (the light source, kept in the ground truth) and a
flare halo around it whose events appear only in the observation, plus
background activity. The demo exercises every layer the project has:
formats, windows, the voxel codec and the pictures.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .events import EVENT_DTYPE, SensorSize, iter_time_windows, merge_events, slice_time
from .io import read_events, write_events
from .viz import event_frame, grid, save_animation, save_image, voxel_montage
from .voxel import decode, encode

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


def run_demo(out_dir: str | os.PathLike[str] = "demo", *, rng: int = 0) -> dict[str, str]:
    """Write the demo to ``out_dir``: event files, a comparison PNG, a GIF, a voxel montage.

    Returns a mapping from artefact name to path (also written as ``summary.json``).
    """
    out = Path(out_dir)
    scene = synthetic_flare_scene(rng=rng)
    size = scene.sensor_size
    paths = {
        "observed": out / "observed.h5",
        "clean": out / "clean.h5",
        "comparison": out / "comparison.png",
        "animation": out / "comparison.gif",
        "voxels": out / "voxels.png",
    }
    write_events(paths["observed"], scene.observed, size)
    write_events(paths["clean"], scene.clean, size)
    observed, _ = read_events(paths["observed"])
    clean, _ = read_events(paths["clean"])
    window = 20_000
    frames, cells = [], []
    for (start, w_obs), (_, w_clean) in zip(
        iter_time_windows(observed, window, start_us=0, end_us=200_000),
        iter_time_windows(clean, window, start_us=0, end_us=200_000),
        strict=True,
    ):
        voxel = encode(w_obs, size, start, window)
        roundtrip = decode(voxel, start, window, rng=rng)
        row = [event_frame(w, size) for w in (w_obs, roundtrip, w_clean)]
        frames.append(grid(row, labels=["observed (flare)", "voxel round trip", "ground truth"]))
        if len(cells) < 9:
            cells.extend(row)
    save_image(
        paths["comparison"],
        grid(
            cells,
            labels=["observed (flare)", "voxel round trip", "ground truth"],
            row_labels=[f"{k * 20}-{k * 20 + 20} ms" for k in range(3)],
        ),
    )
    save_animation(paths["animation"], frames, fps=5)
    first = slice_time(observed, 0, window)
    save_image(paths["voxels"], voxel_montage(encode(first, size, 0, window), ncols=4))
    summary = {
        "observed_events": int(observed.size),
        "clean_events": int(clean.size),
        "flare_fraction": round(1 - clean.size / observed.size, 4),
        **{k: str(v) for k, v in paths.items()},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return {k: str(v) for k, v in paths.items()}
