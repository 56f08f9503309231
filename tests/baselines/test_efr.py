"""Tests of edeflare.baselines.efr: golden outputs of the original, hand traces, known answers."""

from __future__ import annotations

import numpy as np
import pytest
from baseline_helpers import (
    as_tuples,
    background_noise,
    efr_reference,
    flicker_block,
    merge,
    moving_edge,
)

from conftest import random_events
from edeflare.baselines.efr import EFRFilter, efr, efr_bias, efr_delays
from edeflare.errors import EventsError, ParameterError
from edeflare.events import EVENT_DTYPE, make_events, sort_events
from edeflare.io import read_events

# --------------------------------------------------------------------------------------
# Golden outputs of the original program (ziweiWWANG/EFR @ a0e0189)

GOLDEN_EFR = [
    # input, base frequency, output events, ON outputs
    ("mix640", 50, 55_502, 44_851),
    ("mix640", 120, 80_348, 41_403),
    ("davis346_lamps", 50, 13_791, 7_719),
]


def load_npz(path):
    with np.load(path) as z:
        events = np.empty(z["t"].size, dtype=EVENT_DTYPE)
        for k in "txyp":
            events[k] = z[k]
        return events, (int(z["width"]), int(z["height"]))


@pytest.mark.parametrize(("name", "frequency", "count", "on"), GOLDEN_EFR)
def test_reproduces_the_original_program_exactly(golden_data, name, frequency, count, on):
    events, size = load_npz(golden_data / f"{name}_input.npz")
    golden, _ = load_npz(golden_data / f"{name}_efr{frequency}_output.npz")
    out = efr(events, size, frequency, keep_warmup=False)
    assert out.size == golden.size == count
    assert int(out["p"].sum()) == on
    # Same multiset of (t, x, y, p), repeats included ...
    keys = ("p", "y", "x", "t")
    a = out[np.lexsort([out[k] for k in keys])]
    b = golden[np.lexsort([golden[k] for k in keys])]
    assert all(np.array_equal(a[k], b[k]) for k in "txyp")
    # ... and even the same sequence: emission order per pixel, stably sorted by time.
    assert all(np.array_equal(out[k], golden[k]) for k in "txyp")


def test_golden_with_the_papers_warmup_appends_the_first_22_ms(golden_data):
    events, size = load_npz(golden_data / "davis346_lamps_input.npz")
    golden, _ = load_npz(golden_data / "davis346_lamps_efr50_output.npz")
    out = efr(events, size, 50)  # default: keep the warm-up inputs
    warm = events[events["t"] < int(events["t"][0]) + 22_000]
    assert int(events["t"][0]) == 0 and warm.size == int((events["t"] < 22_000).sum()) > 20_000
    assert out.size == golden.size + warm.size
    early = out[out["t"] < 22_000]
    assert as_tuples(early) == as_tuples(warm)  # unchanged, same order
    late = out[out["t"] >= 22_000]
    assert as_tuples(late) == as_tuples(golden)  # the filter's own outputs all come later


def test_golden_outputs_lag_by_at_least_the_filter_delay(golden_data):
    events, size = load_npz(golden_data / "davis346_lamps_input.npz")
    out = efr(events, size, 50, keep_warmup=False)
    assert int(out["t"].min()) == 22_000  # README: first output at d1 + d2 = 22 ms


def test_bias_of_the_golden_inputs(golden_data):
    for name, n_pixels in (("mix640", 1816), ("davis346_lamps", 766)):
        events, size = load_npz(golden_data / f"{name}_input.npz")
        counts = np.bincount(
            events["y"].astype(np.int64) * size[0] + events["x"], minlength=size[0] * size[1]
        )
        bias = efr_bias(events, size)
        assert int((counts >= 20).sum()) == n_pixels
        assert np.count_nonzero(bias.reshape(-1)[counts < 20]) == 0


# --------------------------------------------------------------------------------------
# The plain-Python reference (written from the original's behaviour) on random streams


@pytest.mark.parametrize("frequency", [50, 120, 100])
@pytest.mark.parametrize("merge_us", [10_000, 0, 3_000])
def test_matches_the_reference_on_random_streams(rng, frequency, merge_us):
    size = (6, 5)
    n, span = (3000, 600_000) if merge_us else (200, 300_000)  # no merging: slow reference
    events = random_events(rng, n, size, t0=1_000, span_us=span)
    bias = efr_bias(events, size, min_events=10)
    expected = efr_reference(events, size, frequency, merge_us=merge_us, bias=bias)
    f = EFRFilter(size, frequency, merge_us=merge_us, bias=bias, keep_warmup=False)
    assert as_tuples(f.process(events)) == expected
    assert len(expected) > 20


def test_matches_the_reference_through_every_growth_path(rng):
    """Many pixels and small chunks: the pool and the output buffers grow mid-stream."""
    size = (64, 64)  # 4096 pixels: the 65536-entry pool must grow
    events = random_events(rng, 30_000, size, span_us=400_000)
    expected = efr_reference(events, size, 50)
    f = EFRFilter(size, 50, keep_warmup=False)
    got = np.concatenate([f.process(c) for c in np.array_split(events, 7)])
    assert as_tuples(got) == expected
    assert f._pool_t.size > 1 << 16


def test_matches_the_reference_with_long_queues(rng):
    """Without merging, q2 and q4 keep every value: they outgrow the 64-entry scratch rings."""
    events = make_events(
        np.sort(rng.integers(0, 300_000, 60)), [1] * 60, [0] * 60, rng.integers(0, 2, 60)
    )
    expected = efr_reference(events, (2, 1), 50, merge_us=0)
    f = EFRFilter((2, 1), 50, merge_us=0, keep_warmup=False)
    got = np.concatenate([f.process(c) for c in np.array_split(events, 3)])
    assert as_tuples(got) == expected
    queues, _ = f.pixel_state(1, 0)
    assert len(queues[1]) > 64 and len(queues[3]) > 64


@pytest.mark.parametrize("frequency", [50, 120])
def test_chunks_equal_one_pass(rng, frequency):
    size = (8, 8)
    events = random_events(rng, 5000, size, span_us=2_000_000)
    bias = efr_bias(events, size)
    whole = EFRFilter(size, frequency, bias=bias).process(events)
    f = EFRFilter(size, frequency, bias=bias)
    cuts = np.sort(rng.integers(0, events.size, 12))
    parts = [f.process(c) for c in np.split(events, cuts)]
    assert as_tuples(np.concatenate(parts)) == as_tuples(whole)


def test_safe_time_bounds_every_later_output(rng):
    size = (10, 10)
    events = random_events(rng, 20_000, size, span_us=3_000_000)
    f = EFRFilter(size, 50, bias=efr_bias(events, size))
    marks = []
    for start in range(0, 3_000_000, 20_000):
        window = events[(events["t"] >= start) & (events["t"] < start + 20_000)]
        out = f.process(window)
        for mark in marks:
            assert out.size == 0 or int(out["t"].min()) >= mark
        marks.append(f.safe_time_us(start + 20_000))
    assert max(marks) > 2_000_000  # and the bound moves on


# --------------------------------------------------------------------------------------
# Hand-traced sequences


def test_delays_as_the_original_derives_them():
    assert efr_delays(50) == (20_000, 2000.0)
    assert efr_delays(120) == (8333, 833.3)  # integer d1, fractional d2
    assert efr_delays(100) == (10_000, 1000.0)
    f = EFRFilter((1, 1), 120)
    assert (f.d1_us, f.d2_us, f.delay_us) == (8333, 833.3, 8333 + 833)
    assert f.rho2 == 1 - (1 - 0.6) / 10 == 0.96


def test_hand_traced_single_pixel():
    """One ON pixel at 0, 30 ms and 42 ms (zero bias), queue by queue."""
    f = EFRFilter((1, 1), 50, keep_warmup=False)
    assert f.process(make_events([0], [0], [0], [1])).size == 0
    queues, acc = f.pixel_state(0, 0)
    assert queues == [[(0, 1.0)], [(0, 1.0)], [], []] and acc == 0.0

    # 30 ms: q1 sends (0+d1, -1) to q2; q2's (0, 1) is d1 old: re-pushed as (20 ms, 0.6)
    # and sent to q3 -> q4; then -1 merges into q2's back entry (same time); the new
    # input (30 ms, 1) is 10 ms from the back: not < merge_us, so it is appended.
    assert f.process(make_events([30_000], [0], [0], [1])).size == 0
    queues, acc = f.pixel_state(0, 0)
    assert queues[0] == [(30_000, 1.0)]
    assert queues[1] == [(20_000, 0.6 * 1.0 + -1.0), (30_000, 1.0)]
    assert queues[2] == [(20_000, 0.6)]
    assert queues[3] == [(20_000, 0.6)]
    assert acc == 0.0

    # 42 ms: q2's (20 ms, -0.4) is due: (40 ms, -0.24) goes to q3, whose (20 ms, 0.6) is
    # d2 old: (22 ms, -0.96 * 0.6) goes to q4 after q4 cycles its (20 ms, 0.6) once
    # (acc 0.6 < 0.7) and merges into it; then (40 ms, -0.24) reaches q4, which cycles
    # its (22 ms, 0.024) entry nine times: acc crosses 0.7 at 32 ms -> one ON output.
    out = f.process(make_events([42_000], [0], [0], [1]))
    assert as_tuples(out) == [(32_000, 0, 0, 1)]
    queues, acc = f.pixel_state(0, 0)
    q4_value = 0.6 + -0.96 * 0.6
    expected_acc = 0.6
    for _ in range(9):
        expected_acc += q4_value
        if expected_acc >= 0.7:
            expected_acc -= 0.7
    assert queues[3] == [(40_000, q4_value + 0.6 * (0.6 * 1.0 + -1.0))]
    assert queues[1] == [(30_000, 1.0), (40_000, 0.6 * (0.6 * 1.0 + -1.0) + 1.0)]
    assert queues[2] == [(40_000, 0.6 * (0.6 * 1.0 + -1.0))]
    assert acc == expected_acc


def test_outputs_need_a_later_event_at_the_same_pixel():
    """Queues advance only while their own pixel gets events; nothing is flushed."""
    ev = make_events([0, 30_000, 42_000], [0] * 3, [0] * 3, [1] * 3)
    assert efr(ev[:2], (2, 1), 50, keep_warmup=False).size == 0
    assert efr(ev, (2, 1), 50, keep_warmup=False).size == 1
    # The same third event at another pixel moves nothing at pixel 0.
    other = ev.copy()
    other["x"][2] = 1
    assert efr(other, (2, 1), 50, keep_warmup=False).size == 0


@pytest.mark.parametrize("gap", [833, 834])
def test_fractional_d2_is_due_at_834_and_forwards_by_833(gap):
    """At 120 Hz (d2 = 833.3) a q3/q4 entry is due once 834 µs old; it moves on by 833."""
    ev = make_events([0, gap, 10_000], [0] * 3, [0] * 3, [1] * 3)
    f = EFRFilter((1, 1), 120, merge_us=100, keep_warmup=False)
    assert f.process(ev).size == 0
    (_, _, q3, q4), acc = f.pixel_state(0, 0)
    # q2 forwards (0 + d1, 0.6) and (gap + d1, 0.6) to q3, i.e. 8333 and 8333 + gap.
    if gap == 833:  # 833 < 833.3: nothing is due in q3 or q4
        assert q3 == [(8333, 0.6), (9166, 0.6)]
        assert q4 == [(8333, 0.6), (9166, 0.6)]
        assert acc == 0.0
    else:  # 834: q3 sends (8333 + 833, -0.96 * 0.6) to q4, which then cycles (8333, 0.6)
        assert q3 == [(9167, 0.6)]
        assert q4 == [(9166, -0.96 * 0.6), (9166, 0.6 + 0.6)]
        assert acc == 0.6
    assert efr_reference(ev, (1, 1), 120, merge_us=100) == []


def test_sampler_repeats_identical_events_and_moves_by_the_threshold():
    """A large accumulator emits several identical events, 0.7 at a time."""
    bias = np.array([[-2.0]])  # each ON event feeds 1 - (-2) = 3
    f = EFRFilter((1, 1), 50, keep_warmup=False, bias=bias)
    ev = make_events([0, 30_000, 42_000], [0] * 3, [0] * 3, [1] * 3)
    out = f.process(ev)
    # As in the hand trace, times 3: q4 first cycles (20 ms, 1.8) at 22 ms: 1.8 -> two ON
    # events (1.1, 0.4), then 0.072 per 2 ms cycle.
    assert as_tuples(out[:2]) == [(22_000, 0, 0, 1), (22_000, 0, 0, 1)]
    assert as_tuples(out) == efr_reference(ev, (1, 1), 50, bias=bias)


# --------------------------------------------------------------------------------------
# Warm-up, shift back, bias


def test_warmup_keeps_inputs_of_the_first_delay_unchanged(rng):
    size = (8, 8)
    events = random_events(rng, 3000, size, t0=5_000_000, span_us=300_000)
    plain = efr(events, size, 50, keep_warmup=False)
    kept = efr(events, size, 50)
    warm = events[events["t"] < 5_000_000 + 22_000]
    assert int(events["t"][0]) < 5_000_000 + 22_000
    assert kept.size == plain.size + warm.size
    assert as_tuples(kept[kept["t"] < events["t"][0] + 22_000]) == as_tuples(warm)
    assert int(plain["t"].min()) >= int(events["t"][0]) + 22_000


def test_shift_back_moves_every_output_by_the_delay(rng):
    size = (8, 8)
    events = random_events(rng, 3000, size, span_us=500_000)
    plain = efr(events, size, 120, keep_warmup=False)
    shifted = efr(events, size, 120, shift_back=True)  # no warm-up by default then
    assert shifted.size == plain.size > 0
    assert np.array_equal(shifted["t"], plain["t"] - (8333 + 833))
    assert all(np.array_equal(shifted[k], plain[k]) for k in "xyp")
    assert int(shifted["t"].min()) >= int(events["t"][0])


def test_bias_map_values():
    ev = make_events(
        list(range(25)), [0] * 20 + [1] * 5, [0] * 25, [1] * 15 + [0] * 5 + [1] * 5
    )  # pixel 0: 15 ON 5 OFF; pixel 1: 5 events
    bias = efr_bias(ev, (2, 1))
    assert bias.dtype == np.float64 and bias.shape == (1, 2)
    assert bias[0, 0] == (15 - 5) / 20 and bias[0, 1] == 0.0
    assert efr_bias(ev, (2, 1), min_events=5)[0, 1] == 1.0
    chunks = efr_bias(iter(np.array_split(ev, 4)), (2, 1))  # streamed over chunks
    assert np.array_equal(chunks, bias)


def test_default_bias_is_computed_over_the_whole_input(rng):
    size = (4, 4)
    events = random_events(rng, 4000, size, span_us=1_000_000)
    events["p"] = rng.random(events.size) < 0.7  # ON-heavy: a non-zero bias
    bias = efr_bias(events, size)
    assert np.abs(bias).min() > 0.2
    assert as_tuples(efr(events, size)) == as_tuples(efr(events, size, bias=bias))
    assert as_tuples(efr(events, size)) != as_tuples(efr(events, size, bias=np.zeros((4, 4))))


# --------------------------------------------------------------------------------------
# Known answers on synthetic scenes


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(3)
    size, duration = (64, 48), 400_000
    parts = {
        "f50": flicker_block(50, 4, 4, 14, duration, rng, amplitude=0.2),
        "f100": flicker_block(100, 36, 4, 14, duration, rng, amplitude=0.2),
        "edge": moving_edge(4, 60, 28, 12, duration, rng),
        "noise": background_noise(0.5, size, duration, rng),
    }
    regions = {"f50": (4, 4, 14, 14), "f100": (36, 4, 14, 14), "edge": (0, 28, 64, 12)}
    return merge(*parts.values()), size, parts, regions


def _in(events, region):
    x0, y0, w, h = region
    x, y = events["x"], events["y"]
    return int(((x >= x0) & (x < x0 + w) & (y >= y0) & (y < y0 + h)).sum())


def test_removes_50_and_100_hz_flicker_and_keeps_a_moving_edge(scene):
    events, size, parts, regions = scene
    assert parts["f50"].size > 5000 and parts["f100"].size > 5000
    out = efr(events, size, 50, keep_warmup=False)
    assert _in(out, regions["f50"]) <= 0.10 * _in(events, regions["f50"])
    assert _in(out, regions["f100"]) <= 0.10 * _in(events, regions["f100"])  # a harmonic
    assert _in(out, regions["edge"]) >= 0.5 * _in(events, regions["edge"])
    # Tuned to 100 Hz, the 50 Hz block is not a harmonic and largely survives.
    out100 = efr(events, size, 100, keep_warmup=False)
    assert _in(out100, regions["f100"]) <= 0.10 * _in(events, regions["f100"])
    assert _in(out100, regions["f50"]) >= 0.15 * _in(events, regions["f50"])


def test_real_lamps_lose_their_100_hz_rate_peak(real_data):
    """davis346_flicker_lamps: the event rate peaks at 100 Hz; EFR at 100 Hz flattens it."""
    events, size = read_events(real_data / "davis346_flicker_lamps.aedat4")
    out = efr(events, size, 100)
    start = int(events["t"][0]) + 11_000  # after the warm-up (d1 + d2 = 11 ms)
    stop = start + 110_000  # eleven whole periods

    def peak_and_count(ev):
        t = ev["t"][(ev["t"] >= start) & (ev["t"] < stop)]
        rate = np.bincount((t - start) // 500, minlength=220).astype(np.float64)  # 0.5 ms bins
        centres = (np.arange(rate.size) + 0.5) * 500e-6
        return abs(((rate - rate.mean()) * np.exp(-2j * np.pi * 100 * centres)).sum()), t.size

    before, n_before = peak_and_count(events)
    after, n_after = peak_and_count(out)
    assert before / after >= 10  # measured 17.6
    assert (before / n_before) / (after / n_after) >= 2.5  # per event too (measured 3.65)


# --------------------------------------------------------------------------------------
# Input handling


def test_empty_input_and_input_unchanged(rng):
    empty = np.zeros(0, dtype=EVENT_DTYPE)
    assert efr(empty, (4, 4)).dtype == EVENT_DTYPE and efr(empty, (4, 4)).size == 0
    events = random_events(rng, 500, (4, 4), span_us=200_000)
    copy = events.copy()
    out = efr(events, (4, 4))
    assert np.array_equal(events, copy)
    assert out.dtype == EVENT_DTYPE and np.all(np.diff(out["t"]) >= 0)
    assert as_tuples(out) == as_tuples(sort_events(out))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"frequency_hz": 0}, "frequency_hz must be a positive number"),
        ({"frequency_hz": float("nan")}, "frequency_hz must be a positive number"),
        ({"frequency_hz": 200_000}, "too high"),
        ({"rho1": 1.0}, "rho1 must be below 1"),
        ({"rho1": -0.1}, r"rho1 must lie in \[0.0, 1.0\]"),
        ({"threshold": 0}, "threshold must lie in"),
        ({"merge_us": 1.5}, "merge_us must be an int"),
        ({"bias": np.zeros((3, 3))}, r"bias must have shape \(H, W\) = \(4, 4\)"),
        ({"bias": np.full((4, 4), np.nan)}, "bias must hold finite numbers"),
    ],
)
def test_bad_parameters_say_what_is_wrong(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        EFRFilter((4, 4), **kwargs)


def test_rejects_chunks_out_of_order_and_off_sensor():
    f = EFRFilter((4, 4))
    f.process(make_events([100], [0], [0], [1]))
    with pytest.raises(ParameterError, match="time order"):
        f.process(make_events([50], [0], [0], [1]))
    with pytest.raises(EventsError, match="x out of range"):
        f.process(make_events([200], [4], [0], [1]))
