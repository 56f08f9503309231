"""Tests of edeflare.sim.dvs: the DVS-Voltmeter and ideal log-intensity simulators."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from edeflare.events import EVENT_DTYPE, check_events
from edeflare.sim._buffer import new_buffers
from edeflare.sim._validation import SimError
from edeflare.sim._voltmeter import p_on_first, sample_first_passage
from edeflare.sim.dvs import (
    DVS346_K,
    IdealParams,
    IdealSimulator,
    VoltmeterParams,
    VoltmeterSimulator,
    draw_thresholds,
    make_simulator,
    simulate_frames,
)

K1, K2, K3, K4, K5, K6 = DVS346_K


def video(values, shape=(6, 8), dt_us=1000, t0=0):
    """``(t_us, frame)`` pairs of spatially uniform frames with the given values."""
    return [(t0 + i * dt_us, np.full(shape, v, dtype=np.float64)) for i, v in enumerate(values)]


def run(sim, frames):
    events = simulate_frames(sim, frames)
    check_events(events, sim.sensor_size)
    return events


def per_pixel(events, sensor_size):
    width, height = sensor_size
    flat = events["y"].astype(np.int64) * width + events["x"]
    return np.bincount(flat, minlength=width * height).reshape(height, width)


# --------------------------------------------------------------------------- ideal


def log_ramp(delta, n_frames=101, dt_us=1000, base=20.0, eps=1.0, shape=(6, 8)):
    """Frames whose ``log(L + eps)`` rises linearly by ``delta`` over the clip."""
    ell = math.log(base + eps) + delta * np.arange(n_frames) / (n_frames - 1)
    return video(np.exp(ell) - eps, shape, dt_us)


def test_ideal_constant_light_gives_no_events(rng):
    sim = IdealSimulator((8, 6), IdealParams(c_sigma=0.05), rng=rng)
    scene = rng.uniform(0, 255, (6, 8))
    scene[0, :] = 0.0
    scene[1, :] = 255.0
    events = run(sim, [(i * 500, scene) for i in range(50)])
    assert events.size == 0


def test_ideal_log_ramp_gives_exact_count_and_times():
    # log rises by 1.3 over 100 ms with C = 0.2: floor(6.5) = 6 ON events per pixel at
    # t_j = j * 0.2 / 1.3 * 100 ms = 15384.6 j µs.
    sim = IdealSimulator((8, 6), IdealParams(c_on=0.2, c_off=0.2, log_eps=1.0))
    events = run(sim, log_ramp(1.3))
    assert events.size == 6 * 48
    assert (events["p"] == 1).all()
    expected = [round(j * 0.2 / 1.3 * 100_000) for j in range(1, 7)]
    assert expected == [15385, 30769, 46154, 61538, 76923, 92308]
    assert np.array_equal(np.unique(events["t"]), expected)
    assert (per_pixel(events, (8, 6)) == 6).all()


def test_ideal_falling_ramp_uses_the_off_threshold():
    sim = IdealSimulator((8, 6), IdealParams(c_on=0.2, c_off=0.3))
    events = run(sim, log_ramp(-1.0))  # floor(1.0 / 0.3) = 3 OFF events per pixel
    assert events.size == 3 * 48
    assert (events["p"] == 0).all()


def test_ideal_polarity_follows_the_sign_of_the_change():
    sim = IdealSimulator((8, 6), IdealParams(c_on=0.25, c_off=0.25))
    events = run(sim, video([10, 10, 40, 40, 5, 5]))
    on, off = events[events["p"] == 1], events[events["p"] == 0]
    # log(41/11) = 1.316 -> 5 ON in (1, 2] ms; back down to log(6/41) = -1.922 -> 7 OFF in (3, 4] ms
    assert on.size == 5 * 48 and off.size == 7 * 48
    assert on["t"].min() > 1000 and on["t"].max() <= 2000
    assert off["t"].min() > 3000 and off["t"].max() <= 4000


def test_ideal_refractory_period_drops_events_but_moves_the_reference():
    # The ramp's crossings are 15.4 ms apart; with a 20 ms refractory period every second
    # one is dropped: 15385, 46154 and 76923 µs remain.
    sim = IdealSimulator((1, 1), IdealParams(c_on=0.2, refractory_us=20_000))
    events = run(sim, log_ramp(1.3, shape=(1, 1)))
    assert events["t"].tolist() == [15385, 46154, 76923]


def test_ideal_threshold_mismatch_sets_per_pixel_counts(rng):
    params = IdealParams(c_on=0.2, c_sigma=0.03)
    thresholds = draw_thresholds((8, 6), params, rng=rng)
    sim = IdealSimulator((8, 6), params, thresholds=thresholds)
    events = run(sim, log_ramp(1.3))
    expected = np.floor(1.3 / thresholds[0]).astype(int)
    assert np.unique(expected).size > 1
    assert np.array_equal(per_pixel(events, (8, 6)), expected)


def test_ideal_background_noise_rate_and_hot_pixels():
    size = (64, 64)  # 0.2 s of frames
    params = IdealParams(noise_rate_hz=5.0, hot_pixel_fraction=0.01, hot_pixel_rate_hz=1000.0)
    sim = IdealSimulator(size, params, rng=3)
    events = run(sim, video(np.full(201, 100.0), (64, 64)))
    hot = np.zeros(64 * 64, dtype=bool)
    hot[sim.hot_pixels] = True
    flat = events["y"].astype(np.int64) * 64 + events["x"]
    from_hot = hot[flat]
    n_hot = sim.hot_pixels.size
    assert 20 < n_hot < 70  # 1 % of 4096 = 41
    # Poisson counts: 5 Hz * 4096 px * 0.2 s = 4096 noise events, 200 per hot pixel.
    n_noise = int((~from_hot).sum())
    assert abs(n_noise - 4096 * (1 - n_hot / 4096)) < 5 * math.sqrt(4096)
    assert abs(int(from_hot.sum()) - 200 * n_hot) < 5 * math.sqrt(200 * n_hot) + 5 * math.sqrt(4096)
    assert 0.45 < events["p"].mean() < 0.55
    assert events["t"].min() >= 0 and events["t"].max() <= 200_000


def test_ideal_is_deterministic_for_a_seed():
    params = IdealParams(c_sigma=0.02, noise_rate_hz=50.0)
    clip = log_ramp(0.8)
    a = run(IdealSimulator((8, 6), params, rng=11), clip)
    b = run(IdealSimulator((8, 6), params, rng=11), clip)
    c = run(IdealSimulator((8, 6), params, rng=12), clip)
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()


# --------------------------------------------------------------------------- Voltmeter model


def test_p_on_first_matches_the_formula_and_its_limits():
    def direct(mu, sigma, a, b):
        e = 2 * mu / sigma**2
        return (math.exp(e * b) - 1) / (math.exp(e * b) - math.exp(-e * a))

    for mu, sigma, a, b in [(1e-6, 1e-3, 0.4, 1.6), (-2e-6, 1e-3, 0.9, 1.1), (3e-7, 4e-4, 1, 1)]:
        assert p_on_first(mu, sigma, a, b) == pytest.approx(direct(mu, sigma, a, b), rel=1e-12)
    assert p_on_first(0.0, 1e-5, 0.3, 1.7) == pytest.approx(0.85)  # B / (A + B)
    assert p_on_first(1e-3, 1e-5, 1.0, 1.0) == 1.0  # exp(2e7) overflows: the limit
    assert p_on_first(-1e-3, 1e-5, 1.0, 1.0) == 0.0
    assert p_on_first(1e-3, 0.0, 1.0, 1.0) == 1.0  # no diffusion: the drift decides
    assert p_on_first(1e-3, 1e-5, 1.0, 0.0) == 0.0  # already at the OFF threshold


def test_passage_time_towards_the_drift_is_inverse_gaussian():
    eps, drift, sigma = 0.5, 1e-4, 2e-3
    m, lam = eps / drift, (eps / sigma) ** 2  # mean 5000 µs, shape 62500 µs
    x = sample_first_passage(100_000, eps, drift, sigma, False, 1)
    assert stats.kstest(x, stats.invgauss(m / lam, scale=lam).cdf).pvalue > 1e-3
    assert x.mean() == pytest.approx(m, rel=0.01)
    assert x.var() == pytest.approx(m**3 / lam, rel=0.03)


def test_exact_passage_time_against_the_drift_is_the_conditioned_law():
    eps, drift, sigma = 0.02, -1e-5, 1e-3
    m, lam = eps / abs(drift), (eps / sigma) ** 2
    x = sample_first_passage(100_000, eps, drift, sigma, True, 2)
    assert stats.kstest(x, stats.invgauss(m / lam, scale=lam).cdf).pvalue > 1e-3


def test_original_passage_time_against_the_drift_matches_its_recipe():
    """The original: a normal truncated to X <= -sqrt(4 eps |c| / s^2) through the IG transform."""
    eps, drift, sigma = 2e-3, -3e-7, 2e-5  # the regime of the golden edge video: T = 6
    n = 100_000
    bound = -math.sqrt(4 * eps * -drift / sigma**2)
    gen = np.random.default_rng(5)
    xn = stats.truncnorm.rvs(-np.inf, bound, size=n, random_state=gen)
    mean = eps / drift
    lam = (eps / sigma) ** 2
    y = mean * xn * xn
    root = mean + mean / 2 / lam * (y - np.sqrt(4 * lam * y + y * y))
    u = gen.random(n)
    recipe = np.where(u > mean / (mean + root), mean * mean / root, root)
    ours = sample_first_passage(n, eps, drift, sigma, False, 3)
    assert np.isfinite(ours).all() and (ours > 0).all() and (ours <= eps / -drift).all()
    assert stats.ks_2samp(ours, recipe).pvalue > 1e-3
    exact = sample_first_passage(n, eps, drift, sigma, True, 3)
    assert stats.ks_2samp(exact, recipe).pvalue < 1e-6  # the two laws really differ


def test_passage_times_stay_finite_in_extreme_regimes():
    for eps, drift, sigma in [
        (1.0, -1e-2, 1e-7),
        (1e-12, 1.0, 1e-9),
        (1.0, 1e-12, 1.0),
        (1.0, 0.0, 1e-5),
    ]:
        for exact in (False, True):
            x = sample_first_passage(1000, eps, drift, sigma, exact, 9)
            assert not np.isnan(x).any() and (x >= 0).all()


# --------------------------------------------------------------------------- Voltmeter simulator


def test_voltmeter_constant_light_fires_only_through_the_leak():
    # At L = 255 the leak drift is k4 + k5 * 255 = 1.375e-6 per µs: each pixel reaches the ON
    # threshold once, after about 1 / 1.375e-6 = 727,273 µs. At L = 0 it takes 1 / k4 = 10 s.
    mu = K4 + K5 * 255
    sim = VoltmeterSimulator((16, 8), rng=0)
    scene = np.full((8, 16), 255.0)
    scene[:4] = 0.0
    events = run(sim, [(i * 1000, scene) for i in range(1001)])
    assert (events["p"] == 1).all()
    assert (events["y"] >= 4).all()
    assert events.size == 64  # one per bright pixel
    assert events["t"].mean() == pytest.approx(1 / mu, rel=0.01)
    assert events["t"].std() < 0.01 / mu


def voltage_of(values, dt_us):
    """The model's total drift voltage for a uniform clip (the sum of mu * dt over intervals)."""
    v = np.asarray(values, dtype=np.float64)
    avg = (v[1:] + v[:-1]) / 2
    return float(np.sum(K1 * np.diff(v) / (avg + K2) + (K4 + K5 * avg) * dt_us))


def test_voltmeter_ramp_count_is_the_integrated_drift():
    # An exponential ramp 30 -> 220 over 150 ms: V = sum k1 dL / (L + k2) + leak, about
    # k1 ln(240 / 50) = 8.259 plus (k4 + k5 * mean L) * 150 ms = 0.087, so 8.35 thresholds.
    # The diffusion adds about sigma * sqrt(T) = 0.01, so every pixel fires floor(V) = 8 ON.
    values = 30 * (220 / 30) ** (np.arange(151) / 150)
    v = voltage_of(values, 1000)
    assert v == pytest.approx(8.35, abs=0.01)
    sim = VoltmeterSimulator((16, 8), rng=4)
    events = run(sim, video(values, (8, 16)))
    assert (events["p"] == 1).all()
    assert (per_pixel(events, (16, 8)) == 8).all()
    assert np.allclose(sim.residual, v - 8, atol=0.01)


def test_voltmeter_polarity_follows_the_sign_of_the_change():
    sim = VoltmeterSimulator((8, 6), rng=1)
    events = run(sim, video([50, 50, 150, 150, 40, 40]))
    on, off = events[events["p"] == 1], events[events["p"] == 0]
    assert on.size > 0 and off.size > 0
    assert on["t"].min() >= 1000 and on["t"].max() <= 2000
    assert off["t"].min() >= 3000 and off["t"].max() <= 4000
    # 50 -> 150: k1 * 100 / (100 + 20) = 4.39 thresholds: 4 ON, residual 0.39. 150 -> 40:
    # k1 * 110 / (95 + 20) = 5.04 down; the first OFF needs 1.39 of it, then one per
    # threshold: 1 + floor(5.04 - 1.39) = 4 OFF (the threshold memory of the model).
    assert (per_pixel(on, (8, 6)) == 4).all()
    assert (per_pixel(off, (8, 6)) == 4).all()


def test_voltmeter_is_deterministic_for_a_seed():
    clip = video(40 + 20 * np.sin(np.arange(60) / 3), (6, 8))
    a = run(VoltmeterSimulator((8, 6), rng=7), clip)
    b = run(VoltmeterSimulator((8, 6), rng=7), clip)
    c = run(VoltmeterSimulator((8, 6), rng=8), clip)
    assert a.size > 100
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()


@pytest.mark.parametrize("model", ["voltmeter", "ideal"])
def test_output_does_not_depend_on_the_buffer_capacity(model):
    clip = video(40 + 30 * np.sin(np.arange(40) / 2), (6, 8))
    big = run(make_simulator(model, (8, 6), rng=5), clip)
    sim = make_simulator(model, (8, 6), rng=5)
    chunks = []
    for t_us, frame in clip:
        sim._buffers = list(new_buffers(1))  # forces the grow-and-resume path every frame
        chunks.append(sim.feed(frame, t_us))
    small = np.concatenate(chunks)
    assert big.size > 48 and big.tobytes() == small.tobytes()


@pytest.mark.parametrize("model", ["voltmeter", "ideal"])
def test_no_nan_or_stray_events_on_extreme_inputs(model):
    sim = make_simulator(model, (8, 6), rng=0)
    values = [0, 0, 255, 255, 0, 1e6, 0, 1e6, 1e6, 0.0, 255]
    times = [0, 1, 2, 1000, 1001, 1002, 5000, 5001, 9000, 9001, 10**9]
    events = run(sim, [(t, np.full((6, 8), v)) for t, v in zip(times, values, strict=True)])
    assert events.dtype == EVENT_DTYPE and events.size > 0
    assert events["t"].min() >= 1 and events["t"].max() <= 10**9
    if model == "voltmeter":
        assert np.isfinite(sim.residual).all()
        assert (np.abs(sim.residual) <= 1).all()


@pytest.mark.parametrize("model", ["voltmeter", "ideal"])
def test_events_of_each_frame_lie_in_its_interval_and_are_sorted(model, rng):
    sim = make_simulator(model, (10, 7), rng=rng)
    for i in range(30):
        t_prev = sim.t_us
        ev = sim.feed(rng.uniform(0, 255, (7, 10)), i * 833)
        check_events(ev, (10, 7))
        if ev.size:
            assert ev["t"].min() >= t_prev and ev["t"].max() <= i * 833


@pytest.mark.parametrize("model", ["voltmeter", "ideal"])
def test_bad_frames_are_rejected_without_changing_the_state(model):
    sim = make_simulator(model, (4, 3), rng=0)
    sim.feed(np.full((3, 4), 10.0), 0)
    with pytest.raises(SimError, match=r"shape \(height, width\) = \(3, 4\), got \(4, 3\)"):
        sim.feed(np.zeros((4, 3)), 10)
    bad = np.full((3, 4), 10.0)
    bad[1, 2] = np.nan
    bad[0, 0] = -1.0
    with pytest.raises(SimError, match="2 negative, NaN or infinite"):
        sim.feed(bad, 10)
    with pytest.raises(SimError, match="must increase: got t_us=0 after 0"):
        sim.feed(np.full((3, 4), 10.0), 0)
    with pytest.raises(SimError, match="t_us must be an int"):
        sim.feed(np.full((3, 4), 10.0), 1.5)
    assert sim.t_us == 0
    assert sim.feed(np.full((3, 4), 10.0), 10).size == 0 or model == "voltmeter"


def test_parameters_are_validated():
    with pytest.raises(SimError, match="six finite numbers"):
        VoltmeterParams(k=(1, 2, 3))
    with pytest.raises(SimError, match="against_drift must be one of 'original', 'exact'"):
        VoltmeterParams(against_drift="fast")
    with pytest.raises(SimError, match=r"unknown key\(s\) \['c_of'\]"):
        IdealParams.from_dict({"c_of": 0.3})
    with pytest.raises(SimError, match=r"c_on must lie in \(0"):
        IdealParams(c_on=0)
    with pytest.raises(SimError, match="model must be one of 'voltmeter', 'ideal'"):
        make_simulator("esim", (4, 4))
    assert VoltmeterParams.from_dict(VoltmeterParams().to_dict()) == VoltmeterParams()
    assert IdealParams.from_dict(IdealParams(c_on=0.3).to_dict()) == IdealParams(c_on=0.3)


def test_uint8_and_float_frames_give_the_same_events(rng):
    frames = rng.integers(0, 256, (20, 5, 6)).astype(np.uint8)
    a = run(VoltmeterSimulator((6, 5), rng=2), [(i * 1000, f) for i, f in enumerate(frames)])
    b = run(
        VoltmeterSimulator((6, 5), rng=2),
        [(i * 1000, f.astype(np.float32)) for i, f in enumerate(frames)],
    )
    assert a.size > 0 and a.tobytes() == b.tobytes()


# --------------------------------------------------------------------------- warm start


def test_ideal_warm_start_fires_a_sub_threshold_ramp_in_proportion():
    # a rise of 0.06 in log intensity with C_on = 0.2: from a cold start no pixel reaches
    # its ON threshold; from a warm one (log - ref uniform in (0, 0.2) where the light
    # rises) the pixels within 0.06 of it do, 0.06 / 0.2 = 30 % of them, once each, all ON
    shape = (100, 100)
    params = IdealParams(c_on=0.2, c_off=0.2, log_eps=1.0)
    cold = run(IdealSimulator((100, 100), params, rng=1), log_ramp(0.06, shape=shape))
    warm = run(
        IdealSimulator((100, 100), params, rng=1, warm_start=True), log_ramp(0.06, shape=shape)
    )
    assert cold.size == 0
    n = shape[0] * shape[1]
    assert abs(warm.size / n - 0.3) <= 4 * math.sqrt(0.3 * 0.7 / n)
    assert (warm["p"] == 1).all()
    assert per_pixel(warm, (100, 100)).max() == 1


def test_ideal_warm_start_fires_the_long_run_count():
    # a rise of 1.3 is 6.5 thresholds of 0.2: a cold start fires exactly 6 a pixel
    # (test_ideal_log_ramp_gives_exact_count_and_times), a warm one 6 or 7, 6.5 on average
    sim = IdealSimulator((40, 40), IdealParams(c_on=0.2, c_off=0.2), rng=2, warm_start=True)
    counts = per_pixel(run(sim, log_ramp(1.3, shape=(40, 40))), (40, 40))
    assert set(np.unique(counts)) == {6, 7}
    assert abs(counts.mean() - 6.5) <= 4 * math.sqrt(0.25 / counts.size)


def test_ideal_warm_start_falling_uses_the_off_side():
    # a fall of 0.06 with C_off = 0.3: 0.06 / 0.3 = 20 % of the pixels fire one OFF event
    params = IdealParams(c_on=0.2, c_off=0.3, log_eps=1.0)
    frames = [(t, np.exp(np.log(21.0) - 0.06 * t / 100_000) - 1.0 + np.zeros((80, 80)))
              for t in range(0, 100_001, 1000)]  # fmt: skip
    ev = run(IdealSimulator((80, 80), params, rng=5, warm_start=True), frames)
    assert (ev["p"] == 0).all()
    assert abs(ev.size / 6400 - 0.2) <= 4 * math.sqrt(0.2 * 0.8 / 6400)


def test_voltmeter_warm_start_residuals_by_the_first_drift():
    # constant light: the drift is the leak, k4 + k5 L > 0, so every residual starts
    # uniformly on the ON side; a falling light (k1 dL/dt / (L + k2) far below -leak) on
    # the OFF side; the same with the leak set to 0 and constant light: across both
    still = VoltmeterSimulator((64, 64), rng=3, warm_start=True)
    cold = VoltmeterSimulator((64, 64), rng=3)
    for sim in (still, cold):  # 1 µs of constant light: the dynamics barely move r
        run(sim, video([40.0, 40.0], shape=(64, 64), dt_us=1))
    assert np.abs(cold.residual).max() < 0.05
    r = still.residual.ravel()
    assert (r > 0).all() and (r < 1).all()
    assert stats.kstest(r, stats.uniform(loc=0, scale=1).cdf).pvalue > 1e-3
    falling = VoltmeterSimulator((64, 64), rng=3, warm_start=True)
    run(falling, video([40.0, 39.999], shape=(64, 64), dt_us=1))
    assert (falling.residual < 0).all() and (falling.residual > -1).all()
    no_leak = VoltmeterParams(k=(K1, K2, K3, 0.0, 0.0, K6))
    held = VoltmeterSimulator((64, 64), no_leak, rng=3, warm_start=True)
    run(held, video([40.0, 40.0], shape=(64, 64), dt_us=1))
    assert stats.kstest(held.residual.ravel(), stats.uniform(loc=-1, scale=2).cdf).pvalue > 1e-3
    # the per-pixel random streams start the same either way, and a seed repeats
    fresh = (VoltmeterSimulator((64, 64), rng=3, warm_start=w) for w in (False, True))
    assert np.array_equal(*(f._state for f in fresh))
    a, b = (VoltmeterSimulator((16, 16), rng=4, warm_start=True) for _ in range(2))
    frames = video([40.0, 44.0, 48.0], shape=(16, 16))
    assert np.array_equal(run(a, frames), run(b, frames))


def test_make_simulator_passes_the_warm_start():
    frames = video([40.0, 40.001], shape=(8, 8), dt_us=1)
    volt = make_simulator("voltmeter", (8, 8), rng=0, warm_start=True)
    run(volt, frames)
    assert (volt.residual > 0).all()
    assert make_simulator("ideal", (8, 8), rng=0, warm_start=True).warm_start is True
