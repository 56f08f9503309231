"""Tests of edeflare.voxel: the 8-bin voxel codec (paper, Appendix C)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import random_events, same_events
from edeflare.errors import EventsError
from edeflare.events import EVENT_DTYPE, iter_time_windows, make_events
from edeflare.voxel import decode, encode, encode_polarity

START = 1_600_000_000_000_000  # an absolute time like AEDAT4's


# -- encode: hand-computed grids ---------------------------------------------------------


def test_encode_bin_edges_window_20000_8_bins():
    # bin = floor((t - start) * 8 / 20000): 2500 µs per bin
    offsets = [0, 2499, 2500, 4999, 5000, 17_499, 17_500, 19_999]
    ev = make_events([START + o for o in offsets], range(8), [0] * 8, [1] * 8)
    grid = encode(ev, (8, 1), START, 20_000)
    expected = np.zeros((8, 1, 8), dtype=np.float32)
    for x, b in enumerate([0, 0, 1, 1, 2, 6, 7, 7]):
        expected[b, 0, x] = 1.0
    assert grid.dtype == np.float32
    assert np.array_equal(grid, expected)


def test_encode_bins_of_unequal_length():
    # window 10, 3 bins: floor(t * 3 / 10) -> offsets 0-3 bin 0, 4-6 bin 1, 7-9 bin 2
    ev = make_events(range(100, 110), range(10), [0] * 10, [1] * 10)
    grid = encode(ev, (10, 1), 100, 10, bins=3)
    assert np.flatnonzero(grid[0, 0]).tolist() == [0, 1, 2, 3]
    assert np.flatnonzero(grid[1, 0]).tolist() == [4, 5, 6]
    assert np.flatnonzero(grid[2, 0]).tolist() == [7, 8, 9]


def test_encode_signed_sums_per_cell_and_layout_bins_h_w():
    # sensor 5 wide, 3 high: the grid is (bins, H, W) = (2, 3, 5)
    ev = make_events(
        [0, 1, 2, 3, 4, 5, 6, 10, 11, 12],
        [4, 4, 4, 4, 0, 0, 1, 4, 2, 2],
        [2, 2, 2, 2, 0, 0, 1, 2, 0, 0],
        [1, 1, 1, 0, 1, 0, 0, 0, 0, 0],
    )
    grid = encode(ev, (5, 3), 0, 20, bins=2)
    expected = np.zeros((2, 3, 5), dtype=np.float32)
    expected[0, 2, 4] = 3 - 1  # three ON, one OFF
    expected[0, 0, 0] = 1 - 1  # cancels
    expected[0, 1, 1] = -1
    expected[1, 2, 4] = -1
    expected[1, 0, 2] = -2
    assert grid.shape == (2, 3, 5)
    assert np.array_equal(grid, expected)


def test_encode_default_is_8_bins_and_empty_window_gives_zeros():
    grid = encode(np.zeros(0, dtype=EVENT_DTYPE), (7, 3), START, 50_000)
    assert grid.shape == (8, 3, 7) and grid.dtype == np.float32
    assert not grid.any()


def test_encode_window_counted_from_window_start_not_first_event():
    # The same event lands in different bins depending on the window start only.
    ev = make_events([START + 10_000], [0], [0], [1])
    assert np.flatnonzero(encode(ev, (1, 1), START, 20_000)[:, 0, 0]).tolist() == [4]
    assert np.flatnonzero(encode(ev, (1, 1), START + 10_000, 20_000)[:, 0, 0]).tolist() == [0]


@pytest.mark.parametrize("offset", [-1, 20_000, 25_000])
def test_encode_rejects_events_outside_the_window(offset):
    ev = make_events([START, START + offset], [0, 0], [0, 0], [1, 1], sort=True)
    with pytest.raises(EventsError, match="outside the window"):
        encode(ev, (1, 1), START, 20_000)
    with pytest.raises(EventsError, match="outside the window"):
        encode_polarity(ev, (1, 1), START, 20_000)


def test_encode_accepts_the_last_microsecond_of_the_window():
    ev = make_events([START + 19_999], [0], [0], [0])
    assert encode(ev, (1, 1), START, 20_000)[7, 0, 0] == -1.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"bins": 0}, "bins must be a positive int"),
        ({"bins": 2.0}, "bins must be a positive int"),
        ({"window_us": 7}, r"window_us \(7\) must be at least bins \(8\)"),
        ({"sensor_size": (1, 1)}, "x out of range"),
        ({"sensor_size": (0, 4)}, "sensor_size"),
    ],
)
def test_encode_rejects_bad_arguments(kwargs, message):
    ev = make_events([0, 3], [0, 1], [0, 0], [1, 0])
    args = {"sensor_size": (2, 1), "window_start_us": 0, "window_us": 16, "bins": 8} | kwargs
    with pytest.raises(EventsError, match=message):
        encode(ev, **args)
    with pytest.raises(EventsError, match=message):
        encode_polarity(ev, **args)


def test_encode_rejects_unsorted_and_wrong_dtype():
    ev = np.zeros(2, dtype=EVENT_DTYPE)
    ev["t"] = [5, 1]
    with pytest.raises(EventsError, match="not sorted"):
        encode(ev, (1, 1), 0, 8)
    with pytest.raises(EventsError, match="dtype"):
        encode(np.zeros(2, dtype=np.int64), (1, 1), 0, 8)


def test_encode_does_not_modify_events(rng):
    ev = random_events(rng, 500, (16, 12), t0=START, span_us=20_000)
    before = ev.copy()
    encode(ev, (16, 12), START, 20_000)
    encode_polarity(ev, (16, 12), START, 20_000)
    assert same_events(ev, before)


def test_encode_accepts_strided_views(rng):
    ev = random_events(rng, 500, (16, 12), t0=START, span_us=20_000)
    view = ev[::3]
    assert np.array_equal(
        encode(view, (16, 12), START, 20_000), encode(view.copy(), (16, 12), START, 20_000)
    )


# -- encode_polarity ---------------------------------------------------------------------


def test_encode_polarity_channel_0_is_on_channel_1_is_off():
    ev = make_events([0, 1, 2, 9, 9], [0, 0, 1, 1, 1], [0, 0, 0, 0, 0], [1, 0, 1, 0, 0])
    grid = encode_polarity(ev, (2, 1), 0, 10, bins=2)
    assert grid.shape == (2, 2, 1, 2) and grid.dtype == np.float32
    on, off = grid[0, :, 0, :], grid[1, :, 0, :]
    assert on.tolist() == [[1.0, 1.0], [0.0, 0.0]]
    assert off.tolist() == [[1.0, 0.0], [0.0, 2.0]]


def test_encode_polarity_difference_is_encode(rng):
    ev = random_events(rng, 5000, (20, 10), t0=START, span_us=20_000)
    split = encode_polarity(ev, (20, 10), START, 20_000)
    signed = encode(ev, (20, 10), START, 20_000)
    assert (split >= 0).all()
    assert split[0].sum() == (ev["p"] == 1).sum()
    assert split[1].sum() == (ev["p"] == 0).sum()
    assert np.array_equal(split[0] - split[1], signed)


# -- decode ------------------------------------------------------------------------------


def test_decode_docstring_case_by_hand():
    grid = np.zeros((2, 1, 2), dtype=np.float32)
    grid[1, 0, 1] = -1.6  # rounds to -2: two OFF events in bin 1 = [1010, 1020)
    ev = decode(grid, 1000, 20, rng=0)
    assert ev.dtype == EVENT_DTYPE
    assert ev["x"].tolist() == [1, 1] and ev["y"].tolist() == [0, 0]
    assert ev["p"].tolist() == [0, 0]
    assert ((ev["t"] >= 1010) & (ev["t"] < 1020)).all()


def test_decode_rounds_halves_to_even():
    values = [0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 0.49, -0.51, 3.7]
    grid = np.array(values, dtype=np.float64).reshape(1, 1, -1)
    ev = decode(grid, 0, 100, rng=1)
    counts = np.zeros((2, len(values)), dtype=int)
    np.add.at(counts, (1 - ev["p"].astype(int), ev["x"].astype(int)), 1)
    # rint: 0, -0, 2, -2, 2, -2, 0, -1, 4
    assert counts[0].tolist() == [0, 0, 2, 0, 2, 0, 0, 0, 4]  # ON
    assert counts[1].tolist() == [0, 0, 0, 2, 0, 2, 0, 1, 0]  # OFF


def test_decode_of_zeros_is_empty():
    ev = decode(np.zeros((8, 3, 4)), START, 20_000, rng=0)
    assert ev.dtype == EVENT_DTYPE and ev.size == 0


@pytest.mark.parametrize("window", [8, 9, 20_000, 50_001, (1 << 24) + 12_345])
def test_encode_of_decode_is_rint(rng, window):
    voxel = rng.normal(0.0, 2.5, size=(8, 6, 9))
    voxel[0, 0, :6] = [0.5, -0.5, 1.5, -1.5, 2.5, -2.5]
    voxel[3, 2, :3] = [7.5, -7.5, -0.0]
    ev = decode(voxel, START, window, rng=rng)
    assert ev.size == int(np.abs(np.rint(voxel)).sum())
    assert (np.diff(ev["t"]) >= 0).all()
    assert ev["t"].min() >= START and ev["t"].max() < START + window
    assert ev["x"].max() < 9 and ev["y"].max() < 6
    assert np.array_equal(encode(ev, (9, 6), START, window), np.rint(voxel))


def test_decode_of_encode_keeps_signed_cell_counts(rng):
    ev = random_events(rng, 4000, (12, 8), t0=START, span_us=20_000)
    grid = encode(ev, (12, 8), START, 20_000)
    back = decode(grid, START, 20_000, rng=5)
    assert back.size == int(np.abs(grid).sum())
    assert np.array_equal(encode(back, (12, 8), START, 20_000), grid)


def test_decode_accepts_integer_grids():
    grid = np.zeros((4, 2, 2), dtype=np.int16)
    grid[3, 1, 0] = 3
    grid[0, 0, 1] = -2
    ev = decode(grid, 0, 40, rng=0)
    assert ev[["x", "y", "p"]].tolist() == [(1, 0, 0), (1, 0, 0), (0, 1, 1), (0, 1, 1), (0, 1, 1)]
    assert (ev["t"][:2] < 10).all() and (ev["t"][2:] >= 30).all()


def test_decode_times_are_spread_over_the_whole_bin():
    grid = np.zeros((8, 1, 1))
    grid[5, 0, 0] = 4000  # bin 5 of a 20 ms window: offsets [12500, 15000)
    ev = decode(grid, START, 20_000, rng=3)
    off = ev["t"] - START
    assert off.min() >= 12_500 and off.max() <= 14_999
    # uniform over 2500 values: 4000 draws reach both ends and leave no large hole
    assert off.min() < 12_520 and off.max() > 14_980
    assert np.diff(np.unique(off)).max() < 40


def test_decode_is_seeded():
    voxel = np.random.default_rng(9).normal(0.0, 3.0, size=(8, 4, 4))
    a = decode(voxel, START, 20_000, rng=42)
    b = decode(voxel, START, 20_000, rng=42)
    c = decode(voxel, START, 20_000, rng=np.random.default_rng(42))
    d = decode(voxel, START, 20_000, rng=43)
    assert same_events(a, b) and same_events(a, c)
    assert a.size == d.size and not np.array_equal(a["t"], d["t"])


def test_decode_does_not_modify_the_voxel():
    voxel = np.random.default_rng(2).normal(0.0, 3.0, size=(8, 4, 4)).astype(np.float32)
    before = voxel.copy()
    decode(voxel, 0, 20_000, rng=0)
    assert np.array_equal(voxel, before)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_decode_rejects_non_finite_voxels(bad):
    voxel = np.zeros((8, 2, 2), dtype=np.float32)
    voxel[3, 1, 0] = bad
    with pytest.raises(EventsError, match="NaN or infinity"):
        decode(voxel, 0, 20_000, rng=0)


@pytest.mark.parametrize(
    ("voxel", "window", "message"),
    [
        (np.zeros((8, 4)), 20_000, r"shape \(bins, H, W\)"),
        (np.zeros((1, 8, 4, 4)), 20_000, r"shape \(bins, H, W\)"),
        (np.zeros((8, 2, 2), dtype=bool), 20_000, "numeric"),
        (np.zeros((8, 2, 2)), 7, r"window_us \(7\) must be at least bins \(8\)"),
    ],
)
def test_decode_rejects_bad_arguments(voxel, window, message):
    with pytest.raises(EventsError, match=message):
        decode(voxel, 0, window, rng=0)


def test_codec_on_consecutive_windows_reassembles_the_stream(rng):
    """Window by window (aligned starts), encode->decode keeps per-window cell counts."""
    ev = random_events(rng, 3000, (10, 10), t0=START + 7_777, span_us=95_000)
    decoded = []
    for start, window in iter_time_windows(ev, 20_000):
        grid = encode(window, (10, 10), start, 20_000)
        back = decode(grid, start, 20_000, rng=start)
        assert np.array_equal(encode(back, (10, 10), start, 20_000), grid)
        decoded.append(back)
    out = np.concatenate(decoded)
    assert (np.diff(out["t"]) >= 0).all()
    assert out["t"][0] >= START  # first window starts at a multiple of 20 ms at or below
    assert out.size <= ev.size


# -- property test -----------------------------------------------------------------------


@st.composite
def windows_of_events(draw):
    width = draw(st.integers(1, 6))
    height = draw(st.integers(1, 6))
    bins = draw(st.integers(1, 10))
    window = draw(st.integers(bins, 5_000))
    start = draw(st.integers(-(10**12), 2 * 10**15))
    n = draw(st.integers(0, 60))
    offsets = sorted(draw(st.lists(st.integers(0, window - 1), min_size=n, max_size=n)))
    xs = draw(st.lists(st.integers(0, width - 1), min_size=n, max_size=n))
    ys = draw(st.lists(st.integers(0, height - 1), min_size=n, max_size=n))
    ps = draw(st.lists(st.integers(0, 1), min_size=n, max_size=n))
    events = make_events([start + o for o in offsets], xs, ys, ps)
    return events, (width, height), start, window, bins


@settings(max_examples=150)
@given(case=windows_of_events(), seed=st.integers(0, 2**32 - 1))
def test_property_codec_round_trip(case, seed):
    events, size, start, window, bins = case
    grid = encode(events, size, start, window, bins)
    assert grid.shape == (bins, size[1], size[0])
    # the grid's per-cell sum matches a direct count
    b = ((events["t"] - start) * bins) // window
    direct = np.zeros_like(grid)
    np.add.at(direct, (b, events["y"], events["x"]), np.where(events["p"] == 1, 1.0, -1.0))
    assert np.array_equal(grid, direct)
    back = decode(grid, start, window, rng=seed)
    assert back.size == int(np.abs(grid).sum())
    assert (np.diff(back["t"]) >= 0).all()
    if back.size:
        assert back["t"][0] >= start and back["t"][-1] < start + window
    assert np.array_equal(encode(back, size, start, window, bins), grid)
