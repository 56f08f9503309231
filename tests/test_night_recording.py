"""benchmarks/night_recording.py: the annotation of a drifting night scene, by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import load_benchmark
from edeflare.events import make_events, sort_events


@pytest.fixture
def night_recording(monkeypatch):
    return load_benchmark(monkeypatch, "night_recording")


def _blob(rng, n, t0, span, cx, cy, r):
    """``n`` events uniform in time over ``span`` from ``t0``, in a disc of radius ``r``."""
    a, d = rng.uniform(0, 2 * np.pi, n), r * np.sqrt(rng.uniform(0, 1, n))
    x = np.clip(np.round(cx + d * np.cos(a)), 0, 1279).astype(int)
    y = np.clip(np.round(cy + d * np.sin(a)), 0, 719).astype(int)
    return make_events(t0 + rng.integers(0, span, n), x, y, rng.integers(0, 2, n), sort=True)


def test_the_lights_follow_a_drifting_anchor_at_the_panels_offsets(night_recording):
    rng = np.random.default_rng(0)
    panel = json.loads(night_recording.PANEL.read_text())["sources"]
    anchor0 = np.array(night_recording.ANCHOR_START)
    offsets = [np.array(s["circle"][:2]) - np.array(panel[1]["circle"][:2]) for s in panel]
    drift = np.array([-3.0, 4.0])  # pixels per 100 ms window: 30, 40 px over the second
    parts = []
    for k in range(10):
        centre = anchor0 + k * drift
        t0 = k * night_recording.WINDOW_US
        parts.append(_blob(rng, 3_000, t0, night_recording.WINDOW_US, *(centre + offsets[0]), 15))
        for off in offsets[1:]:
            parts.append(_blob(rng, 300, t0, night_recording.WINDOW_US, *(centre + off), 3))
    events = sort_events(np.concatenate(parts))
    lights, checks = night_recording.annotate(events, (1280, 720))
    assert checks["anchor_windows"] == "10 of 10"
    assert checks["anchor_drift_px"] == pytest.approx(list(9 * drift), abs=1.0)
    mid = np.array([4 * night_recording.WINDOW_US + night_recording.WINDOW_US // 2])
    for source, off, spec in zip(lights.sources, offsets, panel, strict=True):
        cx, cy, r = (float(v[0]) for v in source.at(mid))
        assert (cx, cy) == pytest.approx(tuple(anchor0 + 4 * drift + off), abs=1.5)
        assert r == spec["circle"][2]
    night = lights.sources[0]
    assert (night.halo_outer_px, night.ghost_radius_px) == (320.0, 140.0)
    assert not lights.score_background
    # the light discs hold the blobs (night light radius 18 > 15; small lights 5 > 3)
    assert checks["event_share"]["light"] > 0.99
