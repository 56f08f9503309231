"""The no-reference flare score on synthetic sources, halos and streaks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from edeflare.data.toy import toy_flare_pair
from edeflare.errors import ParameterError
from edeflare.eval.flare_score import (
    FlareGeometry,
    event_energy,
    flare_geometry,
    flare_score,
)
from edeflare.events import make_events

H, W = 120, 160


def _source(cx: int = 100, cy: int = 50, r: int = 3, level: float = 20.0) -> np.ndarray:
    yy, xx = np.mgrid[:H, :W]
    return np.where((xx - cx) ** 2 + (yy - cy) ** 2 <= r * r, level, 0.0)


def _streaks(cx: int = 100, cy: int = 50, length: int = 40, level: float = 3.0) -> np.ndarray:
    e = np.zeros((H, W))
    for angle in np.arange(6) * np.pi / 3:
        r = np.arange(6, length)  # outside the source disc (r_s = 4.8)
        x = np.rint(cx + r * np.cos(angle)).astype(int)
        y = np.rint(cy + r * np.sin(angle)).astype(int)
        ok = (x >= 0) & (x < W) & (y >= 0) & (y < H)
        e[y[ok], x[ok]] = level
    return e


def test_source_alone_scores_zero_and_streaks_raise_the_score():
    source = _source()
    assert flare_geometry(source).center == (100, 50)
    assert flare_score(source) == 0.0
    flared = source + _streaks()
    longer = source + _streaks(length=60)
    brighter = source + _streaks(level=6.0)
    s1, s2, s3 = flare_score(flared), flare_score(longer), flare_score(brighter)
    assert 0 < s1 < s2 and s3 == pytest.approx(2 * s1)


def test_hand_computed_ratio():
    e = np.zeros((50, 50))
    e[25, 25] = 10.0  # source, r_s = 2
    e[25, 30] = 4.0  # flare, d = 5
    e[0, 0] = 7.0  # far field (d = 35 > r_f = 20): not counted, and its median stays 0
    g = FlareGeometry((25, 25), 2.0, 20.0)
    assert flare_score(e, g) == pytest.approx(0.4)


def test_far_field_median_is_subtracted():
    g = FlareGeometry((80, 60), 3.0, 30.0)
    base = _source(80, 60) + _streaks(80, 60, length=25)
    assert flare_score(base + 1.0, g) == pytest.approx(flare_score(base, g))


def test_geometry_from_the_input_scores_other_streams_on_the_same_regions():
    flared = _source() + _streaks()
    g = flare_geometry(flared)
    assert flare_score(_source(), g) == 0.0
    assert flare_score(flared, g) == flare_score(flared)
    assert math.isnan(flare_score(np.zeros((H, W)), g))  # nothing at the source


def test_geometry_prefers_a_compact_bright_region_over_hot_pixels():
    e = _source(40, 80, r=4, level=5.0)
    e[10, 150] = 200.0  # one hot pixel, more than the source's peak but less in total
    e[11, 150] = 200.0  # two of them: still not a region
    assert flare_geometry(e, source_radius_px=2.5).center == (40, 80)


def test_geometry_of_an_empty_map_scores_nan_not_an_error():
    g = flare_geometry(np.zeros((H, W)))
    assert math.isnan(flare_score(np.zeros((H, W)), g))


def test_on_events_of_the_procedural_scene():
    """The halo and streaks of the demo scene's flare score well above the clean stream."""
    size = (160, 120)
    scene = toy_flare_pair(size, duration_us=40_000, rng=3)
    observed, clean = event_energy(scene.observed, size), event_energy(scene.clean, size)
    g = flare_geometry(observed)
    assert np.hypot(g.center[0] - 112, g.center[1] - 36) <= 4  # the lamp is at (0.7 W, 0.3 H)
    assert flare_score(observed, g) > 3 * flare_score(clean, g) > 0


def test_event_energy_counts_both_polarities():
    ev = make_events([0, 1, 2, 3], [1, 1, 0, 1], [0, 0, 1, 0], [1, 0, 1, 1])
    assert event_energy(ev, (2, 2)).tolist() == [[0.0, 3.0], [1.0, 0.0]]


@pytest.mark.parametrize(
    ("energy", "kwargs"),
    [
        (np.zeros((0, 4)), {}),
        (np.zeros(5), {}),
        (-np.ones((4, 4)), {}),
        (np.full((4, 4), np.nan), {}),
        (np.zeros((40, 40)), {"source_radius_px": 5.0, "flare_radius_px": 4.0}),
    ],
)
def test_bad_input(energy, kwargs):
    with pytest.raises(ParameterError):
        flare_score(energy, **kwargs)
