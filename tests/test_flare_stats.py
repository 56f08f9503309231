"""Flare statistics: hand-built scenes with known rates, sectors and intervals; a real recording."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import real_data_dir
from edeflare.eval.flare_stats import RING_EDGES, flare_statistics, lights_from_events
from edeflare.events import make_events
from edeflare.io import read_events
from edeflare.lights import Lights, LightSource, bundled_lights, load_lights

SIZE = (64, 48)
CX, CY, R = 32, 24, 4.0


def _pixels_where(lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    d = np.hypot(xx - CX, yy - CY) / R
    sel = (d >= lo) & (d < hi)
    return xx[sel], yy[sel]


def _scene(light_repeats: int, ring_lo: float, ring_hi: float, sector: bool = False):
    """Every light pixel fires ``light_repeats`` times 1 ms apart (ON, OFF alternately);
    every pixel of the ring [ring_lo, ring_hi) r fires once (ON), or only those of one sector."""
    lx, ly = _pixels_where(0.0, 1.0)
    rx, ry = _pixels_where(ring_lo, ring_hi)
    if sector:
        keep = np.abs(np.arctan2(ry - CY, rx - CX)) < math.radians(10)
        rx, ry = rx[keep], ry[keep]
    t = np.concatenate([np.repeat(np.arange(light_repeats) * 1000, lx.size), np.full(rx.size, 500)])
    x = np.concatenate([np.tile(lx, light_repeats), rx])
    y = np.concatenate([np.tile(ly, light_repeats), ry])
    p = np.concatenate([np.repeat(np.arange(light_repeats) % 2 == 0, lx.size), np.ones(rx.size)])
    order = np.argsort(t, kind="stable")
    return make_events(t[order], x[order], y[order], p[order].astype(int))


def test_radial_rates_are_per_pixel_and_relative_to_the_light():
    ev = _scene(light_repeats=10, ring_lo=2.0, ring_hi=3.0)
    st = flare_statistics(ev, Lights((LightSource.circle(CX, CY, R),)), SIZE)
    ring = RING_EDGES.index(2.0)
    assert st.radial[0] == 1.0
    assert st.radial[ring] == pytest.approx(1 / 10)  # one event per pixel against ten
    assert all(v == 0 for i, v in enumerate(st.radial) if i not in (0, ring))
    span_s = 9 * 1000 / 1e6
    assert st.light_rate == pytest.approx(10 / span_s)
    assert st.interval_ms["light"] == pytest.approx(1.0)  # a light pixel fires every 1 ms
    assert st.on_fraction["light"] == pytest.approx(0.5) and st.on_fraction["halo"] == 1.0
    assert st.streak_contrast == pytest.approx(1.0, abs=0.35)  # an even ring


def test_a_streak_has_a_high_contrast_an_even_ring_does_not():
    lights = Lights((LightSource.circle(CX, CY, R),))
    streak = flare_statistics(_scene(4, 2.0, 5.5, sector=True), lights, SIZE)
    ring = flare_statistics(_scene(4, 2.0, 5.5), lights, SIZE)
    assert streak.streak_contrast > 5 * ring.streak_contrast


def test_lights_from_events_follows_a_moving_source():
    xs, ys = np.meshgrid(np.arange(-2, 3), np.arange(-2, 3))
    t, x, y = [], [], []
    for k in range(4):  # a 5x5 square moving 10 px per 5 ms step
        t.append(np.full(25, k * 5000 + 100))
        x.append(xs.ravel() + 10 + 10 * k)
        y.append(ys.ravel() + 20)
    ev = make_events(np.concatenate(t), np.concatenate(x), np.concatenate(y), np.ones(100, int))
    src = lights_from_events(ev).sources[0]
    cx, cy, r = src.at(np.array([100, 5100, 15_100]))
    assert cx.tolist() == [10.0, 20.0, 40.0] and cy.tolist() == [20.0, 20.0, 20.0]
    assert r == pytest.approx(np.full(3, math.sqrt(25 / math.pi)))
    with pytest.raises(ValueError, match="no events"):
        lights_from_events(ev[:0])


def test_the_real_rotating_light_has_a_dense_core_and_a_sparse_on_trail():
    path = real_data_dir() / "prophesee_gen3_rotating_light.raw"
    rec = read_events(path)
    lights = load_lights(bundled_lights(path.name), rec.sensor_size)
    st = flare_statistics(rec.events, lights, rec.sensor_size)
    assert st.radius_px == 36
    assert st.radial[1] < 0.02 and st.radial[3] < 0.002  # scattered light is sparse
    assert st.on_fraction["halo"] > 0.99  # the trail behind the blob is ON
    assert st.light_rate > 1000  # events per pixel per second in the blob
