"""Tests of edeflare.io.dsec: the DSEC HDF5 layout, written and read by our own code."""

from __future__ import annotations

import itertools

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import random_events, same_events
from edeflare.errors import EventFileError
from edeflare.events import EVENT_DTYPE, empty_events, make_events
from edeflare.io import iter_windows, read_events, write_events
from edeflare.io.dsec import DsecReader, DsecWriter, read_dsec, write_dsec

T_ABS = 1_600_000_000_000_000  # about 1.6e15 µs: an absolute Unix time like AEDAT4's
BLOSC_FILTER_ID = 32001
BLOSC_ZSTD = 5


def files_in(folder):
    return sorted(p.name for p in folder.iterdir())


def check_ms_to_idx(path):
    """Assert the DSEC invariant on a file: t[idx[ms]] >= ms*1000 > t[idx[ms]-1]."""
    with h5py.File(path, "r") as f:
        t = f["events/t"][()].astype(np.int64)
        idx = f["ms_to_idx"][()].astype(np.int64)
    n = t.size
    if n == 0:
        assert idx.size == 0
        return idx
    assert idx.size == t[-1] // 1000 + 1
    assert (np.diff(idx) >= 0).all()
    assert idx.min() >= 0 and idx.max() <= n - 1  # every millisecond up to t[-1] has an event
    for ms, i in enumerate(idx):
        assert t[i] >= ms * 1000
        if i > 0:
            assert ms * 1000 > t[i - 1]
    return idx


# -- layout ------------------------------------------------------------------------------


def test_layout_dtypes_offset_and_compression(tmp_path):
    ev = make_events(
        [T_ABS, T_ABS + 999, T_ABS + 1000, T_ABS + 1000, T_ABS + 3500, T_ABS + 3999, T_ABS + 4000],
        [0, 1, 2, 3, 4, 5, 345],
        [0, 259, 2, 3, 4, 5, 6],
        [1, 0, 1, 1, 0, 0, 1],
    )
    path = tmp_path / "rec.h5"
    write_dsec(path, ev, (346, 260))
    assert files_in(tmp_path) == ["rec.h5"]
    with h5py.File(path, "r") as f:
        g = f["events"]
        dtypes = {k: g[k].dtype.str for k in "xypt"}
        assert dtypes == {"x": "<u2", "y": "<u2", "p": "|u1", "t": "<u4"}
        assert f["ms_to_idx"].dtype.str == "<u8"
        assert f["t_offset"].dtype.str == "<i8" and f["t_offset"].shape == ()
        assert int(f["t_offset"][()]) == T_ABS  # default: the first event's time
        assert g["t"][()].tolist() == [0, 999, 1000, 1000, 3500, 3999, 4000]
        assert g["x"][()].tolist() == [0, 1, 2, 3, 4, 5, 345]
        assert g["p"][()].tolist() == [1, 0, 1, 1, 0, 0, 1]
        # ms 0 -> 0, ms 1 -> first t >= 1000 (index 2), ms 2 and 3 -> 3500 (index 4), ms 4 -> 6
        assert f["ms_to_idx"][()].tolist() == [0, 2, 4, 4, 6]
        assert f.attrs["sensor_size"].tolist() == [346, 260]
        for k in "xypt":
            # Blosc (HDF5 filter 32001); its 7th parameter is the codec, 5 = zstd
            filter_id, _, params, _ = g[k].id.get_create_plist().get_filter(0)
            assert filter_id == BLOSC_FILTER_ID and params[6] == BLOSC_ZSTD
    check_ms_to_idx(path)


def test_explicit_t_offset(tmp_path):
    ev = make_events([T_ABS, T_ABS + 2500], [0, 1], [0, 0], [1, 0])
    path = tmp_path / "rec.h5"
    write_dsec(path, ev, (2, 1), t_offset_us=T_ABS - 1234)
    with h5py.File(path, "r") as f:
        assert int(f["t_offset"][()]) == T_ABS - 1234
        assert f["events/t"][()].tolist() == [1234, 3734]
        assert f["ms_to_idx"][()].tolist() == [0, 0, 1, 1]
    events, size = read_dsec(path)
    assert events["t"].tolist() == [T_ABS, T_ABS + 2500]
    assert size == (2, 1)
    with DsecReader(path) as r:
        assert r.t_offset == T_ABS - 1234
        assert r.time_range() == (T_ABS, T_ABS + 2500)


def test_events_before_t_offset_are_rejected_and_leave_no_file(tmp_path):
    ev = make_events([T_ABS, T_ABS + 5], [0, 1], [0, 0], [1, 0])
    with pytest.raises(EventFileError, match="uint32") as info:
        write_dsec(tmp_path / "rec.h5", ev, (2, 1), t_offset_us=T_ABS + 1)
    assert "rec.h5" in str(info.value)
    assert files_in(tmp_path) == []


def test_empty_stream(tmp_path):
    path = tmp_path / "empty.h5"
    write_dsec(path, empty_events(), (640, 480))
    with h5py.File(path, "r") as f:
        assert f["events/t"].shape == (0,)
        assert f["ms_to_idx"].shape == (0,)
        assert int(f["t_offset"][()]) == 0
    events, size = read_dsec(path)
    assert events.dtype == EVENT_DTYPE and events.size == 0 and size == (640, 480)
    with DsecReader(path) as r:
        assert r.n_events == 0 and r.time_range() is None
        assert r.index_of(123) == 0 and r.read_time(0, 10**6).size == 0


# -- round trips and the ms_to_idx invariant ---------------------------------------------


@st.composite
def streams(draw):
    n = draw(st.integers(0, 80))
    t0 = draw(st.sampled_from([0, 1, 999, T_ABS, T_ABS + 12_345_678, 10**12]))
    deltas = draw(
        st.lists(
            st.one_of(st.integers(0, 3), st.integers(0, 2_000), st.integers(0, 5_000_000)),
            min_size=n,
            max_size=n,
        )
    )
    t = t0 + np.cumsum(np.asarray(deltas, dtype=np.int64))
    xs = draw(st.lists(st.integers(0, 345), min_size=n, max_size=n))
    ys = draw(st.lists(st.integers(0, 259), min_size=n, max_size=n))
    ps = draw(st.lists(st.integers(0, 1), min_size=n, max_size=n))
    return make_events(t, xs, ys, ps)


@settings(max_examples=60)
@given(events=streams())
def test_property_round_trip_and_ms_to_idx(tmp_path, events):
    path = tmp_path / "prop.h5"
    write_dsec(path, events, (346, 260))
    back, size = read_dsec(path)
    assert size == (346, 260)
    assert same_events(back, events)
    idx = check_ms_to_idx(path)
    if events.size:
        assert idx.size == (int(events["t"][-1]) - int(events["t"][0])) // 1000 + 1


def test_ms_to_idx_with_long_silences(tmp_path, rng):
    parts = [
        random_events(rng, 500, (64, 64), t0=T_ABS + 17, span_us=3_000),
        random_events(rng, 1, (64, 64), t0=T_ABS + 250_000, span_us=1),
        random_events(rng, 800, (64, 64), t0=T_ABS + 2_000_000, span_us=10_000),
        random_events(rng, 3, (64, 64), t0=T_ABS + 2_010_000, span_us=1),
    ]
    ev = np.concatenate(parts)
    path = tmp_path / "gaps.h5"
    write_dsec(path, ev, (64, 64))
    idx = check_ms_to_idx(path)
    # during the silence 3 ms .. 250 ms every entry points at the lone event
    assert (idx[4:250] == 500).all()
    assert same_events(read_dsec(path)[0], ev)


def test_relative_times_at_the_uint32_limit(tmp_path):
    limit = 2**32 - 1
    ev = make_events([T_ABS, T_ABS + limit], [0, 1], [0, 0], [1, 0])
    path = tmp_path / "ok.h5"
    write_dsec(path, ev, (2, 1))
    assert read_dsec(path)[0]["t"].tolist() == [T_ABS, T_ABS + limit]
    with h5py.File(path, "r") as f:
        assert f["ms_to_idx"].shape == (limit // 1000 + 1,)
        assert int(f["ms_to_idx"][-1]) == 1


def test_relative_times_beyond_uint32_raise_and_leave_no_file(tmp_path):
    ev = make_events([T_ABS, T_ABS + 2**32], [0, 1], [0, 0], [1, 0])
    with pytest.raises(EventFileError, match="uint32") as info:
        write_dsec(tmp_path / "long.h5", ev, (2, 1))
    assert str(tmp_path / "long.h5") in str(info.value)
    assert files_in(tmp_path) == []


def test_relative_times_beyond_uint32_through_write_events_name_the_target(tmp_path):
    target = tmp_path / "long.h5"
    ev = make_events([T_ABS, T_ABS + 2**32], [0, 1], [0, 0], [1, 0])
    with pytest.raises(EventFileError, match="uint32") as info:
        write_events(target, ev, (2, 1))
    assert files_in(tmp_path) == []
    # The user must be told about the file they asked for, not a temporary name.
    assert info.value.path == str(target)
    assert str(info.value).startswith(f"{target}: ")


# -- chunked writing ---------------------------------------------------------------------


def test_chunked_writer_equals_single_write(tmp_path, rng):
    ev = np.concatenate(
        [
            random_events(rng, 3000, (32, 24), t0=T_ABS, span_us=40_000),
            random_events(rng, 10, (32, 24), t0=T_ABS + 900_000, span_us=500),
        ]
    )
    ev["t"][1500:1510] = ev["t"][1500]  # ties across a chunk boundary below
    ev["t"][1510:] = np.maximum(ev["t"][1510:], ev["t"][1500])
    write_dsec(tmp_path / "one.h5", ev, (32, 24))
    cuts = [0, 0, 1, 1505, 1505, 2999, 3005, ev.size]
    with DsecWriter(tmp_path / "many.h5", (32, 24)) as w:
        for a, b in itertools.pairwise(cuts):
            w.append(ev[a:b])
        assert w.n_events == ev.size
    with h5py.File(tmp_path / "one.h5", "r") as f1, h5py.File(tmp_path / "many.h5", "r") as f2:
        for name in ("events/x", "events/y", "events/p", "events/t", "ms_to_idx", "t_offset"):
            assert np.array_equal(f1[name][()], f2[name][()]), name
        assert f1.attrs["sensor_size"].tolist() == f2.attrs["sensor_size"].tolist()
    check_ms_to_idx(tmp_path / "many.h5")
    assert files_in(tmp_path) == ["many.h5", "one.h5"]


def test_writer_appears_only_on_close(tmp_path):
    w = DsecWriter(tmp_path / "late.h5", (4, 4))
    w.append(make_events([10], [1], [1], [1]))
    assert not (tmp_path / "late.h5").exists()
    w.close()
    w.close()  # idempotent
    assert read_dsec(tmp_path / "late.h5")[0]["t"].tolist() == [10]
    assert files_in(tmp_path) == ["late.h5"]


def test_writer_chunk_out_of_order_raises_and_leaves_no_file(tmp_path):
    with pytest.raises(EventFileError, match="before the previous chunk") as info:
        with DsecWriter(tmp_path / "bad.h5", (4, 4)) as w:
            w.append(make_events([10, 20], [0, 1], [0, 0], [1, 1]))
            w.append(make_events([19], [0], [0], [1]))
    assert "bad.h5" in str(info.value)
    assert files_in(tmp_path) == []


def test_writer_exception_in_with_block_leaves_old_file(tmp_path):
    path = tmp_path / "keep.h5"
    write_dsec(path, make_events([1, 2], [0, 1], [0, 0], [1, 0]), (2, 1))
    before = path.read_bytes()
    with pytest.raises(RuntimeError), DsecWriter(path, (2, 1)) as w:
        w.append(make_events([5], [0], [0], [1]))
        raise RuntimeError("interrupted")
    assert path.read_bytes() == before
    assert files_in(tmp_path) == ["keep.h5"]


def test_writer_rejects_events_off_the_sensor(tmp_path):
    with (
        pytest.raises(EventFileError, match="x out of range"),
        DsecWriter(tmp_path / "off.h5", (4, 4)) as w,
    ):
        w.append(make_events([0], [4], [0], [1]))
    assert files_in(tmp_path) == []


def test_writer_into_an_impossible_folder_raises_a_project_error(tmp_path):
    blocker = tmp_path / "plain_file"
    blocker.write_bytes(b"data")
    with pytest.raises(EventFileError) as info:
        write_dsec(blocker / "rec.h5", make_events([0], [0], [0], [1]), (1, 1))
    assert str(blocker / "rec.h5") in str(info.value)
    assert files_in(tmp_path) == ["plain_file"]


# -- reading other writers' files ---------------------------------------------------------


def _write_dsec_by_hand(path, events, group, t_offset, *, with_ms_to_idx=True, p=None):
    rel = events["t"] - t_offset
    with h5py.File(path, "w") as f:
        g = f.create_group(group)
        g.create_dataset("x", data=events["x"])
        g.create_dataset("y", data=events["y"])
        g.create_dataset("p", data=events["p"] if p is None else p)
        g.create_dataset("t", data=rel.astype(np.uint32))
        if with_ms_to_idx:
            ms = np.arange(int(rel[-1]) // 1000 + 1) * 1000
            f.create_dataset("ms_to_idx", data=np.searchsorted(rel, ms).astype(np.uint64))
        f.create_dataset("t_offset", data=np.int64(t_offset))


def test_reads_events_left_group(tmp_path, rng):
    ev = random_events(rng, 2000, (640, 480), t0=T_ABS + 5_000, span_us=300_000)
    path = tmp_path / "dsec_left.h5"
    _write_dsec_by_hand(path, ev, "events/left", T_ABS)
    with DsecReader(path) as r:
        assert r.group == "events/left"
        assert r.t_offset == T_ABS
        assert r.recorded_sensor_size is None
        assert same_events(r.read(), ev)
        assert same_events(
            r.read_time(T_ABS + 100_000, T_ABS + 200_000),
            ev[(ev["t"] >= T_ABS + 100_000) & (ev["t"] < T_ABS + 200_000)],
        )
    events, size = read_events(path, sensor_size=(640, 480))
    assert same_events(events, ev) and size == (640, 480)


def test_left_group_is_chosen_among_left_and_right(tmp_path, rng):
    left = random_events(rng, 100, (8, 8), t0=1000)
    right = random_events(rng, 50, (8, 8), t0=1000)
    path = tmp_path / "stereo.h5"
    _write_dsec_by_hand(path, left, "events/left", 0, with_ms_to_idx=False)
    with h5py.File(path, "a") as f:
        g = f.create_group("events/right")
        for k in "xyp":
            g.create_dataset(k, data=right[k])
        g.create_dataset("t", data=right["t"].astype(np.uint32))
    with DsecReader(path) as r:
        assert r.group == "events/left"
        assert same_events(r.read(), left)
    with DsecReader(path, group="events/right") as r:
        assert same_events(r.read(), right)


def test_two_groups_without_left_need_a_choice(tmp_path, rng):
    ev = random_events(rng, 10, (8, 8))
    path = tmp_path / "two.h5"
    with h5py.File(path, "w") as f:
        for name in ("a", "b"):
            g = f.create_group(name)
            for k in "xyp":
                g.create_dataset(k, data=ev[k])
            g.create_dataset("t", data=ev["t"].astype(np.uint32))
    with pytest.raises(EventFileError, match="several event groups"):
        DsecReader(path)
    with DsecReader(path, group="b") as r:
        assert same_events(r.read(), ev)


def test_polarity_stored_as_minus_one_plus_one(tmp_path):
    ev = make_events([0, 1, 2, 3], [0, 1, 2, 3], [0, 0, 0, 0], [0, 1, 1, 0])
    path = tmp_path / "pm1.h5"
    _write_dsec_by_hand(path, ev, "events", 0, p=np.array([-1, 1, 1, -1], dtype=np.int8))
    assert read_dsec(path)[0]["p"].tolist() == [0, 1, 1, 0]


# -- random access -----------------------------------------------------------------------


@pytest.mark.parametrize("with_ms_to_idx", [True, False])
def test_read_time_and_index_of_match_searchsorted(tmp_path, rng, with_ms_to_idx):
    ev = np.concatenate(
        [
            random_events(rng, 5000, (16, 16), t0=T_ABS + 10, span_us=20_000),
            random_events(rng, 200, (16, 16), t0=T_ABS + 3_000_000, span_us=5_000),
        ]
    )
    path = tmp_path / "ra.h5"
    if with_ms_to_idx:
        write_dsec(path, ev, (16, 16))
    else:
        _write_dsec_by_hand(path, ev, "events", T_ABS, with_ms_to_idx=False)
    t = ev["t"]
    queries = np.concatenate(
        [
            rng.integers(T_ABS - 5_000, T_ABS + 3_010_000, 300),
            t[rng.integers(0, t.size, 100)],  # exactly on events (ties)
            [0, T_ABS, t[0], t[-1], t[-1] + 1, 2**62],
        ]
    )
    with DsecReader(path) as r:
        assert r.n_events == ev.size
        assert r.time_range() == (int(t[0]), int(t[-1]))
        for q in queries:
            assert r.index_of(int(q)) == int(np.searchsorted(t, q, side="left")), q
        for a, b in rng.integers(T_ABS - 1_000, T_ABS + 3_010_000, (100, 2)):
            lo, hi = np.searchsorted(t, [a, b], side="left")
            assert same_events(r.read_time(int(a), int(b)), ev[lo : max(lo, hi)])
        chunks = list(r.iter_chunks(777))
        assert [c.size for c in chunks[:-1]] == [777] * (len(chunks) - 1)
        assert same_events(np.concatenate(chunks), ev)


def test_index_of_bisects_blocks_larger_than_65536_events(tmp_path, rng):
    # 150,000 events inside 3 ms, and no ms_to_idx: the reader bisects the dataset itself
    n = 150_000
    t = T_ABS + np.sort(rng.integers(0, 3_000, n))
    ev = make_events(t, rng.integers(0, 4, n), rng.integers(0, 4, n), rng.integers(0, 2, n))
    for with_idx in (True, False):
        path = tmp_path / f"dense{with_idx}.h5"
        _write_dsec_by_hand(path, ev, "events", T_ABS, with_ms_to_idx=with_idx)
        with DsecReader(path) as r:
            for q in [
                T_ABS,
                T_ABS + 1,
                T_ABS + 999,
                T_ABS + 1000,
                T_ABS + 1500,
                T_ABS + 2999,
                T_ABS + 3000,
                int(t[77_777]),
            ]:
                assert r.index_of(q) == int(np.searchsorted(t, q, side="left"))


def test_iter_windows_on_h5_uses_offsets(tmp_path, rng):
    ev = random_events(rng, 1000, (8, 8), t0=T_ABS + 3_333, span_us=100_000)
    path = tmp_path / "w.h5"
    write_dsec(path, ev, (8, 8))
    windows = list(iter_windows(path, 20_000))
    assert windows[0][0] == T_ABS  # aligned to a multiple of 20 ms in absolute time
    assert same_events(np.concatenate([w for _, w in windows]), ev)
