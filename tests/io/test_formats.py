"""Round trips through every writable format, and window streaming from files."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import edeflare.io.dat as dat_module
import edeflare.io.text as text_module
from conftest import random_events, same_events
from edeflare.errors import EventFileError
from edeflare.events import EVENT_DTYPE, empty_events, iter_time_windows, make_events
from edeflare.io import (
    EventSource,
    Recording,
    format_of,
    iter_windows,
    list_formats,
    open_events,
    read_events,
    write_event_chunks,
    write_events,
)
from edeflare.io.faery_formats import read_raw_header

T_ABS = 1_600_000_000_000_000

# (suffix, evt_version): every format edeflare writes
WRITABLE = [
    (".h5", "evt3"),
    (".hdf5", "evt3"),
    (".raw", "evt3"),
    (".raw", "evt2"),
    (".dat", "evt3"),
    (".aedat4", "evt3"),
    (".es", "evt3"),
    (".csv", "evt3"),
    (".npz", "evt3"),
    (".txt", "evt3"),
]
WRITABLE_IDS = [s[1:] + ("-" + v if s == ".raw" else "") for s, v in WRITABLE]


def expected_times(suffix, t):
    """Times a format gives back: ``.es`` has no offset field and starts at the first event."""
    if suffix == ".es" and t.size:
        return t - t[0]
    return t


def files_in(folder):
    return sorted(p.name for p in folder.iterdir())


def hand_events():
    # corners of a 640x480 sensor, ties in t, both polarities, a 2 s silence
    return make_events(
        [1_000_005, 1_000_010, 1_000_010, 1_050_000, 3_000_123, 3_000_124],
        [0, 5, 639, 100, 7, 639],
        [0, 479, 3, 200, 8, 479],
        [1, 0, 1, 0, 1, 0],
    )


def test_list_formats_and_names():
    assert list_formats() == [
        ".h5",
        ".hdf5",
        ".raw",
        ".dat",
        ".aedat4",
        ".es",
        ".csv",
        ".npz",
        ".txt",
    ]
    assert format_of("a.H5") == "DSEC HDF5"
    assert format_of("drive.raw") == "Prophesee EVT"
    assert format_of("x/y/rec.aedat4") == "AEDAT 4"


@pytest.mark.parametrize(("suffix", "evt"), WRITABLE, ids=WRITABLE_IDS)
def test_round_trip_hand_events(tmp_path, suffix, evt):
    ev = hand_events()
    path = tmp_path / f"rec{suffix}"
    write_events(path, ev, (640, 480), evt_version=evt)
    assert files_in(tmp_path) == [path.name]  # no temporary file left behind
    events, size = read_events(path)
    assert size == (640, 480)
    assert events.dtype == EVENT_DTYPE
    if suffix == ".es":
        assert events["t"].tolist() == [0, 5, 5, 49_995, 2_000_118, 2_000_119]
    else:
        assert events["t"].tolist() == ev["t"].tolist()
    assert events["x"].tolist() == ev["x"].tolist()
    assert events["y"].tolist() == ev["y"].tolist()
    assert events["p"].tolist() == ev["p"].tolist()


@pytest.mark.parametrize(("suffix", "evt"), WRITABLE, ids=WRITABLE_IDS)
def test_round_trip_random_absolute_times(tmp_path, rng, suffix, evt):
    ev = random_events(rng, 5000, (346, 260), t0=T_ABS + 123, span_us=5_000_000)
    path = tmp_path / f"rec{suffix}"
    write_events(path, ev, (346, 260), evt_version=evt)
    recording = read_events(path)
    assert isinstance(recording, Recording)
    assert recording.sensor_size == (346, 260)  # from the file, not inferred from max + 1
    events = recording.events
    assert np.array_equal(events["t"], expected_times(suffix, ev["t"]))
    for k in ("x", "y", "p"):
        assert np.array_equal(events[k], ev[k]), k


@pytest.mark.parametrize(("suffix", "evt"), WRITABLE, ids=WRITABLE_IDS)
def test_round_trip_empty_stream_keeps_sensor_size(tmp_path, suffix, evt):
    path = tmp_path / f"empty{suffix}"
    chunks = [empty_events(), empty_events()]
    assert write_event_chunks(path, chunks, (320, 240), evt_version=evt) == 0
    events, size = read_events(path)
    assert events.dtype == EVENT_DTYPE and events.size == 0
    assert size == (320, 240)


@pytest.mark.parametrize(("suffix", "evt"), WRITABLE, ids=WRITABLE_IDS)
def test_write_event_chunks_equals_one_write(tmp_path, rng, suffix, evt):
    ev = random_events(rng, 3000, (64, 48), t0=T_ABS, span_us=300_000)
    chunks = [ev[:0], ev[:1000], ev[1000:1000], ev[1000:2999], ev[2999:]]
    n = write_event_chunks(tmp_path / f"c{suffix}", chunks, (64, 48), evt_version=evt)
    assert n == ev.size
    write_events(tmp_path / f"w{suffix}", ev, (64, 48), evt_version=evt)
    assert same_events(
        read_events(tmp_path / f"c{suffix}").events, read_events(tmp_path / f"w{suffix}").events
    )


def test_raw_header_records_version_and_geometry(tmp_path):
    for evt, version in (("evt3", "evt3"), ("evt2", "evt2")):
        path = tmp_path / f"{evt}.raw"
        write_events(path, hand_events(), (640, 480), evt_version=evt)
        header = read_raw_header(path)
        assert header.version == version
        assert header.sensor_size == (640, 480)


def test_overwrites_an_existing_file(tmp_path):
    path = tmp_path / "again.npz"
    write_events(path, hand_events(), (640, 480))
    write_events(path, hand_events()[:2], (800, 600))
    events, size = read_events(path)
    assert events.size == 2 and size == (800, 600)
    assert files_in(tmp_path) == ["again.npz"]


@pytest.mark.parametrize("suffix", [".h5", ".raw", ".npz", ".txt", ".dat"])
def test_written_files_get_the_usual_permissions(tmp_path, suffix):
    """Atomic writes go through a private temporary file; the result must not stay 0600."""
    mask = os.umask(0o022)
    try:
        path = tmp_path / f"mode{suffix}"
        write_events(path, hand_events(), (640, 480))
        assert stat.S_IMODE(path.stat().st_mode) == 0o644
    finally:
        os.umask(mask)


def test_raw_round_trip_of_a_sparse_stream_longer_than_the_24_bit_clock(tmp_path):
    """EVT 2.0 (the default) keeps 34-bit times: 40 s of sparse events read back exactly.

    One event every 100 ms for 40 s: EVT 3.0's 24-bit clock (16.78 s) would wrap twice.
    """
    t = T_ABS + np.arange(0, 40_000_000, 100_000)
    ev = make_events(t, t % 7, t % 5, (t // 100_000) % 2)
    path = tmp_path / "long_evt2.raw"
    write_events(path, ev, (8, 8))
    events = read_events(path).events
    assert same_events(events, ev)


def test_evt3_refuses_streams_longer_than_its_clock(tmp_path):
    """faery 0.7 writes EVT 3.0 that no reader can unwrap past 16.78 s (232 of these 400
    timestamps came back clamped), so such a write is refused instead of corrupted."""
    t = T_ABS + np.arange(0, 40_000_000, 100_000)
    ev = make_events(t, t % 7, t % 5, (t // 100_000) % 2)
    with pytest.raises(EventFileError, match=r"must span less than 16\.8 s"):
        write_events(tmp_path / "long_evt3.raw", ev, (8, 8), evt_version="evt3")
    assert list(tmp_path.iterdir()) == []


# -- sensor size sources -----------------------------------------------------------------


def test_sensor_size_option_overrides_the_file(tmp_path):
    path = tmp_path / "s.npz"
    write_events(path, hand_events(), (640, 480))
    src = open_events(path, sensor_size=(1280, 720))
    assert src.sensor_size == (1280, 720) and src.sensor_size_source == "option"
    assert src.recorded_sensor_size == (640, 480)
    src = EventSource(path)
    assert src.sensor_size == (640, 480) and src.sensor_size_source == "file"


def test_sensor_size_inferred_with_a_warning_for_headerless_text(tmp_path):
    path = tmp_path / "bare.txt"
    path.write_text("10 3 4 1\n20 7 1 0\n")
    src = open_events(path)
    assert src.sensor_size_source == "inferred"
    with pytest.warns(UserWarning, match=r"no sensor size recorded; using 8x5"):
        assert src.sensor_size == (8, 5)
    events, size = read_events(path, sensor_size=(640, 480))
    assert events["t"].tolist() == [10, 20] and size == (640, 480)


# -- text variants -------------------------------------------------------------------------


def test_csv_header_in_any_column_order(tmp_path):
    path = tmp_path / "cols.csv"
    path.write_text("x@32,polarity,t,y@16\n3,1,100,4\n5,0,105,6\n")
    events, size = read_events(path)
    assert size == (32, 16)
    assert events[["t", "x", "y", "p"]].tolist() == [(100, 3, 4, 1), (105, 5, 6, 0)]


def test_txt_with_decimal_times_is_read_as_seconds(tmp_path):
    path = tmp_path / "rpg.txt"
    path.write_text("240 180\n0.000005 1 2 1\n1.250000 3 4 0\n")
    events, size = read_events(path)
    assert size == (240, 180)
    assert events["t"].tolist() == [5, 1_250_000]
    assert events["p"].tolist() == [1, 0]


def test_npz_with_signed_polarity(tmp_path):
    path = tmp_path / "pm.npz"
    np.savez(
        path,
        t=np.array([1, 2, 3]),
        x=np.array([0, 1, 2]),
        y=np.array([0, 0, 0]),
        p=np.array([-1, 1, -1]),
        width=4,
        height=1,
    )
    events, size = read_events(path)
    assert events["p"].tolist() == [0, 1, 0] and size == (4, 1)


# -- windows from files --------------------------------------------------------------------


def _windows(iterator):
    return [(s, w["t"].tolist(), w["x"].tolist(), w["p"].tolist()) for s, w in iterator]


def _stream_with_silences(rng):
    return np.concatenate(
        [
            random_events(rng, 400, (16, 16), t0=T_ABS + 7_000, span_us=30_000),
            random_events(rng, 5, (16, 16), t0=T_ABS + 95_000, span_us=2_000),
            random_events(rng, 300, (16, 16), t0=T_ABS + 180_000, span_us=20_000),
        ]
    )


@pytest.mark.parametrize("suffix", [".h5", ".raw", ".dat", ".txt", ".npz", ".aedat4"])
@pytest.mark.parametrize(
    ("window", "start", "end"),
    [
        (10_000, None, None),
        (7_777, None, None),
        (20_000, T_ABS, T_ABS + 300_000),  # explicit: empty windows at the end
        (10_000, T_ABS - 50_000, None),  # empty windows before the first event
        (10_000, T_ABS + 12_345, T_ABS + 100_000),  # unaligned start, end inside the data
        (10_000, T_ABS + 400_000, T_ABS + 420_000),  # all after the events: empty
        (1_000, T_ABS + 90_000, T_ABS + 92_000),  # inside a silence
    ],
)
def test_iter_windows_equals_iter_time_windows(tmp_path, rng, suffix, window, start, end):
    ev = _stream_with_silences(rng)
    path = tmp_path / f"w{suffix}"
    write_events(path, ev, (16, 16))
    got = _windows(iter_windows(path, window, start_us=start, end_us=end))
    expected = _windows(iter_time_windows(ev, window, start_us=start, end_us=end))
    assert got == expected
    assert any(not w[1] for w in expected) or start is None  # empty windows are compared too


@pytest.mark.parametrize("suffix", [".dat", ".txt"])
def test_iter_windows_across_many_small_chunks(tmp_path, rng, monkeypatch, suffix):
    monkeypatch.setattr(dat_module, "_CHUNK", 7)
    monkeypatch.setattr(text_module, "_TEXT_CHUNK_LINES", 5)
    ev = _stream_with_silences(rng)
    path = tmp_path / f"small{suffix}"
    write_events(path, ev, (16, 16))
    assert len(list(open_events(path).chunks())) > 50
    for window, start, end in [(3_000, None, None), (10_000, T_ABS, T_ABS + 250_000)]:
        got = _windows(iter_windows(path, window, start_us=start, end_us=end))
        assert got == _windows(iter_time_windows(ev, window, start_us=start, end_us=end))


@pytest.mark.parametrize("suffix", [".h5", ".npz", ".raw"])
def test_iter_windows_on_an_empty_file(tmp_path, suffix):
    path = tmp_path / f"empty{suffix}"
    write_events(path, empty_events(), (4, 4))
    assert list(iter_windows(path, 1000)) == []
    got = [(s, len(w)) for s, w in iter_windows(path, 1000, start_us=0, end_us=2500)]
    assert got == [(0, 0), (1000, 0), (2000, 0)]


def test_iter_windows_rejects_non_positive_window(tmp_path):
    path = tmp_path / "w.npz"
    write_events(path, hand_events(), (640, 480))
    with pytest.raises(ValueError, match="window_us must be positive"):
        list(iter_windows(path, 0))


# -- property test -------------------------------------------------------------------------


@st.composite
def npz_streams(draw):
    n = draw(st.integers(0, 50))
    t0 = draw(st.integers(-(10**15), 2 * 10**15))
    deltas = draw(st.lists(st.integers(0, 10**9), min_size=n, max_size=n))
    width = draw(st.integers(1, 65536))
    height = draw(st.integers(1, 65536))
    xs = draw(st.lists(st.integers(0, width - 1), min_size=n, max_size=n))
    ys = draw(st.lists(st.integers(0, height - 1), min_size=n, max_size=n))
    ps = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    t = t0 + np.cumsum(np.asarray(deltas, dtype=np.int64))
    return make_events(t, xs, ys, ps), (width, height)


@settings(max_examples=60)
@given(case=npz_streams())
def test_property_npz_round_trip(tmp_path, case):
    events, size = case
    path = tmp_path / "prop.npz"
    write_events(path, events, size)
    back, back_size = read_events(path)
    assert back_size == size
    assert same_events(back, events)


# -- DAT details -----------------------------------------------------------------------------


def _dat_file(path, header, t32, data):
    records = np.empty(len(t32), dtype=[("t", "<u4"), ("data", "<u4")])
    records["t"] = t32
    records["data"] = data
    path.write_bytes(header + bytes([0x0C, 8]) + records.tobytes())


@pytest.mark.parametrize("chunk", [1 << 20, 2, 3])
def test_dat_unwraps_32_bit_time(tmp_path, monkeypatch, chunk):
    monkeypatch.setattr(dat_module, "_CHUNK", chunk)
    path = tmp_path / "wrap.dat"
    t32 = [4_294_967_000, 4_294_967_295, 0, 100, 4_294_967_200, 5]
    _dat_file(path, b"% Version 2\n% Width 8\n% Height 8\n% t0 7\n", t32, [0] * 6)
    events = read_events(path).events
    assert events["t"].tolist() == [
        7 + 4_294_967_000,
        7 + 4_294_967_295,
        7 + 2**32,
        7 + 2**32 + 100,
        7 + 2**32 + 4_294_967_200,
        7 + 2**33 + 5,
    ]


def test_dat_version_1_bit_layout(tmp_path):
    path = tmp_path / "v1.dat"
    # x in bits 0-8, y in bits 9-16, polarity in bit 17
    data = [303 | (239 << 9) | (1 << 17), 5 | (7 << 9)]
    _dat_file(path, b"% Version 1\n% Width 304\n% Height 240\n", [10, 20], data)
    events, size = read_events(path)
    assert size == (304, 240)
    assert events[["t", "x", "y", "p"]].tolist() == [(10, 303, 239, 1), (20, 5, 7, 0)]


def test_dat_version_2_bit_layout_and_header(tmp_path):
    path = tmp_path / "v2.dat"
    write_events(path, make_events([T_ABS, T_ABS + 3], [1279, 2], [719, 3], [1, 0]), (1280, 720))
    data = path.read_bytes()
    assert b"% Width 1280\n% Height 720\n" in data and f"% t0 {T_ABS}\n".encode() in data
    records = np.frombuffer(data[-16:], dtype=[("t", "<u4"), ("data", "<u4")])
    assert records["t"].tolist() == [0, 3]
    assert records["data"].tolist() == [1279 | (719 << 14) | (1 << 28), 2 | (3 << 14)]
