"""Tests of edeflare.sim.stage1: the flare and light events of one script, one sensor."""

from __future__ import annotations

import dataclasses

import numpy as np

from edeflare.events import check_events
from edeflare.sim.dvs import IdealParams, VoltmeterSimulator
from edeflare.sim.optics import PSFConfig
from edeflare.sim.script import FlareScript, Flicker, LightSpec, SensorSpec, Trajectory
from edeflare.sim.stage1 import sensor_pair, simulate_flare_events

SIZE = (96, 72)


def script(**kw):
    base = dict(
        duration_us=20_000,
        fps=4800.0,
        trajectory=Trajectory(start=(0.4, 0.5), direction_deg=0.0, travel_px=10.0),
        flicker=Flicker(frequency_hz=100.0, depth=0.8),
        light=LightSpec(radius_px=3.0, exposure=200.0),
        psf=PSFConfig(grid=128, dust_count=30, star_orientations=3, wavelengths_nm=(550.0,)),
    )
    base.update(kw)
    return FlareScript(**base)


def test_one_script_gives_identical_events_every_time():
    a = simulate_flare_events(script(), SIZE)
    b = simulate_flare_events(script(), SIZE)
    assert a.flare.tobytes() == b.flare.tobytes() and a.light.tobytes() == b.light.tobytes()
    check_events(a.flare, SIZE)
    check_events(a.light, SIZE)
    other = simulate_flare_events(script(sensor=SensorSpec(seed=1)), SIZE)
    assert other.flare.tobytes() != a.flare.tobytes()


def test_flare_events_cover_the_light_events_region_and_more():
    ev = simulate_flare_events(script(), SIZE)
    assert ev.flare.size > 3 * ev.light.size > 0
    light_px = set(zip(ev.light["x"].tolist(), ev.light["y"].tolist(), strict=True))
    flare_px = set(zip(ev.flare["x"].tolist(), ev.flare["y"].tolist(), strict=True))
    assert len(light_px & flare_px) > 0.8 * len(light_px)
    assert len(flare_px) > 3 * len(light_px)
    # light events stay near the light's path: x in 38.4 +- (radius + travel + blur)
    assert ev.light["x"].min() > 30 and ev.light["x"].max() < 56


def test_one_sensor_draw_for_both_videos():
    spec = SensorSpec(model="ideal", ideal=IdealParams(c_sigma=0.05, noise_rate_hz=1.0), seed=9)
    flare_sim, light_sim = sensor_pair(spec, (16, 12))
    assert np.array_equal(flare_sim._c_on, light_sim._c_on)  # one camera
    assert np.array_equal(flare_sim._c_off, light_sim._c_off)
    assert np.unique(flare_sim._c_on).size > 1
    v_flare, v_light = sensor_pair(SensorSpec(seed=9), (16, 12))
    assert isinstance(v_flare, VoltmeterSimulator) and v_flare.params == v_light.params
    assert not np.array_equal(v_flare._state, v_light._state)  # two recordings: own noise
    ev = simulate_flare_events(script(sensor=spec), SIZE)
    assert ev.flare.size > ev.light.size > 0


def test_no_flicker_and_no_motion_gives_no_light_events():
    still = script(flicker=None, trajectory=Trajectory(start=(0.4, 0.5), travel_px=0.0))
    ideal = dataclasses.replace(still, sensor=SensorSpec(model="ideal"))
    ev = simulate_flare_events(ideal, SIZE)
    assert ev.light.size == 0 and ev.flare.size == 0
