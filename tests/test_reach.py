"""Where the flare reaches, measured from a recording: rings of event rate around a light."""

from __future__ import annotations

import math

import numpy as np
import pytest

from edeflare.cli import main
from edeflare.events import make_events, sort_events
from edeflare.io import write_events
from edeflare.lights import Lights, LightSource, flare_reach, light_response, measure_regions
from edeflare.lights.reach import EXCESS, GHOST_SPREAD, ghost_spread, synthetic_flare


def _true_reach(radius: float, reach: float, strength: float) -> float:
    """Where the drawn halo's rate falls to EXCESS of the background's (or its end)."""
    return min(reach, radius * math.sqrt(strength / EXCESS))


@pytest.mark.parametrize("size", [(346, 260), (640, 480), (1280, 720)])
@pytest.mark.parametrize("log_strength", [1.5, 2.5, 3.5, 5.0])
def test_the_reach_is_found_within_15_percent_at_every_size_and_strength(size, log_strength):
    strength = 10.0**log_strength
    radius, reach = 0.02 * size[0], 0.25 * size[0]
    centre = (0.35 * size[0], 0.4 * size[1])
    # a strong source fires so much that a shorter recording holds as many events
    duration = int(100_000 * min(1.0, 10**1.5 / strength) ** 0.5)
    ev = synthetic_flare(
        np.random.default_rng(int(log_strength * 10)), size, centre, radius=radius,
        reach=reach, strength=strength, ghost_radius=2 * radius, duration_us=duration,
    )  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(*centre, radius))
    true = _true_reach(radius, reach, strength)
    assert found.halo_outer_px is not None
    assert abs(found.halo_outer_px - true) <= 0.15 * true, (found.halo_outer_px, true)
    gx, gy = found.ghost_centre
    assert math.hypot(gx - (size[0] - 1 - centre[0]), gy - (size[1] - 1 - centre[1])) <= 10


def test_a_faint_source_shows_no_ghost_and_gets_no_ghost_region():
    size = (346, 260)
    ev = synthetic_flare(np.random.default_rng(3), size, (100, 90), radius=6, reach=80,
                         strength=50.0)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(100, 90, 6))
    assert found.ghost_radius_px is None and found.halo_outer_px is not None
    lights = measure_regions(ev, size, Lights((LightSource.circle(100, 90, 6),)))
    (source,) = lights.sources
    assert source.ghost_radius_px is None and source.halo_outer_px == found.halo_outer_px
    assert source.ghost is False  # measured absent: no ghost region (not the factor's disc)
    assert not found.ghost_in_halo
    assert "measured" in lights.note


def test_the_factor_is_the_least_halo():
    # a halo that meets the background at 20 px from a 6 px source: less than the
    # factor's 36 px, which stays (a rate test cannot see flare that replaces scene)
    size = (346, 260)
    ev = synthetic_flare(np.random.default_rng(6), size, (100, 90), radius=6, reach=20,
                         strength=300.0)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(100, 90, 6))
    assert found.halo_outer_px is not None and found.halo_outer_px < 36
    (source,) = measure_regions(ev, size, Lights((LightSource.circle(100, 90, 6),))).sources
    assert source.halo_outer_px is None  # Lights.halo_factor (6) applies
    (source,) = measure_regions(
        ev, size, Lights((LightSource.circle(100, 90, 6),), halo_factor=2.0)
    ).sources
    assert source.halo_outer_px == found.halo_outer_px


def test_a_reflection_inside_the_halo_keeps_the_factors_ghost():
    size = (346, 260)  # the source 12 px from the centre: its reflection 24 px away
    ev = synthetic_flare(np.random.default_rng(7), size, (160, 129.5), radius=5, reach=80,
                         strength=500.0)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(160, 129.5, 5))
    assert found.ghost_in_halo and found.ghost_radius_px is None
    (source,) = measure_regions(ev, size, Lights((LightSource.circle(160, 129.5, 5),))).sources
    assert source.ghost and source.ghost_radius_px is None  # Lights.ghost_factor applies


def _scene_at(size, centre, rng):
    """Bright scene edges at ``centre``: two lines, an L, as a lit table's corner."""
    cx, cy = centre
    xs = np.r_[np.arange(cx - 25, cx + 1), np.full(25, cx)].astype(int)
    ys = np.r_[np.full(26, cy), np.arange(cy - 25, cy)].astype(int)
    n = 60
    return make_events(rng.integers(0, 100_000, xs.size * n), np.tile(xs, n), np.tile(ys, n),
                       rng.integers(0, 2, xs.size * n), sort=True)  # fmt: skip


def test_scene_at_the_reflection_is_not_a_ghost():
    # The DAVIS346 lamps' reflections land on a lit table: edges, a local excess over
    # the frame's background, spread unevenly round the reflection. A drawn ghost disc
    # of the same count is even. Both measured by the same flare_reach.
    size = (346, 260)
    rng = np.random.default_rng(8)
    lamp = synthetic_flare(rng, size, (100, 60), radius=6, reach=30, strength=300.0)
    g = (size[0] - 1 - 100, size[1] - 1 - 60)
    with_scene = sort_events(np.concatenate([lamp, _scene_at(size, g, rng)]))
    found = flare_reach(with_scene, size, LightSource.circle(100, 60, 6))
    assert found.ghost_spread is not None and found.ghost_spread > GHOST_SPREAD
    assert found.ghost_radius_px is None
    (source,) = measure_regions(with_scene, size, Lights((LightSource.circle(100, 60, 6),))).sources
    assert source.ghost is False
    ghost = synthetic_flare(rng, size, (100, 60), radius=6, reach=30, strength=300.0,
                            ghost_radius=12)  # fmt: skip
    found = flare_reach(ghost, size, LightSource.circle(100, 60, 6))
    assert found.ghost_radius_px is not None and found.ghost_spread < 0.1


def test_ghost_spread_by_hand():
    # four sectors of a disc: counts 100, 100, 100, 100 -> 0; one side only -> large
    yy, xx = np.mgrid[:21, :21]
    inside = np.hypot(xx - 10, yy - 10) <= 8
    dx, dy = (xx[inside] - 10.0), (yy[inside] - 10.0)
    even = ghost_spread(np.repeat(dx, 50), np.repeat(dy, 50), (10, 10), (21, 21), 8, sectors=4)
    assert even < 0.05
    right = dx > 0
    one = ghost_spread(np.repeat(dx[right], 50), np.repeat(dy[right], 50), (10, 10), (21, 21), 8,
                       sectors=4)  # fmt: skip
    # two of four sectors lit at about twice the mean: rates (2, 2, 0, 0) x, CV = 1
    assert 0.9 <= one <= 1.0
    assert ghost_spread(dx[:0], dy[:0], (10, 10), (21, 21), 8) == 1.0  # nothing there


def test_light_response_of_a_moving_disc_and_none_for_a_still_one():
    track = LightSource.track([[0, 10, 20, 4], [60_000, 70, 20, 4]])  # 1 px per ms
    px = np.arange(10, 71)
    exit_us = (px - 10 + 4) * 1000.0
    delays = np.where(px % 2 == 0, 1_950, 250)  # half the pixels settle late
    t = exit_us + delays
    order = np.argsort(t)
    ev = make_events(t[order], px[order], np.full(px.size, 20), np.ones(px.size, int))
    found = light_response(ev, track)
    assert found.response_us == 2_000  # the 95th percentile: a late one, rounded up
    assert found.delays_us.size == 35  # passed 10 ms after the start, 15 ms before the end
    assert abs(found.speed_px_per_us - 0.001) < 1e-6
    assert light_response(ev, track, quantile=0.4).response_us == 300  # 250, rounded up
    still = LightSource.track([[0, 40, 20, 4], [60_000, 41, 20, 4]])
    assert light_response(ev, still).response_us is None
    # a detected lamp's track jitters by a pixel: a long path, but it stays put
    jitter = LightSource.track([[k * 1_000, 40 + k % 2, 20 - k % 2, 4] for k in range(61)])
    assert light_response(ev, jitter).response_us is None
    assert light_response(ev, LightSource.circle(40, 20, 4)).response_us is None


def test_a_ghost_is_measured_where_the_light_reflects():
    size = (640, 480)
    ev = synthetic_flare(np.random.default_rng(4), size, (200, 150), radius=10, reach=150,
                         strength=1000.0, ghost_radius=30)  # fmt: skip
    found = flare_reach(ev, size, LightSource.circle(200, 150, 10))
    assert found.ghost_centre == (439.0, 329.0)
    assert found.ghost_radius_px is not None and 25 <= found.ghost_radius_px <= 40


def test_score_records_the_regions_it_measured_and_a_dark_recording_gets_a_message(
    tmp_path, capsys
):
    size = (346, 260)
    ev = synthetic_flare(np.random.default_rng(5), size, (120, 100), radius=6, reach=80,
                         strength=300.0)  # fmt: skip
    write_events(tmp_path / "lamp.h5", ev, size)
    report = tmp_path / "s.json"
    args = ["score", str(tmp_path / "lamp.h5"), "-m", "raw", "--detect-lights"]
    assert main([*args, "--json", str(report)]) == 0
    import json

    data = json.loads(report.read_text())
    (source,) = data["lights"]["sources"]
    assert 0.85 * 80 <= source["halo_outer_px"] <= 1.15 * 80
    assert "measured" in data["lights"]["note"]
    assert main([*args, "--fixed-regions", "--json", str(report)]) == 0
    (source,) = json.loads(report.read_text())["lights"]["sources"]
    assert "halo_outer_px" not in source and "ghost" not in source  # the factors alone
    capsys.readouterr()
    dark = ev[:0]
    write_events(tmp_path / "dark.h5", dark, size)
    assert main(["score", str(tmp_path / "dark.h5"), "-m", "raw", "--detect-lights"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("edeflare: error:") and "dark.h5" in err and "nan" not in err.lower()
