"""The leaky-integrator reconstruction: hand-computed values, invariants, streaming, speed."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from conftest import random_events
from edeflare.errors import ParameterError
from edeflare.eval.reconstruct import LeakyIntegrator, display_scale, reconstruct, to_uint8
from edeflare.events import empty_events, make_events

SIZE = (16, 12)


def test_one_pixel_two_events_hand_computed():
    # ON at 1 ms, OFF at 4 ms on pixel (3, 2); f_c = 10 Hz -> alpha = 20 pi /s.
    ev = make_events([1_000, 4_000], [3, 3], [2, 2], [1, 0])
    alpha = 2 * math.pi * 10.0
    frames = reconstruct(ev, SIZE, [0, 1_000, 2_000, 4_000, 10_000], cutoff_hz=10.0, contrast=0.3)
    assert frames.shape == (5, 12, 16) and frames.dtype == np.float32
    at_4ms = 0.3 * math.exp(-alpha * 0.003)  # the OFF event at 4 ms is not seen yet
    after_off = at_4ms - 0.3
    expected = [0.0, 0.0, 0.3 * math.exp(-alpha * 0.001), at_4ms,
                after_off * math.exp(-alpha * 0.006)]  # fmt: skip
    np.testing.assert_allclose(frames[:, 2, 3], expected, rtol=1e-6)
    others = np.delete(frames.reshape(5, -1), 2 * 16 + 3, axis=1)
    assert not others.any()


def test_no_events_gives_zeros_and_no_times_gives_no_frames():
    assert not reconstruct(empty_events(), SIZE, [0, 5, 10]).any()
    assert reconstruct(make_events([1], [0], [0], [1]), SIZE, []).shape == (0, 12, 16)


def test_decay_is_monotone_and_zero_cutoff_is_a_pure_integrator(rng):
    ev = make_events([0, 10, 20], [5, 5, 5], [5, 5, 5], [1, 1, 1])
    times = np.arange(100, 1_000_000, 50_000)
    decaying = reconstruct(ev, SIZE, times, cutoff_hz=2.0)[:, 5, 5]
    assert np.all(np.diff(decaying) < 0) and decaying[0] > 0
    flat = reconstruct(ev, SIZE, times, cutoff_hz=0.0, contrast=0.25)[:, 5, 5]
    np.testing.assert_allclose(flat, 0.75)
    # Without decay L is the signed event count times c.
    events = random_events(rng, 2_000, SIZE, span_us=50_000)
    net = np.zeros((12, 16))
    np.add.at(net, (events["y"], events["x"]), events["p"].astype(int) * 2 - 1)
    np.testing.assert_allclose(
        reconstruct(events, SIZE, [50_000], cutoff_hz=0.0, contrast=0.1)[0], 0.1 * net, atol=1e-5
    )


def test_linear_in_contrast_and_odd_in_polarity(rng):
    events = random_events(rng, 3_000, SIZE, span_us=100_000)
    times = [20_000, 60_000, 100_000]
    a = reconstruct(events, SIZE, times, contrast=0.1)
    np.testing.assert_allclose(reconstruct(events, SIZE, times, contrast=0.3), 3 * a, rtol=1e-5)
    flipped = events.copy()
    flipped["p"] = 1 - flipped["p"]
    np.testing.assert_allclose(reconstruct(flipped, SIZE, times, contrast=0.1), -a, atol=1e-7)


def test_frame_sees_events_strictly_before_its_time():
    ev = make_events([500], [0], [0], [1])
    assert reconstruct(ev, SIZE, [500])[0, 0, 0] == 0
    assert reconstruct(ev, SIZE, [501])[0, 0, 0] > 0


def test_streaming_equals_one_call_and_input_is_unchanged(rng):
    events = random_events(rng, 5_000, SIZE, span_us=200_000)
    before = events.copy()
    times = np.arange(20_000, 200_001, 20_000)
    whole = reconstruct(events, SIZE, times)
    integ = LeakyIntegrator(SIZE)
    parts = []
    for a in range(0, times.size, 3):
        lo = np.searchsorted(events["t"], times[a - 1]) if a else 0
        hi = np.searchsorted(events["t"], times[min(a + 3, times.size) - 1])
        parts.append(integ.frames(events[lo:hi], times[a : a + 3]))
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert np.array_equal(events, before)
    np.testing.assert_array_equal(reconstruct(events, SIZE, times), whole)  # deterministic


def test_streaming_rejects_going_back_in_time():
    integ = LeakyIntegrator(SIZE)
    integ.frames(make_events([100, 200], [0, 0], [0, 0], [1, 1]), [300])
    with pytest.raises(ParameterError, match="back in time"):
        integ.frames(make_events([250], [0], [0], [1]), [])
    fed = LeakyIntegrator(SIZE)
    fed.frames(make_events([100], [0], [0], [1]), [])
    with pytest.raises(ParameterError, match="before events already fed"):
        fed.frames(empty_events(), [100])
    fed.frames(empty_events(), [101])  # just after the event is fine


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"times_us": [10, 5]}, "non-decreasing"),
        ({"times_us": [[1, 2]]}, "1-D"),
        ({"times_us": [1.5]}, "whole"),
        ({"times_us": [1], "cutoff_hz": -1.0}, "cutoff_hz"),
        ({"times_us": [1], "contrast": 0.0}, "contrast"),
        ({"times_us": [1], "cutoff_hz": float("nan")}, "cutoff_hz"),
    ],
)
def test_bad_parameters(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        reconstruct(empty_events(), SIZE, **kwargs)


def test_to_uint8_is_symmetric_around_mid_gray():
    frames = np.array([[-2.0, -1.0, 0.0, 1.0, 2.0]])
    assert to_uint8(frames, scale=2.0).tolist() == [[0, 64, 128, 191, 255]]
    # Default scale: the 99th percentile of the non-zero magnitudes; hot pixels saturate.
    rng = np.random.default_rng(0)
    image = rng.normal(0, 1, (50, 50))
    image[0, 0] = 1e6
    assert display_scale(image) < 10
    assert to_uint8(image)[0, 0] == 255
    assert display_scale(np.zeros((3, 3))) == 1.0
    assert to_uint8(np.zeros((2, 2))).tolist() == [[128, 128], [128, 128]]
    with pytest.raises(ParameterError):
        to_uint8(frames, scale=0.0)


def test_speed_sanity(rng):
    """At least 5 M events/s once compiled (measured about 60 M/s on the CI machine)."""
    size = (346, 260)
    events = random_events(rng, 2_000_000, size, span_us=100_000)
    times = np.arange(20_000, 100_001, 20_000)
    reconstruct(events[:10], size, times)  # compile / load the cache
    t0 = time.perf_counter()
    reconstruct(events, size, times)
    rate = events.size / (time.perf_counter() - t0)
    assert rate > 5e6, f"{rate / 1e6:.1f} M events/s"
