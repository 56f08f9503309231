"""Tests of edeflare.sim.script: drawing, determinism, JSON, the paper's ranges."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from edeflare.sim._validation import SimError
from edeflare.sim.dvs import DVS346_K
from edeflare.sim.script import (
    WAVEFORMS,
    FlareScript,
    Flicker,
    ScriptConfig,
    Trajectory,
    draw_script,
)

N_DRAWS = 2000


@pytest.fixture(scope="module")
def many():
    return [draw_script(rng=seed) for seed in range(N_DRAWS)]


def within(fraction, p, n=N_DRAWS, sds=4.0):
    """``fraction`` agrees with a binomial proportion ``p`` to ``sds`` standard deviations."""
    return abs(fraction - p) <= sds * math.sqrt(p * (1 - p) / n)


def test_same_seed_same_script_and_generator_streams_differ():
    assert draw_script(rng=42) == draw_script(rng=42)
    assert draw_script(rng=42) != draw_script(rng=43)
    gen = np.random.default_rng(5)
    a, b = draw_script(rng=gen), draw_script(rng=gen)
    assert a != b
    assert draw_script(rng=np.random.default_rng(5)) == a


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 17])
def test_json_round_trip_is_exact(seed):
    script = draw_script(rng=seed, flare7k_names=["Flare-R/Compound_Flare/a.png"])
    text = script.to_json()
    back = FlareScript.from_json(text)
    assert back == script
    assert back.to_json() == text
    assert json.loads(text)["sensor"]["voltmeter"]["k"][1:] == list(DVS346_K[1:])


def test_unknown_keys_are_rejected_at_every_level():
    d = draw_script(rng=0).to_dict()
    with pytest.raises(SimError, match=r"unknown key\(s\) \['colour'\] for FlareScript"):
        FlareScript.from_dict({**d, "colour": 1})
    bad = {**d, "affine": {**d["affine"], "rotaton_deg": 3}}
    with pytest.raises(SimError, match=r"unknown key\(s\) \['rotaton_deg'\] for script 'affine'"):
        FlareScript.from_dict(bad)
    bad = {**d, "sensor": {**d["sensor"], "voltmeter": {"k": DVS346_K, "gain": 2}}}
    with pytest.raises(SimError, match=r"unknown key\(s\) \['gain'\]"):
        FlareScript.from_dict(bad)
    with pytest.raises(SimError, match="a script must be JSON"):
        FlareScript.from_json("{not json")
    with pytest.raises(SimError, match=r"unknown key\(s\) \['ghost_prob'\]"):
        ScriptConfig.from_dict({"ghost_prob": 0.5})


def test_flicker_disabled_in_30_percent_and_ghosts_in_90_percent(many):
    no_flicker = np.mean([s.flicker is None for s in many])
    ghosts = np.mean([len(s.ghosts) > 0 for s in many])
    assert within(no_flicker, 0.3) and within(ghosts, 0.9)
    counts = [len(s.ghosts) for s in many if s.ghosts]
    assert min(counts) == 3 and max(counts) == 8
    ks = np.array([g.k for s in many for g in s.ghosts])
    assert ks.min() >= -5 and ks.max() <= 1 and ks.mean() == pytest.approx(-2, abs=0.1)


def test_frame_rate_is_48_times_the_flicker_frequency_capped_at_6000(many):
    flickering = [s for s in many if s.flicker is not None]
    for s in flickering:
        assert s.fps == pytest.approx(min(48 * s.flicker.frequency_hz, 6000.0))
        assert 100 <= s.flicker.frequency_hz <= 140
        assert 0.3 <= s.flicker.depth <= 1.0
    fps = np.array([s.fps for s in many])
    assert fps.min() >= 4800 and fps.max() == 6000
    assert within(np.mean(fps == 6000), 15 / 40)  # f >= 125 Hz
    waveforms = [s.flicker.waveform for s in flickering]
    for w in WAVEFORMS:
        assert within(waveforms.count(w) / len(waveforms), 1 / 3, n=len(waveforms))


def test_motion_and_affine_draws_cover_the_papers_ranges(many):
    def arr(f):
        return np.array([f(s) for s in many])

    checks = {
        "travel": (arr(lambda s: s.trajectory.travel_px), 0, 180),
        "direction": (arr(lambda s: s.trajectory.direction_deg), 0, 360),
        "rotation": (arr(lambda s: s.affine.rotation_deg), 0, 360),
        "scale": (arr(lambda s: s.affine.scale), 0.8, 1.5),
        "translate": (arr(lambda s: s.affine.translate[0]), -0.2, 0.2),
        "shear": (arr(lambda s: s.affine.shear_deg), -20, 20),
        "duration_ms": (arr(lambda s: s.duration_us / 1000), 50, 100),
    }
    for name, (x, lo, hi) in checks.items():
        assert x.min() >= lo and x.max() <= hi, name
        # uniform: the mean within 4 SE of the midpoint, and the ends reached
        se = (hi - lo) / math.sqrt(12 * x.size)
        assert abs(x.mean() - (lo + hi) / 2) < 4 * se, name
        assert x.min() < lo + 0.01 * (hi - lo) and x.max() > hi - 0.01 * (hi - lo), name


def test_sensor_contrast_is_randomised_like_the_authors(many):
    k1 = np.array([s.sensor.voltmeter.k[0] for s in many])
    assert k1.min() >= 5 and k1.max() <= 16
    assert within(np.mean(k1 < 7), 0.5)  # U(5, 7) half the time, else U(7, 16)
    assert all(s.sensor.voltmeter.k[1:] == DVS346_K[1:] for s in many)
    assert len({s.sensor.seed for s in many}) == N_DRAWS


def test_flare7k_choice_uses_the_given_names_and_a_gamma_in_range():
    names = ["b.png", "a.png", "c.png"]
    picks = [draw_script(rng=i, flare7k_names=names).flare7k for i in range(200)]
    assert {p.name for p in picks} == set(names)
    assert all(1.8 <= p.gamma <= 2.2 for p in picks)
    assert draw_script(rng=0).flare7k is None


def test_frame_times_positions_and_flicker_factor():
    s = FlareScript(
        duration_us=100_000,
        fps=6000.0,
        trajectory=Trajectory(start=(0.25, 0.5), direction_deg=90.0, travel_px=120.0),
        flicker=Flicker(frequency_hz=100.0, waveform="triangle", depth=0.8),
    )
    t = s.frame_times_us()
    assert t.size == 601 and t[0] == 0 and t[-1] == 100_000 and (np.diff(t) > 0).all()
    assert s.position_px(0, (640, 480)) == pytest.approx((160.0, 240.0))
    assert s.position_px(50_000, (640, 480)) == pytest.approx((160.0, 300.0))
    # triangle, phase 0: w = 1 - 2 |frac - 1/2|: 0 at t = 0, 1 at half a period (5 ms)
    assert s.intensity(np.array([0, 2500, 5000])).tolist() == pytest.approx([0.2, 0.6, 1.0])
    sine = Flicker(frequency_hz=50.0, waveform="sine", depth=1.0, phase=0.25)
    assert sine.factor(np.array([0.0, 10_000.0])).tolist() == pytest.approx([1.0, 0.0])
    assert FlareScript().intensity(123.0) == 1.0


def test_invalid_scripts_are_rejected():
    with pytest.raises(SimError, match="duration_us must be > 0"):
        FlareScript(duration_us=0)
    with pytest.raises(SimError, match="waveform must be one of 'sine', 'square', 'triangle'"):
        Flicker(waveform="saw")
    with pytest.raises(SimError, match="gt_lens must be one of"):
        FlareScript(gt_lens="perfect")
    with pytest.raises(SimError, match="scale must be"):
        ScriptConfig(scale=(1.5, 0.8))


def test_warm_start_reaches_the_sensor_and_round_trips_and_is_left_out_while_off():
    cold = draw_script(rng=4)
    warm = draw_script(ScriptConfig(warm_start=True), rng=4)
    assert cold.sensor.warm_start is False and warm.sensor.warm_start is True
    # the same draws otherwise: the flag costs no random number
    as_cold = dataclasses.replace(warm.sensor, warm_start=False)
    assert dataclasses.replace(warm, sensor=as_cold) == cold
    assert "warm_start" not in cold.to_dict()["sensor"]
    assert warm.to_dict()["sensor"]["warm_start"] is True
    assert FlareScript.from_json(warm.to_json()) == warm
    with pytest.raises(SimError, match="warm_start must be a bool"):
        ScriptConfig(warm_start=1)
