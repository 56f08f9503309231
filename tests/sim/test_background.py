"""Tests of edeflare.sim.background: recorded windows (any format) and synthetic night streets."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace

import numpy as np
import pytest

from conftest import random_events, same_events
from edeflare.errors import EdeflareError
from edeflare.events import check_events, make_events, slice_time
from edeflare.io import read_events, write_events
from edeflare.sim.background import (
    NightStreet,
    RecordedBackground,
    SceneConfig,
    SyntheticBackground,
    fit_to_sensor,
)
from edeflare.sim.compose import AccumulatedIntensity, CountIntensity
from edeflare.sim.script import SensorSpec

FAST = SceneConfig(fps=1000.0)


# --------------------------------------------------------------------------- synthetic


def test_synthetic_background_is_seeded_sorted_and_on_the_sensor():
    src = SyntheticBackground(FAST)
    a = src.draw(20_000, (80, 60), rng=3)
    b = src.draw(20_000, (80, 60), rng=np.random.default_rng(3))
    c = src.draw(20_000, (80, 60), rng=4)
    check_events(a.events, (80, 60))
    assert same_events(a.events, b.events) and not same_events(a.events, c.events)
    assert a.events.size and 0 <= a.events["t"].min() and a.events["t"].max() < 20_000
    assert a.description == b.description and a.description["kind"] == "synthetic"
    assert 0.3 < a.events["p"].mean() < 0.7  # both polarities


def test_synthetic_event_rates_look_like_night_driving():
    """0.2-15 M events/s at 640x480 equivalent (DSEC night drives are in the low millions)."""
    rates = []
    for seed in range(4):
        bg = SyntheticBackground(FAST).draw(50_000, (160, 120), rng=seed)
        rates.append(bg.events.size / 0.05 / (160 * 120) * (640 * 480))
    assert all(0.2e6 < r < 15e6 for r in rates), rates


def test_scene_frames_are_a_dim_street_with_bright_spots():
    scene = NightStreet((160, 120), rng=0)
    frame = scene.frame(0)
    assert frame.dtype == np.float32 and frame.shape == (120, 160)
    assert 3 < np.median(frame) < 50 and frame.max() > 100 and frame.min() > 0
    assert not np.array_equal(frame, scene.frame(50_000))  # the camera moves


def test_scene_sample_is_exactly_the_rendered_video(rng):
    scene = NightStreet((64, 48), rng=1)
    events = random_events(rng, 2_000, (64, 48), span_us=100_000)
    got = scene.sample(events)
    for t in np.unique(events["t"])[:50]:
        sel = events[events["t"] == t]
        expected = scene.frame(int(t))[sel["y"], sel["x"]]
        np.testing.assert_allclose(got[events["t"] == t], expected, rtol=1e-5)


NEAR = SceneConfig(fps=1000.0, near_objects=(1, 1), near_speed_px_per_s=(2000.0, 2000.0))


def test_a_near_object_is_a_textured_ellipse_that_swings_in_front_of_the_street():
    size = (160, 120)
    street = NightStreet(size, FAST, rng=2)
    near = NightStreet(size, dataclasses_replace(FAST, near_objects=(1, 1)), rng=2)
    (obj,) = near.objects
    # the street behind is drawn as before: the same texture and camera
    assert np.array_equal(near.texture, street.texture) and near.params == street.params
    assert 0.3 * 60 <= obj.ay <= 0.8 * 60 and 0.6 * obj.ay <= obj.ax <= obj.ay
    t = 10_000
    cx, cy = obj.centre(t)
    yy, xx = np.mgrid[:120, :160]
    inside = ((xx - cx) / obj.ax) ** 2 + ((yy - cy) / obj.ay) ** 2 < 0.8
    outside = ((xx - cx) / obj.ax) ** 2 + ((yy - cy) / obj.ay) ** 2 > 1.2
    a, b = near.frame(t), street.frame(t)
    assert np.array_equal(a[outside], b[outside])
    assert np.mean(a[inside] != b[inside]) > 0.99
    # its centre swings along (dx, dy) at omega: at its fastest, |omega (dx, dy)| px per us
    s0 = np.sin(obj.phase)
    assert obj.centre(0) == pytest.approx((obj.cx + obj.dx * s0, obj.cy + obj.dy * s0))
    speed = obj.omega * np.hypot(obj.dx, obj.dy) * 1e6
    assert 300.0 <= speed <= 3000.0
    assert "near_objects" in near.describe() and "near_objects" not in street.describe()


def test_a_near_objects_sample_is_exactly_its_rendered_video(rng):
    scene = NightStreet((64, 48), NEAR, rng=1)
    events = random_events(rng, 3_000, (64, 48), span_us=100_000)
    got = scene.sample(events)
    covered = 0
    for t in np.unique(events["t"])[:400]:
        sel = events["t"] == t
        frame = scene.frame(int(t))
        np.testing.assert_allclose(got[sel], frame[events["y"][sel], events["x"][sel]], rtol=1e-5)
        cx, cy = scene.objects[0].centre(int(t))
        ev = events[sel]
        o = scene.objects[0]
        covered += np.count_nonzero(((ev["x"] - cx) / o.ax) ** 2 + ((ev["y"] - cy) / o.ay) ** 2 < 1)
    assert covered > 10  # some of the checked events fell on the object


def test_a_fast_near_object_fires_densely_and_a_scene_without_one_keeps_its_digest():
    size = (96, 72)
    plain = SyntheticBackground(FAST).draw(30_000, size, rng=5)
    near = SyntheticBackground(NEAR).draw(30_000, size, rng=5)
    assert near.events.size > 1.5 * plain.events.size
    assert "near_objects" not in FAST.to_dict() and NEAR.to_dict()["near_objects"] == [1, 1]
    assert SceneConfig.from_dict(NEAR.to_dict()) == NEAR
    assert SceneConfig.from_dict(FAST.to_dict()) == FAST


def test_synthetic_intensity_choices_and_camera():
    size = (48, 32)
    video = SyntheticBackground(FAST).draw(10_000, size, rng=0)
    acc = SyntheticBackground(FAST, intensity="accumulation").draw(10_000, size, rng=0)
    cnt = SyntheticBackground(FAST, intensity="counts").draw(10_000, size, rng=0)
    assert isinstance(video.intensity, NightStreet) and video.video is not None
    assert isinstance(acc.intensity, AccumulatedIntensity)
    assert isinstance(cnt.intensity, CountIntensity)
    assert same_events(video.events, acc.events)
    ideal = SensorSpec(model="ideal", seed=5)
    a = SyntheticBackground(FAST).draw(10_000, size, ideal, rng=0)
    assert not same_events(a.events, video.events)
    with pytest.raises(EdeflareError, match="intensity must be one of"):
        SyntheticBackground(intensity="vidoe")


def test_scene_config_rejects_unknown_keys_and_bad_ranges():
    with pytest.raises(EdeflareError, match="unknown key"):
        SceneConfig.from_dict({"fsp": 100})
    with pytest.raises(EdeflareError, match="low <= high"):
        SceneConfig(pan_px_per_s=(5.0, 1.0))
    assert SceneConfig.from_dict(SceneConfig().to_dict()) == SceneConfig()


# ---------------------------------------------------------------------------- recorded


@pytest.fixture
def drive_h5(tmp_path, rng):
    """A DSEC file: 1 s of random events on 64x48, starting at t = 5 s."""
    events = random_events(rng, 50_000, (64, 48), t0=5_000_000, span_us=1_000_000)
    path = tmp_path / "drive.h5"
    write_events(path, events, (64, 48))
    return path, events


def test_recorded_windows_are_cut_shifted_and_fitted(drive_h5):
    path, events = drive_h5
    src = RecordedBackground([path])
    bg = src.draw(60_000, (32, 24), rng=7)
    d = bg.description
    assert d["kind"] == "recorded" and d["file"] == "drive.h5" and d["offset_xy"] == [-16, -12]
    window = slice_time(events, d["start_us"], d["start_us"] + 60_000)
    expected, _ = fit_to_sensor(window, (64, 48), (32, 24))
    expected["t"] -= d["start_us"]
    assert same_events(bg.events, expected)
    assert 5_000_000 <= d["start_us"] <= 6_000_000 - 60_000
    assert isinstance(bg.intensity, AccumulatedIntensity) and bg.video is None
    again = src.draw(60_000, (32, 24), rng=7)
    assert same_events(again.events, bg.events)
    padded = src.draw(60_000, (100, 50), rng=7)
    assert padded.description["offset_xy"] == [18, 1]
    assert padded.events.size == window.size  # nothing lost when padding
    counts = RecordedBackground([path], intensity="counts").draw(60_000, (32, 24), rng=7)
    assert isinstance(counts.intensity, CountIntensity)


def test_recorded_formats_agree(drive_h5, tmp_path):
    path, events = drive_h5
    npz = tmp_path / "drive.npz"
    write_events(npz, events, (64, 48))
    a = RecordedBackground([path]).draw(40_000, (64, 48), rng=2)
    b = RecordedBackground([npz]).draw(40_000, (64, 48), rng=2)
    assert same_events(a.events, b.events)


def test_recorded_picks_files_by_usable_span(tmp_path, rng):
    long = tmp_path / "long.npz"
    short = tmp_path / "short.npz"
    write_events(long, random_events(rng, 5_000, (8, 8), span_us=1_000_000), (8, 8))
    write_events(short, random_events(rng, 500, (8, 8), span_us=60_000), (8, 8))
    src = RecordedBackground([long, short])
    names = [src.draw(50_000, (8, 8), rng=s).description["file"] for s in range(60)]
    assert names.count("long.npz") > 45  # usable spans ~950 ms vs ~10 ms
    with pytest.raises(EdeflareError, match="no background file spans 2000000"):
        src.draw(2_000_000, (8, 8), rng=0)


def test_recorded_errors_name_the_problem(tmp_path):
    with pytest.raises(EdeflareError, match="at least one event file"):
        RecordedBackground([])
    with pytest.raises(EdeflareError, match="no such file"):
        RecordedBackground([tmp_path / "missing.h5"])
    empty = tmp_path / "empty.npz"
    write_events(empty, make_events([], [], [], []), (4, 4))
    with pytest.raises(EdeflareError, match="holds no events"):
        RecordedBackground([empty])
    with pytest.raises(EdeflareError, match="duration_us must be > 0"):
        SyntheticBackground().draw(0, (4, 4))


@pytest.mark.parametrize(
    "name, size, target, duration",
    [
        ("davis346_street_cars.aedat4", None, (320, 240), 100_000),  # centre crop
        ("davis346_street_cars.aedat4", None, (640, 480), 100_000),  # padding
        ("prophesee_gen41_street.raw", None, (640, 480), 5_000),  # EVT3 1280x720 (8.8 ms)
        ("prophesee_gen3_rotating_light.raw", (640, 480), (346, 260), 40_000),  # no size
    ],
)
def test_real_recordings_serve_as_backgrounds(real_data, name, size, target, duration):
    path = real_data / name
    src = RecordedBackground([path], sensor_size=size)
    bg = src.draw(duration, target, rng=0)
    check_events(bg.events, target)
    assert bg.events.size > 100
    assert 0 <= bg.events["t"].min() and bg.events["t"].max() < duration
    # The window is the recording's own events, moved.
    events, rec_size = read_events(path, size)
    start = bg.description["start_us"]
    expected, _ = fit_to_sensor(slice_time(events, start, start + duration), rec_size, target)
    assert bg.events.size == expected.size
    i = bg.intensity.sample(bg.events)
    assert np.isfinite(i).all() and (i > 0).all()
