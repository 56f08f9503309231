"""A toy paired sample for examples, tests and speed benchmarks (no simulator needed).

:func:`toy_flare_pair` draws a procedural pair in milliseconds: a moving bar
and a 100 Hz lamp (the clean stream) and a six-spike flare halo flickering
with the lamp (in the observed stream only), over shared background activity.
For physics-driven pairs use :func:`edeflare.sim.pair.simulate_pair` or a
recipe (:mod:`edeflare.data.generate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..events import EVENT_DTYPE, SensorSize, merge_events

__all__ = ["ToyPair", "toy_flare_pair"]


@dataclass(frozen=True)
class ToyPair:
    """A paired sample: ``observed`` (with flare) and ``clean`` (without), same sensor."""

    observed: np.ndarray
    clean: np.ndarray
    sensor_size: SensorSize


def _events(t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    ev = np.empty(t.size, dtype=EVENT_DTYPE)
    ev["t"], ev["x"], ev["y"], ev["p"] = t, x, y, p
    return ev[np.argsort(ev["t"], kind="stable")]


def toy_flare_pair(
    sensor_size: SensorSize = (346, 260),
    duration_us: int = 200_000,
    rng: np.random.Generator | int | None = 0,
) -> ToyPair:
    """Procedural paired scene: moving bar + 100 Hz lamp (clean) and a flare halo (observed only).

    Examples
    --------
    >>> scene = toy_flare_pair(duration_us=40_000, rng=1)
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
    return ToyPair(merge_events(clean, flare), clean, (width, height))
