"""One idea of a light: the type, its JSON form (old layouts too) and the detector."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from edeflare.errors import AnnotationError, ParameterError
from edeflare.lights import (
    Circle,
    Lights,
    LightSource,
    Polygon,
    bundled_lights,
    detect_light_source,
    load_lights,
    save_lights,
)
from edeflare.realworld import PairConfig


def test_save_then_load_gives_the_same_lights(tmp_path):
    lights = Lights(
        (
            LightSource.circle(10, 5, 3, name="lamp", halo_outer_px=40.0),
            LightSource.polygon([[0, 0], [4, 0], [4, 2]], ghost=False),
            LightSource.track([[0, 1, 1, 1], [100, 5, 1, 2]], response_us=50.0),
        ),
        halo_factor=8.0,
        note="by hand",
    )
    path = tmp_path / "lights.json"
    save_lights(path, lights, sensor_size=[20, 10], method="by hand")
    back = load_lights(path, (20, 10))
    assert back == lights
    assert json.loads(path.read_text())["method"] == "by hand"
    with pytest.raises(AnnotationError, match=r"lights\.json: annotates a 20x10 sensor"):
        load_lights(path, (64, 48))


def test_the_pairing_layout_of_lights_loads_as_fixed_sources(tmp_path):
    path = tmp_path / "old.json"
    old = {"lights": [{"type": "circle", "cx": 3, "cy": 4, "r": 2}, "polygon:0,0,4,0,4,4"]}
    path.write_text(json.dumps(old))
    lights = load_lights(path)
    assert [s.kind for s in lights.sources] == ["circle", "polygon"]
    assert lights.sources[0].shape == Circle(3.0, 4.0, 2.0)
    assert lights.sources[1].shape == Polygon(((0.0, 0.0), (4.0, 0.0), (4.0, 4.0)))
    assert lights.halo_factor == 6.0  # the scorer's default regions


def test_a_moving_source_has_no_outline_and_the_pairing_says_so():
    track = LightSource.track([[0, 1, 1, 1], [100, 5, 1, 1]])
    with pytest.raises(ParameterError, match="a track light source moves"):
        _ = track.shape
    config = PairConfig(lights=(LightSource.circle(5, 5, 2),))
    assert config.lights == (Circle(5.0, 5.0, 2.0),)  # the pairing works on outlines
    with pytest.raises(ParameterError, match="moves"):
        PairConfig(lights=(track,))


def test_every_bundled_annotation_loads_on_its_sensor():
    sizes = {"davis346_flicker_lamps": (346, 260), "prophesee_gen3_rotating_light": (640, 480)}
    assert bundled_lights() == sorted(sizes)
    for name, size in sizes.items():
        lights = load_lights(bundled_lights(name), size)
        assert lights.sources and all(np.isfinite(s.table[:, 3]).any() for s in lights.sources)


def test_the_detector_finds_a_disc_where_it_is():
    counts = np.zeros((40, 60))
    yy, xx = np.mgrid[:40, :60]
    counts[(xx - 42) ** 2 + (yy - 12) ** 2 <= 16] = 50.0
    (found,) = detect_light_source(counts)
    assert abs(found.cx - 42) < 0.5 and abs(found.cy - 12) < 0.5 and 4 <= found.r <= 6


def _blob(t0, cx, cy, side=5, repeats=10, dt=4):
    from edeflare.events import make_events

    yy, xx = np.mgrid[:side, :side]
    n = xx.size * repeats
    return make_events(t0 + np.arange(n) * dt, np.tile(xx.ravel() + cx, repeats),
                       np.tile(yy.ravel() + cy, repeats), np.ones(n, int))  # fmt: skip


def test_tracked_lights_keep_their_identity_and_move_with_the_light():
    from edeflare.events import merge_events
    from edeflare.lights import track_lights

    # a bright blob moving right and a dimmer one standing still; in the second window the
    # moving one is dimmer (fewer events): detection ranks them the other way round
    a1, b1 = _blob(0, 10, 20, repeats=12, dt=3), _blob(0, 40, 30, repeats=10, dt=3)
    a2, b2 = _blob(1000, 16, 20, repeats=10, dt=3), _blob(1000, 40, 30, repeats=12, dt=3)
    lights = track_lights(merge_events(a1, b1, a2, b2), (64, 48), max_sources=2, window_us=1000)
    moving, still = sorted(lights.sources, key=lambda s: -float(np.ptp(s.table[:, 1])))
    assert moving.kind == still.kind == "track"
    cx, _, _ = moving.at(np.array([500, 1000, 1500]))
    assert np.round(cx).tolist() == [12, 15, 18]  # linear between the windows' middles
    assert np.ptp(still.table[:, 1]) < 1e-9 and moving.response_us == 1000


def test_a_lights_radius_comes_from_its_rings_even_at_the_frames_edge():
    from edeflare.events import make_events
    from edeflare.lights import light_radius

    yy, xx = np.mgrid[:48, :64]
    disc = np.hypot(xx - 30, yy - 2) < 10  # cut by the top edge
    n = int(disc.sum())
    ev = make_events(np.arange(5 * n), np.tile(xx[disc], 5), np.tile(yy[disc], 5),
                     np.ones(5 * n, int))  # fmt: skip
    assert light_radius(ev, (64, 48), LightSource.circle(30, 2, 3)) == 10.0


def test_light_cells_count_each_cell_and_refuse_events_off_the_sensor():
    from edeflare.events import make_events
    from edeflare.lights.cells import _Coords, light_cells

    rng = np.random.default_rng(3)
    n = 5000
    x, y = rng.integers(0, 30, n), rng.integers(0, 21, n)
    ev = make_events(np.arange(n), x, y, np.ones(n))
    # 4x4 cells of a 30x21 sensor: 8 x 6, the last column and row cut short
    per_cell = np.zeros((6, 8), np.int64)
    np.add.at(per_cell, (y // 4, x // 4), 1)
    rate = 0.25 * 16 * 20_000 / 1000.0  # events per cell at LIGHT_RATE over 20 ms
    got = light_cells(ev, (30, 21), 20_000, cell=4)
    np.testing.assert_array_equal(got, per_cell >= rate)
    assert 0 < got.sum() < got.size  # some cells are lights, some are not
    per_pixel = np.zeros((21, 30), np.int64)
    np.add.at(per_pixel, (y, x), 1)
    np.testing.assert_array_equal(_Coords(ev, (30, 21), 4).counts, per_pixel)
    for off in (make_events([0], [30], [0], [1]), make_events([0], [0], [21], [1])):
        with pytest.raises(ValueError, match="outside the 30x21 sensor"):
            light_cells(off, (30, 21), 20_000, cell=4)


def _block(per_pixel: int, t0: int, x0: int = 40, y0: int = 16, side: int = 16):
    """A ``side`` x ``side`` block whose pixels fire ``per_pixel`` events each in 20 ms."""
    from edeflare.events import make_events

    yy, xx = np.mgrid[y0 : y0 + side, x0 : x0 + side]
    n = per_pixel * xx.size
    return make_events(t0 + np.arange(n) * 20_000 // n, np.tile(xx.ravel(), per_pixel),
                       np.tile(yy.ravel(), per_pixel), np.ones(n))  # fmt: skip


def test_light_test_summary_counts_lit_windows_and_rates_the_brightest_region():
    from edeflare.events import iter_time_windows, merge_events
    from edeflare.lights import light_test_summary

    # window 1: a light (1 event per pixel and ms); window 2: the same block at 0.3, below
    # the cell rate, beside a hot pixel firing 2,000 events, which must not be "brightest";
    # window 3: empty (not counted); window 4: 0.5 per pixel and ms
    hot = _block(1, 20_000, x0=5, y0=50, side=1)
    hot = np.repeat(hot, 2000)
    hot["t"] = 20_000 + np.arange(2000) * 10
    ev = merge_events(_block(20, 0), _block(6, 20_000), hot, _block(10, 60_000))
    s = light_test_summary(iter_time_windows(ev, 20_000), (96, 64))
    assert (s.windows, s.with_light) == (3, 1)
    assert s.share == pytest.approx(1 / 3)
    # the median of 1.0, 0.3, 0.5 (over the covered span: to its last event, a few µs short)
    assert s.brightest_rate == pytest.approx(0.5, rel=1e-3)
    assert s.lines(20_000)[0] == "light test  a light in 1 of 3 windows of 20 ms"


def test_light_test_summary_refuses_a_bad_window_and_handles_no_events():
    from edeflare.lights import light_test_summary

    with pytest.raises(ParameterError, match="window_us must be positive"):
        light_test_summary([], (8, 8), 0)
    s = light_test_summary([], (8, 8))
    assert (s.windows, s.with_light, s.brightest_rate) == (0, 0, None)
    assert np.isnan(s.share)
    assert s.lines(20_000) == ["light test  a light in 0 of 0 windows of 20 ms"]


def test_info_lights_on_real_recordings(real_data, capsys):
    from edeflare.cli import main

    # the Gen3 light passes the test in each of its four windows; the Gen4.1 street's
    # dense texture in neither of its two, though it passes the cell rate
    assert main(["info", str(real_data / "prophesee_gen3_rotating_light.raw"), "--lights"]) == 0
    out = capsys.readouterr().out
    assert "light test  a light in 4 of 4 windows of 20 ms" in out
    rate = float(re.search(r"brightest   ([0-9.]+) events per firing pixel", out).group(1))
    assert rate > 0.55
    assert main(["info", str(real_data / "prophesee_gen41_street.raw"), "--lights"]) == 0
    assert "a light in 0 of 2 windows" in capsys.readouterr().out
    assert main(["info", str(real_data / "prophesee_gen41_street.raw"), "--lights",
                 "--window-ms", "-1"]) == 1  # fmt: skip
    assert "--window-ms must be positive" in capsys.readouterr().err


@pytest.mark.parametrize("seed", range(6))
def test_sparse_filters_give_scipys_numbers_exactly(seed):
    from scipy import ndimage

    from edeflare.lights.detect import gaussian_on_support, median3

    rng = np.random.default_rng(seed)
    h, w = (72, 128) if seed % 2 else (260, 346)
    counts = np.zeros((h, w))
    lone = rng.integers(0, h * w, 200)  # isolated events and hot pixels, borders included
    counts.flat[lone] = rng.integers(1, 60, lone.size)
    cy, cx = rng.integers(0, h), rng.integers(0, w)  # a light, possibly cut by the frame
    yy, xx = np.mgrid[:h, :w]
    counts[np.hypot(yy - cy, xx - cx) <= rng.uniform(2, 12)] += rng.integers(1, 9)
    median = median3(counts)
    assert np.array_equal(median, ndimage.median_filter(counts, size=3, mode="nearest"))
    for sigma in (1.0, 2.0, 3.5):
        assert np.array_equal(
            gaussian_on_support(median, sigma),
            ndimage.gaussian_filter(median, sigma, mode="nearest"),
        )
    dense = rng.integers(0, 5, (h, w)).astype(float)  # the plain filters' path
    assert np.array_equal(median3(dense), ndimage.median_filter(dense, size=3, mode="nearest"))
    assert not gaussian_on_support(np.zeros((h, w)), 2.0).any()


def test_detect_light_source_smooths_real_windows_as_scipys_filters(real_data):
    # the detector's smoothing, on 2 ms windows of real recordings (what track_lights and
    # edeflare score --detect-lights run it on), equals scipy's median and Gaussian filters
    # to the bit; the rest of the detector reads only the smoothed map
    from scipy import ndimage

    from edeflare.events import count_map, iter_time_windows
    from edeflare.io import read_events
    from edeflare.lights.detect import gaussian_on_support, median3

    checked = 0
    for name in ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4",
                 "prophesee_gen41_street.raw"):  # fmt: skip
        events, size = read_events(real_data / name)
        for _, window in list(iter_time_windows(events, 2_000))[::3]:
            counts = count_map(window, size).astype(float)
            plain = ndimage.gaussian_filter(
                ndimage.median_filter(counts, size=3, mode="nearest"), 2.0, mode="nearest"
            )
            assert np.array_equal(gaussian_on_support(median3(counts), 2.0), plain)
            checked += 1
    assert checked > 30
