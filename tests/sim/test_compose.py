"""Tests of edeflare.sim.compose: PNL-ES, its N-way form, intensity fields, pairs, forward model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import random_events, same_events
from edeflare.errors import EdeflareError
from edeflare.events import EVENT_DTYPE, check_events, make_events, merge_events
from edeflare.sim.compose import (
    VARIANTS,
    AccumulatedIntensity,
    AccumulationParams,
    Components,
    ConstantIntensity,
    CountIntensity,
    VideoIntensity,
    compose_pair,
    forward_pair,
    fusion_weights,
    jitter_times,
    keep_masks,
    pnl_es,
    pnl_es_sampled,
)
from edeflare.sim.dvs import IdealParams, IdealSimulator, simulate_frames

SIZE = (32, 24)


def left_half(value: float, size=SIZE) -> np.ndarray:
    """An (H, W) map equal to ``value`` on the left half of the sensor and 0 elsewhere."""
    width, height = size
    out = np.zeros((height, width))
    out[:, : width // 2] = value
    return out


# ------------------------------------------------------------------------------- PNL-ES


def test_bright_flare_drops_nearly_every_background_event_there(rng):
    bg = random_events(rng, 20_000, SIZE, span_us=50_000)
    flare = random_events(rng, 5_000, SIZE, span_us=50_000)
    i_f = left_half(1e6)  # I_f >> I_bg = 10 on the left, 0 on the right
    out = pnl_es([bg, flare], [ConstantIntensity(10.0), ConstantIntensity(i_f)], rng=rng)
    left = out["x"] < SIZE[0] // 2
    # Every flare event on the left survives (w_f ~ 1), background ones there do not.
    n_bg_left = int((bg["x"] < SIZE[0] // 2).sum())
    n_flare_left = int((flare["x"] < SIZE[0] // 2).sum())
    assert n_flare_left <= int(left.sum()) <= n_flare_left + 0.001 * n_bg_left + 3
    # On the right the background is untouched and the flare vanishes.
    right_bg = bg[bg["x"] >= SIZE[0] // 2]
    assert same_events(out[~left], right_bg)


def test_zero_flare_intensity_returns_the_background_exactly(rng):
    bg = random_events(rng, 5_000, SIZE, span_us=50_000)
    flare = random_events(rng, 3_000, SIZE, span_us=50_000)
    out = pnl_es([bg, flare], [ConstantIntensity(7.0), ConstantIntensity(0.0)], rng=rng)
    assert same_events(out, bg)


def test_expected_kept_count_is_the_sum_of_weights(rng):
    """Kept count ~ Binomial sums: mean sum(w), variance sum(w (1 - w)); z-scores over seeds."""
    bg = random_events(rng, 4_000, SIZE, span_us=10_000)
    flare = random_events(rng, 4_000, SIZE, span_us=10_000)
    i_bg = rng.uniform(0.1, 10.0, (SIZE[1], SIZE[0]))
    i_f = rng.uniform(0.1, 10.0, (SIZE[1], SIZE[0]))
    fields = [ConstantIntensity(i_bg), ConstantIntensity(i_f)]
    w_bg = i_bg[bg["y"], bg["x"]] / (i_bg + i_f)[bg["y"], bg["x"]]
    w_f = i_f[flare["y"], flare["x"]] / (i_bg + i_f)[flare["y"], flare["x"]]
    mean = w_bg.sum() + w_f.sum()
    sd = math.sqrt((w_bg * (1 - w_bg)).sum() + (w_f * (1 - w_f)).sum())
    z = np.array([(pnl_es([bg, flare], fields, rng=seed).size - mean) / sd for seed in range(60)])
    assert np.abs(z).max() < 5
    assert abs(z.mean()) < 5 / math.sqrt(z.size)  # the mean of 60 z-scores is N(0, 1/60)
    assert 0.5 < z.std() < 1.5


@pytest.mark.parametrize("n", [2, 3, 5])
def test_n_way_weights_sum_to_one(rng, n):
    events = random_events(rng, 500, SIZE)
    inten = rng.uniform(0, 5, (n, events.size))
    inten[:, :50] = 0.0  # all dark: fall back to the k shares
    k = [float(v) for v in rng.uniform(0.1, 2.0, n)]
    k[0] = rng.uniform(0, 1, (SIZE[1], SIZE[0]))  # a spatial map
    total = sum(fusion_weights(inten, i, events, k=k) for i in range(n))
    np.testing.assert_allclose(total, 1.0, rtol=1e-12)


def test_weights_match_the_formula_and_fall_back_to_k_shares():
    inten = np.array([[2.0, 0.0, 0.0], [6.0, 3.0, 0.0]])
    np.testing.assert_allclose(fusion_weights(inten, 0, k=(3.0, 1.0)), [0.5, 0.0, 0.75])
    np.testing.assert_allclose(fusion_weights(inten, 1, k=(3.0, 1.0)), [0.5, 1.0, 0.25])
    # Zero coefficient and zero intensity everywhere: nothing is kept.
    assert fusion_weights(np.zeros((2, 1)), 0, k=(0.0, 0.0)).tolist() == [0.0]
    # The same through pnl_es_sampled with given draws: u < w keeps.
    a = make_events([0, 1, 2], [0, 0, 0], [0, 0, 0], [1, 1, 1])
    b = make_events([1], [1], [0], [0])
    out = pnl_es_sampled(
        [a, b], [inten, np.array([[1.0], [3.0]])], k=(3.0, 1.0), uniforms=[[0.4, 0.1, 0.8], [0.9]]
    )
    assert out[["t", "x"]].tolist() == [(0, 0)]


def test_occlusion_map_hides_background_behind_the_occluder(rng):
    bg = random_events(rng, 3_000, SIZE)
    occluder = random_events(rng, 1_000, SIZE)
    visible = 1.0 - left_half(1.0)
    out = pnl_es(
        [bg, occluder],
        [ConstantIntensity(5.0), ConstantIntensity(3.0)],
        k=(visible, 1.0 - visible),
        rng=rng,
    )
    right = SIZE[0] // 2
    expected = merge_events(bg[bg["x"] >= right], occluder[occluder["x"] < right])
    assert same_events(out, expected)
    # A black occluder hides the background all the same.
    out = pnl_es(
        [bg, occluder[:0]],
        [ConstantIntensity(5.0), ConstantIntensity(0.0)],
        k=(visible, 1.0 - visible),
        rng=rng,
    )
    assert same_events(out, bg[bg["x"] >= right])


def test_output_contract_sorted_input_unchanged_deterministic(rng):
    a = random_events(rng, 2_000, SIZE)
    b = random_events(rng, 2_000, SIZE)
    a0, b0 = a.copy(), b.copy()
    fields = [ConstantIntensity(1.0), ConstantIntensity(2.0)]
    out1 = pnl_es([a, b], fields, rng=5)
    out2 = pnl_es([a, b], fields, rng=np.random.default_rng(5))
    check_events(out1, SIZE)
    assert same_events(out1, out2)
    assert not same_events(out1, pnl_es([a, b], fields, rng=6))
    assert same_events(a, a0) and same_events(b, b0)
    # Ties keep stream order: all of a's events at a time come before b's.
    ev = make_events([5], [0], [0], [1])
    fused = pnl_es([ev, ev], [ConstantIntensity(1.0)] * 2, uniforms=[[0.0], [0.0]])
    assert fused.size == 2


def test_empty_streams_and_keep_masks_with_given_uniforms():
    empty = np.empty(0, dtype=EVENT_DTYPE)
    assert pnl_es([empty, empty], [ConstantIntensity(1.0)] * 2, rng=0).size == 0
    ev = make_events([0, 1, 2], [0, 0, 0], [0, 0, 0], [1, 1, 1])
    inten = np.array([[1.0] * 3, [3.0] * 3])  # w = 0.25
    (mask,) = keep_masks([ev], [inten[:1]], uniforms=[np.array([0.1, 0.3, 0.99])])
    assert mask.tolist() == [True, True, True]  # one component: w = 1
    m_a, m_b = keep_masks(
        [ev, empty], [inten, np.zeros((2, 0))], uniforms=[np.array([0.1, 0.3, 0.2]), None]
    )
    assert m_a.tolist() == [True, False, True] and m_b.size == 0


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda ev: pnl_es([ev], [ConstantIntensity(1.0)] * 2), "one intensity field per stream"),
        (lambda ev: keep_masks([ev], [np.ones((1, 2))]), r"shape \(components, events\)"),
        (lambda ev: keep_masks([ev], [-np.ones((1, 3))]), "finite and >= 0"),
        (lambda ev: fusion_weights(np.ones((2, 3)), 2), r"index must be in \[0, 2\)"),
        (lambda ev: fusion_weights(np.ones((2, 3)), 0, k=(1.0,)), "one coefficient per component"),
        (lambda ev: fusion_weights(np.ones((2, 3)), 0, ev, k=(np.ones((1, 1)), 1.0)), "cover"),
        (
            lambda ev: fusion_weights(np.ones((2, 3)), 0, k=(np.ones((1, 1)), 1.0)),
            "need the events",
        ),
        (lambda ev: keep_masks([ev], [np.ones((1, 3))], uniforms=[[0.5]]), "uniforms"),
        (lambda ev: ConstantIntensity(np.ones(3)), "number >= 0 or an"),
        (lambda ev: VideoIntensity([0, 0], np.ones((2, 1, 1))), "strictly increasing"),
        (lambda ev: VideoIntensity([0, 1], np.ones((3, 1, 1))), "T = 2 frame times"),
    ],
)
def test_bad_input_raises_a_project_error(call, match):
    ev = make_events([0, 1, 2], [0, 1, 2], [0, 0, 0], [1, 0, 1])
    with pytest.raises(EdeflareError, match=match):
        call(ev)


# ---------------------------------------------------------------------- intensity fields


def test_video_intensity_interpolates_and_clamps():
    frames = np.stack([np.full((1, 2), 0.0), np.full((1, 2), 10.0), np.full((1, 2), 4.0)])
    video = VideoIntensity([100, 200, 300], frames)
    ev = make_events([0, 150, 200, 250, 999], [0, 1, 0, 1, 0], [0] * 5, [1] * 5)
    np.testing.assert_allclose(video.sample(ev), [0.0, 5.0, 10.0, 7.0, 4.0])


def test_accumulated_intensity_tracks_an_ideal_sensor_log_ramp():
    """Events of an ideal sensor on a log ramp: the estimate follows I(t) / I(0) within e^c."""
    c = 0.2
    sim = IdealSimulator((1, 1), IdealParams(c_on=c, c_off=c, log_eps=1e-9))
    times = np.arange(0, 20_001, 100)
    log_i = np.log(20.0) + 2.0 * np.sin(times / 4000.0)  # up and down: ON then OFF events
    events = simulate_frames(
        sim, [(int(t), np.exp([[v]])) for t, v in zip(times, log_i, strict=True)]
    )
    assert (events["p"] == 1).any() and (events["p"] == 0).any()
    params = AccumulationParams(contrast=c, base_level=20.0, time_resolution_us=100, smoothing_px=0)
    est = AccumulatedIntensity(events, (1, 1), 0, 20_001, params)
    probe = make_events(times, np.zeros_like(times), np.zeros_like(times), np.ones_like(times))
    err = np.log(est.sample(probe)) - log_i
    assert np.abs(err).max() <= c + 0.05


def test_accumulated_intensity_grid_smoothing_and_clip(rng):
    ev = make_events([10] * 40, [4] * 40, [4] * 40, [1] * 40)  # 40 ON events at one pixel
    p = AccumulationParams(contrast=0.2, base_level=10.0, time_resolution_us=100, max_log=3.0)
    est = AccumulatedIntensity(ev, (9, 9), 0, 1000, p)
    assert est.log_intensity.shape == (11, 9, 9)
    assert est.log_intensity[0].max() == 0.0  # nothing before the first event
    # Smoothing (sigma 1 px) spreads the 40 events: the centre keeps about 1 / (2 pi).
    assert est.log_intensity[-1, 4, 4] == pytest.approx(40 * 0.2 / (2 * math.pi), rel=0.05)
    assert est.log_intensity[-1, 4, 5] > 0
    sharp = AccumulatedIntensity(ev, (9, 9), 0, 1000, AccumulationParams(smoothing_px=0))
    assert sharp.log_intensity[-1, 4, 5] == 0
    assert sharp.log_intensity[-1, 4, 4] == pytest.approx(3.0)  # 40 * 0.2 clipped at 3
    assert np.array_equal(sharp.times_us, np.arange(0, 1001, 1000))
    assert sharp.sample(ev[:1])[0] == pytest.approx(30.0 * math.exp(3.0 * 10 / 1000))
    with pytest.raises(EdeflareError, match="unknown key"):
        AccumulationParams.from_dict({"contrast": 0.2, "bse_level": 3})
    with pytest.raises(EdeflareError, match="t_end_us > t_start_us"):
        AccumulatedIntensity(ev, (9, 9), 10, 10)


def test_count_intensity_is_the_per_pixel_count(rng):
    ev = random_events(rng, 3_000, SIZE)
    counts = CountIntensity(ev, SIZE)
    expected = np.bincount(ev["y"].astype(int) * SIZE[0] + ev["x"], minlength=SIZE[0] * SIZE[1])
    assert np.array_equal(counts.counts.reshape(-1), expected)
    assert np.array_equal(counts.sample(ev), expected[ev["y"].astype(int) * SIZE[0] + ev["x"]])


# ------------------------------------------------------------------------------- pairs


def _components(rng, i_flare, i_light, n=6_000):
    bg = random_events(rng, n, SIZE, span_us=40_000)
    flare = random_events(rng, n // 2, SIZE, span_us=40_000)
    light = random_events(rng, n // 10, SIZE, span_us=40_000)
    fields = {
        "background": ConstantIntensity(10.0),
        "flare": ConstantIntensity(i_flare),
        "light": ConstantIntensity(i_light),
    }
    return Components.from_fields(
        {"background": bg, "flare": flare, "light": light}, fields, 0, 40_000
    )


def test_pair_shares_background_draws(rng):
    # Flare and light equally dark at the right half: the same background events survive there.
    flare_map = left_half(30.0)
    light_map = left_half(5.0)
    comp = _components(rng, flare_map, light_map)
    ob, gt = compose_pair(comp, rng=1)
    bg = comp.events["background"]
    right = lambda ev: ev[ev["x"] >= SIZE[0] // 2]  # noqa: E731
    # Only background events live on the right (w_f = w_light = 0 there), all of them.
    assert same_events(right(ob), right(bg)) and same_events(right(gt), right(bg))
    # On the left the flare (30) suppresses more than the light (5): input's background
    # events are a subset of the ground truth's, because both use one draw per event.
    key = lambda ev: set(zip(ev["t"].tolist(), ev["x"].tolist(), ev["y"].tolist(), strict=True))  # noqa: E731
    bg_keys = key(bg)
    ob_bg, gt_bg = key(ob) & bg_keys, key(gt) & bg_keys
    assert ob_bg < gt_bg
    # Independent thinning breaks the inclusion.
    ob_i, gt_i = compose_pair(comp, independent_background=True, rng=1)
    assert not (key(ob_i) & bg_keys) <= (key(gt_i) & bg_keys)


def test_variants(rng):
    comp = _components(rng, left_half(30.0), left_half(5.0))
    bg, fl, li = (comp.events[k] for k in ("background", "flare", "light"))
    ob, gt = compose_pair(comp, "simple", rng=0)
    assert same_events(ob, merge_events(bg, fl)) and same_events(gt, merge_events(bg, li))
    ob_p, _ = compose_pair(comp, "physical", rng=3)
    ob_n, gt_n = compose_pair(comp, "no-light", rng=3)
    assert same_events(ob_n, ob_p) and same_events(gt_n, bg)
    # +random: the same kept events (draws come first), times moved by at most the jitter.
    for base in ("simple", "physical"):
        ob_b, gt_b = compose_pair(comp, base, rng=3)
        ob_r, gt_r = compose_pair(comp, f"{base}+random", jitter_us=500, rng=3)
        for b, r in ((ob_b, ob_r), (gt_b, gt_r)):
            check_events(r, SIZE)
            assert b.size == r.size and not same_events(b, r)
            assert sorted(b[["x", "y", "p"]].tolist()) == sorted(r[["x", "y", "p"]].tolist())
            assert abs(int(b["t"].sum()) - int(r["t"].sum())) <= 500 * b.size
    assert set(VARIANTS) == {"physical", "simple", "simple+random", "physical+random", "no-light"}
    with pytest.raises(EdeflareError, match="variant must be one of"):
        compose_pair(comp, "phyiscal")


def test_components_check_their_intensities(rng):
    comp = _components(rng, 1.0, 1.0)
    bad = {c: dict(v) for c, v in comp.intensity.items()}
    bad["flare"]["background"] = bad["flare"]["background"][:-1]
    with pytest.raises(EdeflareError, match=r"intensity\['flare'\]\['background'\]"):
        Components(comp.events, bad, 0, 40_000)
    with pytest.raises(EdeflareError, match="components need a 'flare' stream"):
        Components({"background": comp.events["background"]}, comp.intensity, 0, 1)


def test_jitter_times_stays_in_the_sequence(rng):
    ev = random_events(rng, 1_000, SIZE, span_us=1_000)
    out = jitter_times(ev, 300, 0, 1_000, rng=0)
    check_events(out)
    assert out["t"].min() >= 0 and out["t"].max() < 1_000
    assert jitter_times(ev, 0, 0, 1_000, rng=0)["t"].tolist() == ev["t"].tolist()


# ------------------------------------------------------------------------ forward model


def _ramp_video(size, n_frames=200, dt_us=100, flare_level=90.0):
    """A background rising from 10 to 10 e^2 (log-linear) under a static flare on the left."""
    width, height = size
    flare = left_half(flare_level, size)
    for i in range(n_frames + 1):
        bg = np.full((height, width), 10.0 * math.exp(2.0 * i / n_frames))
        yield i * dt_us, bg, flare, np.zeros((height, width))


def test_forward_model_without_flare_is_the_background_alone():
    size, p = (8, 4), IdealParams(c_on=0.1, c_off=0.1)
    frames = [(t, bg, np.zeros_like(bg), light) for t, bg, _, light in _ramp_video(size)]
    ob, gt = forward_pair(frames, IdealSimulator(size, p), IdealSimulator(size, p))
    alone = simulate_frames(IdealSimulator(size, p), [(t, bg) for t, bg, _, _ in frames])
    assert same_events(ob, alone) and same_events(gt, alone)


def test_pnl_es_matches_the_forward_model_in_expectation_on_a_log_ramp():
    """sum_k w(t_k) c ~ Delta log(I_bg + I_f): PNL-ES keeps as many events as physics makes."""
    size, c = (16, 8), 0.05
    p = IdealParams(c_on=c, c_off=c, log_eps=1e-9)
    frames = list(_ramp_video(size))
    ob, _ = forward_pair(frames, IdealSimulator(size, p), IdealSimulator(size, p))
    bg = simulate_frames(IdealSimulator(size, p), [(t, b) for t, b, _, _ in frames])
    times = np.array([t for t, *_ in frames])
    video_bg = VideoIntensity(times, np.stack([b for _, b, _, _ in frames]))
    fused = pnl_es([bg, bg[:0]], [video_bg, ConstantIntensity(left_half(90.0, size))], rng=0)
    n_left = (size[0] // 2) * size[1]
    per_pixel = lambda ev: (ev["x"] < size[0] // 2).sum() / n_left  # noqa: E731
    physics = math.log((10 * math.e**2 + 90) / 100) / c  # 9.9 thresholds crossed
    assert per_pixel(bg) == pytest.approx(2.0 / c, abs=1)  # 40 without the flare
    assert per_pixel(ob) == pytest.approx(physics, abs=1)  # forward: 9 (whole crossings)
    assert per_pixel(fused) == pytest.approx(physics, rel=0.1)  # PNL-ES: ~ sum of weights
    # Right half (no flare): both keep the background as is.
    assert (ob["x"] >= size[0] // 2).sum() == (bg["x"] >= size[0] // 2).sum()
