"""Tests of edeflare.events: the event dtype, validation, sorting, merging, windows, crops."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import random_events, same_events
from edeflare.errors import EdeflareError, EventsError
from edeflare.events import (
    EVENT_DTYPE,
    center_crop,
    check_events,
    check_sensor_size,
    crop,
    empty_events,
    iter_chunk_windows,
    iter_time_windows,
    make_events,
    merge_events,
    parse_sensor_size,
    slice_time,
    sort_events,
    stream_sensor_size,
    window_start_for,
)


def ev_from(t, x=None, y=None, p=None):
    """Events from lists, defaulting x/y to 0 and p to ON."""
    n = len(t)
    return make_events(
        t,
        [0] * n if x is None else x,
        [0] * n if y is None else y,
        [1] * n if p is None else p,
    )


# -- make_events -------------------------------------------------------------------------


def test_event_dtype_is_the_documented_layout():
    assert EVENT_DTYPE.names == ("t", "x", "y", "p")
    assert [EVENT_DTYPE[k].str for k in EVENT_DTYPE.names] == ["<i8", "<u2", "<u2", "|u1"]


def test_make_events_fills_every_field():
    ev = make_events([3, 7, 7], [1, 639, 2], [479, 0, 5], [1, 0, 1])
    assert ev.dtype == EVENT_DTYPE
    assert ev["t"].tolist() == [3, 7, 7]
    assert ev["x"].tolist() == [1, 639, 2]
    assert ev["y"].tolist() == [479, 0, 5]
    assert ev["p"].tolist() == [1, 0, 1]


@pytest.mark.parametrize(
    "p",
    [
        [0, 1, 1, 0],
        np.array([0, 1, 1, 0], dtype=np.uint8),
        [False, True, True, False],
        np.array([False, True, True, False]),
        [-1, 1, 1, -1],
        np.array([-1, 1, 1, -1], dtype=np.int8),
        [-1.0, 1.0, 1.0, -1.0],
        [0.0, 1.0, 1.0, 0.0],
    ],
    ids=["0/1", "u8", "bools", "bool array", "-1/+1", "i8 -1/+1", "float -1/+1", "float 0/1"],
)
def test_make_events_polarity_conventions_map_to_0_1(p):
    ev = make_events([0, 1, 2, 3], [0, 1, 2, 3], [0, 0, 0, 0], p)
    assert ev["p"].dtype == np.uint8
    assert ev["p"].tolist() == [0, 1, 1, 0]


@pytest.mark.parametrize(
    ("p", "expected"),
    [([1, 1], [1, 1]), ([0, 0], [0, 0]), ([-1, -1], [0, 0]), ([True, True], [1, 1])],
)
def test_make_events_single_polarity_streams(p, expected):
    assert make_events([0, 1], [0, 0], [0, 0], p)["p"].tolist() == expected


def test_make_events_rejects_mixed_zero_and_minus_one():
    with pytest.raises(EventsError, match="mixes 0 and -1"):
        make_events([0, 1, 2], [0, 0, 0], [0, 0, 0], [0, -1, 1])


@pytest.mark.parametrize("p", [[0, 2], [1, -2], [0.5, 1]])
def test_make_events_rejects_other_polarity_values(p):
    with pytest.raises(EventsError, match="p "):
        make_events([0, 1], [0, 0], [0, 0], p)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_make_events_rejects_non_finite_t(bad):
    with pytest.raises(EventsError, match=r"t contains NaN or infinity \(first at index 1\)"):
        make_events([0.0, bad, 2.0], [0, 0, 0], [0, 0, 0], [1, 1, 1])


def test_make_events_rejects_fractional_t_naming_the_index():
    with pytest.raises(EventsError, match=r"t must hold whole numbers.*1\.5.*index 1"):
        make_events([0.0, 1.5, 2.0], [0, 0, 0], [0, 0, 0], [1, 1, 1])


def test_make_events_accepts_integral_floats_exactly():
    ev = make_events([0.0, 1_600_000_000_000_000.0], [3.0, 4.0], [5.0, 6.0], [1.0, 0.0])
    assert ev["t"].tolist() == [0, 1_600_000_000_000_000]
    assert ev["x"].tolist() == [3, 4]
    assert ev["y"].tolist() == [5, 6]


@pytest.mark.parametrize(
    ("x", "y", "message"),
    [
        ([0, -1], [0, 0], r"x values must lie in \[0, 65535\]"),
        ([0, 65536], [0, 0], r"x values must lie in \[0, 65535\]"),
        ([0, 0], [0, 2.5], "y must hold whole numbers"),
        ([0, np.nan], [0, 0], "x contains NaN"),
    ],
)
def test_make_events_rejects_bad_coordinates(x, y, message):
    with pytest.raises(EventsError, match=message):
        make_events([0, 1], x, y, [1, 1])


@pytest.mark.parametrize(
    "arrays",
    [
        ([0, 1, 2], [0, 0], [0, 0], [1, 1]),
        ([0, 1], [0, 0, 0], [0, 0], [1, 1]),
        ([0, 1], [0, 0], [0], [1, 1]),
        ([0, 1], [0, 0], [0, 0], [1]),
    ],
)
def test_make_events_rejects_mismatched_lengths(arrays):
    with pytest.raises(EventsError, match="same length"):
        make_events(*arrays)


def test_make_events_rejects_non_numeric_and_2d_input():
    with pytest.raises(EventsError, match="numeric"):
        make_events(["a", "b"], [0, 0], [0, 0], [1, 1])
    with pytest.raises(EventsError, match="one-dimensional"):
        make_events([[0, 1]], [[0, 0]], [[0, 0]], [[1, 1]])


def test_make_events_rejects_unsorted_naming_the_index():
    with pytest.raises(EventsError, match=r"t decreases at index 2.*sort=True"):
        make_events([0, 5, 3, 9], [0, 0, 0, 0], [0, 0, 0, 0], [1, 1, 1, 1])


def test_make_events_rejects_unsorted_when_validating_against_a_sensor():
    with pytest.raises(EventsError, match="not sorted"):
        make_events([5, 3], [0, 0], [0, 0], [1, 1], sensor_size=(4, 4))


def test_make_events_sort_is_stable_and_leaves_inputs_unchanged():
    t = np.array([5, 1, 5, 1, 5, 0])
    x = np.array([0, 1, 2, 3, 4, 5])
    t_before, x_before = t.copy(), x.copy()
    ev = make_events(t, x, np.zeros(6), [1, 0, 1, 0, 1, 0], sort=True)
    assert ev["t"].tolist() == [0, 1, 1, 5, 5, 5]
    # Equal times keep their input order: x 1 before 3, and 0, 2, 4 in that order.
    assert ev["x"].tolist() == [5, 1, 3, 0, 2, 4]
    assert ev["p"].tolist() == [0, 0, 0, 1, 1, 1]
    assert np.array_equal(t, t_before) and np.array_equal(x, x_before)


def test_make_events_checks_coordinates_against_sensor_size():
    make_events([0, 1], [3, 0], [0, 2], [1, 1], sensor_size=(4, 3))
    with pytest.raises(EventsError, match="x=4 at index 0"):
        make_events([0, 1], [4, 0], [0, 2], [1, 1], sensor_size=(4, 3))
    with pytest.raises(EventsError, match="y=3 at index 1"):
        make_events([0, 1], [3, 0], [0, 3], [1, 1], sensor_size=(4, 3))


def test_make_events_empty():
    ev = make_events([], [], [], [])
    assert ev.dtype == EVENT_DTYPE and ev.shape == (0,)


def test_events_error_is_a_project_value_error():
    assert issubclass(EventsError, EdeflareError)
    assert issubclass(EventsError, ValueError)


# -- check_events ------------------------------------------------------------------------


def test_check_events_returns_its_argument():
    ev = ev_from([0, 1], [0, 9], [0, 0], [1, 0])
    assert check_events(ev) is ev
    assert check_events(ev, (10, 1)) is ev


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(3, dtype=np.int64),
        np.zeros(3, dtype=[("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("p", "i1")]),
        np.zeros(3, dtype=[("t", "<i4"), ("x", "<u2"), ("y", "<u2"), ("p", "u1")]),
        np.zeros(3, dtype=[("x", "<u2"), ("t", "<i8"), ("y", "<u2"), ("p", "u1")]),
        [(0, 0, 0, 1)],
    ],
    ids=["int array", "p int8", "t int32", "field order", "list"],
)
def test_check_events_rejects_wrong_dtype(bad):
    with pytest.raises(EventsError, match="structured array of dtype"):
        check_events(bad)


def test_check_events_rejects_2d():
    with pytest.raises(EventsError, match="one-dimensional"):
        check_events(np.zeros((2, 2), dtype=EVENT_DTYPE))


def test_check_events_rejects_unsorted_naming_the_index():
    ev = np.zeros(5, dtype=EVENT_DTYPE)
    ev["t"] = [0, 5, 5, 3, 9]
    with pytest.raises(EventsError, match=r"t=3 at index 3 follows t=5"):
        check_events(ev)


@pytest.mark.parametrize(
    ("x", "y", "message"),
    [
        ([0, 3, 4, 5], [0, 0, 0, 0], "x out of range for sensor width 4: x=4 at index 2"),
        ([0, 0, 0, 0], [0, 2, 1, 3], "y out of range for sensor height 3: y=3 at index 3"),
    ],
)
def test_check_events_rejects_coordinates_off_the_sensor(x, y, message):
    ev = ev_from([0, 1, 2, 3], x, y)
    check_events(ev)  # fine without a sensor size
    with pytest.raises(EventsError, match=message):
        check_events(ev, (4, 3))


def test_check_events_rejects_polarity_two_naming_the_index():
    ev = ev_from([0, 1, 2], p=[1, 0, 1])
    ev["p"][2] = 2
    with pytest.raises(EventsError, match="p=2 at index 2"):
        check_events(ev)


@pytest.mark.parametrize("bad_index", [1, 99, 100, 101, 799, 800, 1599])
def test_check_events_names_the_first_problem_in_long_streams(rng, bad_index):
    # 1600 events: the first decreasing t / off-sensor x / bad p can sit anywhere,
    # including on either side of any internal block boundary of the scan.
    ev = random_events(rng, 1600, (64, 32), span_us=10**6)
    ev["t"] = np.arange(1600) * 10
    unsorted = ev.copy()
    unsorted["t"][bad_index] = unsorted["t"][bad_index - 1] - 1
    if bad_index < 1599:
        unsorted["t"][1599] = 0  # a later decrease must not be the one reported
    with pytest.raises(EventsError, match=rf"at index {bad_index} follows"):
        check_events(unsorted)
    off = ev.copy()
    off["x"][bad_index] = 64
    if bad_index < 1599:
        off["x"][1599] = 65
    with pytest.raises(EventsError, match=rf"x=64 at index {bad_index}$"):
        check_events(off, (64, 32))
    check_events(off, (66, 32))  # all on a wider sensor
    pol = ev.copy()
    pol["p"][bad_index] = 7
    with pytest.raises(EventsError, match=rf"p=7 at index {bad_index}$"):
        check_events(pol)


def test_check_events_empty_stream_still_checks_the_sensor_size():
    assert check_events(empty_events(), (4, 4)).size == 0
    with pytest.raises(EventsError, match="sensor_size"):
        check_events(empty_events(), (0, 4))


def test_empty_events_is_zero_filled():
    ev = empty_events(3)
    assert ev.dtype == EVENT_DTYPE
    assert ev["t"].tolist() == [0, 0, 0] and ev["p"].tolist() == [0, 0, 0]


# -- sort / merge ------------------------------------------------------------------------


def test_sort_events_returns_a_stable_copy():
    ev = np.zeros(4, dtype=EVENT_DTYPE)
    ev["t"] = [3, 1, 3, 1]
    ev["x"] = [0, 1, 2, 3]
    before = ev.copy()
    out = sort_events(ev)
    assert out["x"].tolist() == [1, 3, 0, 2]
    assert same_events(ev, before)
    assert not np.shares_memory(out, ev)


def test_merge_events_keeps_argument_order_on_ties():
    a = ev_from([0, 10, 10], x=[0, 1, 2])
    b = ev_from([5, 10, 20], x=[10, 11, 12])
    c = ev_from([10], x=[20])
    a0, b0 = a.copy(), b.copy()
    merged = merge_events(a, b, c)
    assert merged["t"].tolist() == [0, 5, 10, 10, 10, 10, 20]
    assert merged["x"].tolist() == [0, 10, 1, 2, 11, 20, 12]
    assert same_events(a, a0) and same_events(b, b0)
    # the other argument order changes the order of tied events only
    assert merge_events(c, b, a)["x"].tolist() == [0, 10, 20, 11, 1, 2, 12]


def test_merge_events_with_empty_streams(rng):
    a = random_events(rng, 50, (8, 8))
    assert same_events(merge_events(empty_events(), a, empty_events()), a)
    assert merge_events().shape == (0,) and merge_events().dtype == EVENT_DTYPE


def test_merge_events_equals_a_stable_sort_of_the_concatenation(rng):
    streams = [random_events(rng, n, (16, 16), span_us=1000) for n in (0, 30, 100, 7)]
    merged = merge_events(*streams)
    cat = np.concatenate(streams)
    assert same_events(merged, cat[np.argsort(cat["t"], kind="stable")])


def test_merge_events_rejects_unsorted_input():
    unsorted = np.zeros(2, dtype=EVENT_DTYPE)
    unsorted["t"] = [5, 1]
    with pytest.raises(EventsError, match="not sorted"):
        merge_events(ev_from([0]), unsorted)


# -- slice_time --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("start", "end", "expected"),
    [
        (10, 20, [10, 10]),
        (10, 21, [10, 10, 20]),
        (0, 10, [0]),
        (-5, 1, [0]),
        (-5, 0, []),
        (11, 20, []),
        (31, 40, []),
        (20, 10, []),
        (0, 31, [0, 10, 10, 20, 30]),
    ],
)
def test_slice_time_is_half_open(start, end, expected):
    ev = ev_from([0, 10, 10, 20, 30])
    assert slice_time(ev, start, end)["t"].tolist() == expected


def test_slice_time_returns_a_view():
    ev = ev_from([0, 10, 20, 30])
    part = slice_time(ev, 10, 30)
    assert np.shares_memory(part, ev)


# -- windows -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("t", "window", "expected"),
    [(45_123, 20_000, 40_000), (40_000, 20_000, 40_000), (39_999, 20_000, 20_000), (-5, 10, -10)],
)
def test_window_start_for_floors_to_a_multiple(t, window, expected):
    assert window_start_for(t, window) == expected


def test_iter_time_windows_aligned_with_empty_windows():
    ev = ev_from([45_123, 59_999, 60_000, 60_000, 79_999, 120_000], x=[0, 1, 2, 3, 4, 5])
    windows = list(iter_time_windows(ev, 20_000))
    assert [s for s, _ in windows] == [40_000, 60_000, 80_000, 100_000, 120_000]
    assert [w["x"].tolist() for _, w in windows] == [[0, 1], [2, 3, 4], [], [], [5]]
    for _, w in windows:
        assert w.dtype == EVENT_DTYPE


def test_iter_time_windows_event_on_a_boundary_opens_the_next_window():
    # t = start + k*len belongs to window k, never to window k-1
    ev = ev_from([0, 999, 1000, 2000, 2999, 3000])
    windows = [(s, w["t"].tolist()) for s, w in iter_time_windows(ev, 1000)]
    assert windows == [(0, [0, 999]), (1000, [1000]), (2000, [2000, 2999]), (3000, [3000])]


def test_iter_time_windows_explicit_start_and_end():
    ev = ev_from([5, 15, 25, 35, 45])
    got = [(s, w["t"].tolist()) for s, w in iter_time_windows(ev, 10, start_us=-20, end_us=31)]
    # windows until end_us is covered: the last one [30, 40) holds 35 although 35 >= end_us
    assert got == [(-20, []), (-10, []), (0, [5]), (10, [15]), (20, [25]), (30, [35])]
    # an explicit start need not be aligned, and events before it are left out
    got = [(s, w["t"].tolist()) for s, w in iter_time_windows(ev, 10, start_us=12)]
    assert got == [(12, [15]), (22, [25]), (32, [35]), (42, [45])]
    # windows beyond the last event are yielded when end_us asks for them
    got = [(s, len(w)) for s, w in iter_time_windows(ev, 20, end_us=100)]
    assert got == [(0, 2), (20, 2), (40, 1), (60, 0), (80, 0)]


def test_iter_time_windows_empty_stream():
    assert list(iter_time_windows(empty_events(), 10)) == []
    got = [(s, len(w)) for s, w in iter_time_windows(empty_events(), 10, start_us=0, end_us=25)]
    assert got == [(0, 0), (10, 0), (20, 0)]


@pytest.mark.parametrize("window", [0, -10])
def test_iter_time_windows_rejects_non_positive_length(window):
    with pytest.raises(EventsError, match="window_us must be positive"):
        list(iter_time_windows(ev_from([0]), window))


@pytest.mark.parametrize("window", [1, 7, 1000, 33_333])
def test_iter_time_windows_every_event_in_exactly_one_window(rng, window):
    ev = random_events(rng, 2000, (32, 32), t0=1_600_000_000_123_456, span_us=20_000)
    gap_start = int(ev["t"][-1]) + 9_000  # a silence longer than several windows
    ev = np.concatenate([ev, random_events(rng, 100, (32, 32), t0=gap_start, span_us=5_000)])
    windows = list(iter_time_windows(ev, window))
    starts = np.array([s for s, _ in windows])
    assert starts[0] == window_start_for(int(ev["t"][0]), window)
    assert starts[0] % window == 0
    assert np.array_equal(np.diff(starts), np.full(len(starts) - 1, window))
    assert starts[-1] <= ev["t"][-1] < starts[-1] + window
    for s, w in windows:
        assert ((w["t"] >= s) & (w["t"] < s + window)).all()
    assert same_events(np.concatenate([w for _, w in windows]), ev)


# -- crop --------------------------------------------------------------------------------


def test_center_crop_1280x720_to_640x480_shifts_by_320_120():
    ev = make_events(
        [0, 1, 2, 3, 4, 5, 6, 7],
        [320, 959, 319, 960, 320, 320, 640, 0],
        [120, 599, 120, 120, 119, 600, 360, 0],
        [1, 0, 1, 1, 0, 1, 0, 1],
    )
    before = ev.copy()
    out, size = center_crop(ev, (1280, 720), (640, 480))
    assert size == (640, 480)
    assert out.dtype == EVENT_DTYPE
    assert out["t"].tolist() == [0, 1, 6]
    assert out["x"].tolist() == [0, 639, 320]
    assert out["y"].tolist() == [0, 479, 240]
    assert out["p"].tolist() == [1, 0, 0]
    assert same_events(ev, before)  # the input is not modified
    check_events(out, size)


def test_center_crop_odd_margin_rounds_down():
    # (11 - 4) // 2 = 3, (7 - 4) // 2 = 1
    ev = ev_from([0, 1, 2], x=[3, 6, 7], y=[1, 4, 1])
    out, size = center_crop(ev, (11, 7), (4, 4))
    assert size == (4, 4)
    assert out[["x", "y"]].tolist() == [(0, 0), (3, 3)]


def test_crop_random_matches_a_mask(rng):
    ev = random_events(rng, 3000, (64, 48))
    before = ev.copy()
    out, size = crop(ev, (64, 48), 10, 5, 20, 30)
    keep = (ev["x"] >= 10) & (ev["x"] < 30) & (ev["y"] >= 5) & (ev["y"] < 35)
    assert size == (20, 30)
    assert np.array_equal(out["t"], ev["t"][keep])
    assert np.array_equal(out["x"], ev["x"][keep] - 10)
    assert np.array_equal(out["y"], ev["y"][keep] - 5)
    assert np.array_equal(out["p"], ev["p"][keep])
    assert same_events(ev, before)


@pytest.mark.parametrize(
    "rect", [(-1, 0, 4, 4), (0, -1, 4, 4), (7, 0, 4, 4), (0, 7, 4, 4), (0, 0, 0, 4), (0, 0, 11, 1)]
)
def test_crop_rejects_rectangles_off_the_sensor(rect):
    with pytest.raises(EventsError):
        crop(ev_from([0]), (10, 10), *rect)


def test_center_crop_larger_than_sensor_is_rejected():
    with pytest.raises(EventsError, match="does not fit"):
        center_crop(ev_from([0]), (640, 480), (1280, 720))


# -- sensor sizes ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("640x480", (640, 480)),
        ("1280X720", (1280, 720)),
        ("346,260", (346, 260)),
        (" 304 x 240 ", (304, 240)),
        ("65536x1", (65536, 1)),
    ],
)
def test_parse_sensor_size_accepts(text, expected):
    assert parse_sensor_size(text) == expected


@pytest.mark.parametrize(
    "text", ["640", "640x480x3", "axb", "640.5x480", "0x480", "-640x480", "65537x1", ""]
)
def test_parse_sensor_size_rejects(text):
    with pytest.raises(EventsError, match=r"640x480|sensor_size"):
        parse_sensor_size(text)


@pytest.mark.parametrize(
    "bad", [4, (4,), (4, 4, 4), (0, 4), (4.0, 4), (True, 4), (65537, 4), ("4", 4), None]
)
def test_check_sensor_size_rejects(bad):
    with pytest.raises(EventsError, match="sensor_size"):
        check_sensor_size(bad)


def test_check_sensor_size_returns_python_ints():
    size = check_sensor_size((np.int64(640), np.uint16(480)))
    assert size == (640, 480)
    assert all(type(v) is int for v in size)


def test_stream_sensor_size():
    a = ev_from([0, 1], x=[3, 9], y=[2, 0])
    b = ev_from([0], x=[1], y=[7])
    assert stream_sensor_size([a, empty_events(), b]) == (10, 8)
    with pytest.raises(EventsError, match="empty"):
        stream_sensor_size([empty_events()])


@pytest.mark.parametrize("cuts", [[], [1], [3, 3, 7], [0, 2, 4, 6, 8, 9]])
def test_iter_chunk_windows_matches_iter_time_windows_for_any_chunking(cuts):
    ev = make_events([5, 18, 20, 21, 44, 60, 61, 99, 140, 141], [0] * 10, [0] * 10, [1] * 10)
    chunks = np.split(ev, cuts)
    for bounds in ({}, {"start_us": 0, "end_us": 200}, {"start_us": 20, "end_us": 100}):
        want = [(s, w["t"].tolist()) for s, w in iter_time_windows(ev, 20, **bounds)]
        got = [(s, w["t"].tolist()) for s, w in iter_chunk_windows(chunks, 20, **bounds)]
        assert got == want
    assert [s for s, _ in iter_chunk_windows(chunks, 20)] == [0, 20, 40, 60, 80, 100, 120, 140]


def test_concat_and_select_equal_numpy_on_every_layout(rng):
    from edeflare.events import concat_events, select_events

    a = random_events(rng, 1000, (64, 48))
    b = random_events(rng, 7, (64, 48))
    strided = a[::3]  # not contiguous: copied first
    for chunks in ([a, b], [strided, b, a[:0]], [a[:0]], [b]):
        got = concat_events(chunks)
        assert got.dtype == EVENT_DTYPE and np.array_equal(got, np.concatenate(chunks))
    assert concat_events([]).shape == (0,)
    keep = rng.random(a.size) < 0.3
    assert np.array_equal(select_events(a, keep), a[keep])
    assert np.array_equal(select_events(strided, keep[::3]), strided[keep[::3]])
    out = select_events(a, keep)
    out["x"] = 0  # a copy: the input is untouched
    assert a["x"][keep].any()
    with pytest.raises(EventsError, match="dtype"):
        concat_events([a, a.astype([("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("p", "<u2")])])
    with pytest.raises(EventsError, match="dtype"):
        select_events(np.zeros(3), np.ones(3, bool))


def test_isin_keys_equals_numpy_isin_on_streams_with_ties_and_repeats(rng):
    from edeflare.events import event_keys, isin_keys

    size = (64, 48)
    a = random_events(rng, 5000, size)
    a["t"] //= 50  # many events share a time stamp: their keys are out of order
    b = np.concatenate([a[rng.random(a.size) < 0.4], random_events(rng, 300, size)])
    b = b[rng.permutation(b.size)]  # unsorted, with repeats below
    b = np.concatenate([b, b[:100]])
    ka, kb = event_keys(a, size), event_keys(b, size)
    got = isin_keys(ka, kb)
    assert got.dtype == bool and np.array_equal(got, np.isin(ka, kb))
    assert 0.3 < got.mean() < 0.6  # both outcomes occur
    assert np.array_equal(isin_keys(kb, ka), np.isin(kb, ka))
    # hand-computed: a key above, below and between every key of ``of``
    assert isin_keys(np.array([0, 4, 7, 10, 11]), np.array([10, 4, 7])).tolist() == [
        False, True, True, True, False,
    ]  # fmt: skip
    assert isin_keys(np.array([], np.int64), kb).shape == (0,)
    assert not isin_keys(ka, np.array([], np.int64)).any()
