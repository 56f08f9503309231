"""Bad input: every problem raises EventFileError naming the file, and nothing is left behind."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from edeflare.errors import EdeflareError, EventFileError, UnknownFormatError
from edeflare.events import EVENT_DTYPE, make_events
from edeflare.io import iter_windows, list_formats, open_events, read_events, write_events

GOOD = make_events([0, 10, 20], [0, 1, 3], [0, 2, 3], [1, 0, 1])
SIZE = (4, 4)
WRITE_SUFFIXES = [".h5", ".raw", ".dat", ".aedat4", ".es", ".csv", ".npz", ".txt"]


def files_in(folder):
    return sorted(p.name for p in folder.iterdir())


def assert_read_fails(path, match=None, **kwargs):
    """read_events raises EventFileError naming ``path``; the folder is left as it was."""
    before = files_in(path.parent)
    with pytest.raises(EventFileError, match=match) as info:
        read_events(path, **kwargs)
    assert info.value.path == str(path)
    assert str(path) in str(info.value)
    assert files_in(path.parent) == before
    return info.value


def assert_write_fails(path, events, size=SIZE, match=None, **kwargs):
    """write_events raises EventFileError naming ``path`` and leaves the folder unchanged."""
    before = {p.name: p.read_bytes() for p in path.parent.iterdir()}
    with pytest.raises(EventFileError, match=match) as info:
        write_events(path, events, size, **kwargs)
    assert str(path) in str(info.value)
    after = {p.name: p.read_bytes() for p in path.parent.iterdir()}
    assert after == before  # no new or partial file, an existing target byte-identical
    return info.value


def test_errors_are_project_value_errors():
    assert issubclass(EventFileError, EdeflareError) and issubclass(EventFileError, ValueError)
    assert issubclass(UnknownFormatError, EventFileError)
    exc = EventFileError("rec.h5", "file is empty")
    assert str(exc) == "rec.h5: file is empty" and exc.path == "rec.h5"


# -- reading ---------------------------------------------------------------------------------


def test_unknown_suffix(tmp_path):
    path = tmp_path / "rec.bin"
    path.write_bytes(b"\x00" * 16)
    exc = assert_read_fails(path, match=r"unknown event file suffix '\.bin'")
    assert isinstance(exc, UnknownFormatError)
    assert ".aedat4" in str(exc)  # lists the known ones
    with pytest.raises(UnknownFormatError, match=r"rec\.mp4"):
        write_events(tmp_path / "rec.mp4", GOOD, SIZE)
    assert files_in(tmp_path) == ["rec.bin"]


def test_no_suffix(tmp_path):
    path = tmp_path / "recording"
    path.write_bytes(b"x")
    with pytest.raises(UnknownFormatError, match="recording"):
        read_events(path)


@pytest.mark.parametrize("suffix", list_formats())
def test_missing_file(tmp_path, suffix):
    assert_read_fails(tmp_path / f"absent{suffix}", match="no such file")


@pytest.mark.parametrize("name", ["dir.h5", "recordings"])
def test_a_folder_is_called_a_folder(tmp_path, name):
    folder = tmp_path / name
    folder.mkdir()
    exc = assert_read_fails(folder, match="is a folder")
    assert str(exc) == f"{folder}: is a folder, not an event file" and exc.path == str(folder)


@pytest.mark.parametrize("suffix", list_formats())
def test_empty_file(tmp_path, suffix):
    path = tmp_path / f"zero{suffix}"
    path.write_bytes(b"")
    assert_read_fails(path, match="file is empty")
    with pytest.raises(EventFileError, match="file is empty"):
        list(iter_windows(path, 1000))


def test_truncated_aedat4(tmp_path, real_data):
    data = (real_data / "davis346_flicker_lamps.aedat4").read_bytes()
    path = tmp_path / "half.aedat4"
    path.write_bytes(data[: len(data) // 2])
    assert_read_fails(path, match="corrupt or truncated")


def test_aedat4_cut_inside_its_header(tmp_path, real_data):
    data = (real_data / "davis346_flicker_lamps.aedat4").read_bytes()
    path = tmp_path / "head.aedat4"
    path.write_bytes(data[:100])
    assert_read_fails(path, match="truncated AEDAT 4 header")


def test_truncated_dat_odd_byte_count(tmp_path, real_data):
    data = (real_data / "atis_ncars_crop.dat").read_bytes()
    path = tmp_path / "odd.dat"
    path.write_bytes(data[:-3])
    assert_read_fails(path, match="truncated: .* not a multiple of 8")


def test_truncated_dat_written_by_us(tmp_path):
    path = tmp_path / "ours.dat"
    write_events(path, GOOD, SIZE)
    path.write_bytes(path.read_bytes()[:-1])
    assert_read_fails(path, match="not a multiple of 8")


def test_dat_header_without_records(tmp_path):
    path = tmp_path / "head.dat"
    path.write_bytes(b"% Version 2\n% Width 4\n% Height 4\n")
    assert_read_fails(path, match="no event type/size bytes")


def test_dat_with_unsupported_event_type(tmp_path):
    path = tmp_path / "imu.dat"
    path.write_bytes(b"% Version 2\n" + bytes([0x02, 16]) + b"\x00" * 16)
    assert_read_fails(path, match="unsupported DAT event type")


def test_garbage_h5(tmp_path):
    path = tmp_path / "garbage.h5"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    assert_read_fails(path, match="not a readable HDF5 file")


def test_text_file_named_h5(tmp_path):
    path = tmp_path / "text.h5"
    path.write_text("0 1 2 1\n")
    assert_read_fails(path, match="not a readable HDF5 file")


def test_h5_without_event_datasets(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("images", data=np.zeros((2, 3, 3)))
        g = f.create_group("events")
        g.create_dataset("x", data=np.zeros(3, dtype=np.uint16))
        g.create_dataset("t", data=np.zeros(3, dtype=np.uint32))  # no y, no p
    assert_read_fails(path, match="no group with datasets x, y, p, t")


def test_h5_with_mismatched_lengths(tmp_path):
    path = tmp_path / "ragged.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name, n in (("x", 3), ("y", 3), ("p", 2), ("t", 3)):
            g.create_dataset(name, data=np.zeros(n, dtype=np.uint16))
    assert_read_fails(path, match="one length")


def test_h5_with_float_timestamps(tmp_path):
    path = tmp_path / "float.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name in "xyp":
            g.create_dataset(name, data=np.zeros(3, dtype=np.uint16))
        g.create_dataset("t", data=np.array([0.0, 0.5, 1.0]))
    assert_read_fails(path, match="not integer")


def test_h5_with_bad_ms_to_idx(tmp_path):
    path = tmp_path / "badidx.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name in "xyp":
            g.create_dataset(name, data=np.zeros(3, dtype=np.uint8))
        g.create_dataset("t", data=np.array([0, 1000, 2000], dtype=np.uint32))
        f.create_dataset("ms_to_idx", data=np.array([0, 2, 1], dtype=np.uint64))
    assert_read_fails(path, match="ms_to_idx is not a valid index")


def test_h5_with_polarity_two(tmp_path):
    path = tmp_path / "p2.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        g.create_dataset("x", data=np.zeros(2, dtype=np.uint16))
        g.create_dataset("y", data=np.zeros(2, dtype=np.uint16))
        g.create_dataset("p", data=np.array([1, 2], dtype=np.uint8))
        g.create_dataset("t", data=np.array([0, 1], dtype=np.uint32))
        f.attrs["sensor_size"] = [4, 4]
    assert_read_fails(path, match="polarity")


def test_h5_unsorted(tmp_path):
    path = tmp_path / "unsorted.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        g.create_dataset("x", data=np.zeros(3, dtype=np.uint16))
        g.create_dataset("y", data=np.zeros(3, dtype=np.uint16))
        g.create_dataset("p", data=np.ones(3, dtype=np.uint8))
        g.create_dataset("t", data=np.array([0, 9, 3], dtype=np.uint32))
        f.attrs["sensor_size"] = [4, 4]
    assert_read_fails(path, match="not sorted")


def test_npz_missing_arrays(tmp_path):
    path = tmp_path / "partial.npz"
    np.savez(path, t=np.arange(3), x=np.arange(3))
    assert_read_fails(path, match=r"npz lacks arrays \['y', 'p'\]")


def test_npz_that_is_not_a_zip(tmp_path):
    path = tmp_path / "fake.npz"
    path.write_bytes(b"PK but not really a zip archive")
    assert_read_fails(path, match="not a readable npz archive")


def test_npz_with_nan_time(tmp_path):
    path = tmp_path / "nan.npz"
    np.savez(
        path,
        t=np.array([0.0, np.nan, 2.0]),
        x=np.arange(3),
        y=np.arange(3),
        p=np.ones(3),
        width=4,
        height=4,
    )
    assert_read_fails(path, match=r"t contains NaN or infinity \(first at index 1\)")


def test_npz_with_fractional_time(tmp_path):
    path = tmp_path / "frac.npz"
    np.savez(path, t=np.array([0.0, 1.5]), x=[0, 0], y=[0, 0], p=[1, 1], width=4, height=4)
    assert_read_fails(path, match="whole numbers")


def test_npz_events_off_its_own_sensor(tmp_path):
    path = tmp_path / "off.npz"
    np.savez(path, t=[0, 1], x=[0, 4], y=[0, 0], p=[1, 1], width=4, height=4)
    assert_read_fails(path, match="x out of range for sensor width 4: x=4 at index 1")


@pytest.mark.parametrize(
    ("name", "text"),
    [
        ("unsorted.txt", "4 4\n10 0 0 1\n20 1 1 0\n5 2 2 1\n"),
        ("unsorted.csv", "t,x,y,p\n10,0,0,1\n20,1,1,0\n5,2,2,1\n"),
        ("unsorted_nohead.csv", "10,0,0,1\n20,1,1,0\n5,2,2,1\n"),
    ],
)
def test_text_with_unsorted_timestamps(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    assert_read_fails(path, match="not sorted", sensor_size=SIZE)


def test_text_unsorted_across_blocks(tmp_path, monkeypatch):
    import edeflare.io.text as text_module

    monkeypatch.setattr(text_module, "_TEXT_CHUNK_LINES", 2)
    path = tmp_path / "blocks.txt"
    path.write_text("4 4\n10 0 0 1\n20 1 1 0\n15 2 2 1\n30 2 2 1\n")
    assert_read_fails(path, match="not sorted near line 4")


def test_csv_with_a_non_numeric_field(tmp_path):
    path = tmp_path / "word.csv"
    path.write_text("t,x,y,p\n10,0,0,1\n11,abc,1,0\n")
    assert_read_fails(path, match="malformed line", sensor_size=SIZE)


def test_csv_header_without_polarity(tmp_path):
    path = tmp_path / "nop.csv"
    path.write_text("t,x,y,brightness\n10,0,0,1\n")
    assert_read_fails(path, match="must name columns t, x, y and p")


def test_txt_with_three_columns(tmp_path):
    path = tmp_path / "three.txt"
    path.write_text("10 0 0\n11 1 1\n")
    assert_read_fails(path, match="need 4 columns")


def test_txt_with_words_first(tmp_path):
    path = tmp_path / "words.txt"
    path.write_text("time x y polarity\n10 0 0 1\n")
    assert_read_fails(path, match="is not 't x y p' numbers")


def test_txt_with_bad_polarity(tmp_path):
    path = tmp_path / "pol.txt"
    path.write_text("4 4\n10 0 0 3\n")
    assert_read_fails(path, match="p values must lie")


def test_raw_without_header(tmp_path):
    path = tmp_path / "bare.raw"
    path.write_bytes(b"\x00\x80" * 8)
    assert_read_fails(path, match="no Prophesee '%' header")


def test_raw_header_without_version(tmp_path):
    path = tmp_path / "nover.raw"
    path.write_bytes(b"% geometry 4x4\n% end\n" + b"\x00\x80" * 8)
    assert_read_fails(path, match="names no EVT version")


def test_raw_with_events_off_the_sensor(tmp_path):
    path = tmp_path / "big.raw"
    write_events(path, make_events([0, 5], [0, 600], [0, 400], [1, 0]), (640, 480))
    assert_read_fails(path, sensor_size=(320, 240))


def test_bad_sensor_size_option(tmp_path):
    path = tmp_path / "ok.npz"
    write_events(path, GOOD, SIZE)
    assert_read_fails(path, match="sensor_size", sensor_size=(0, 4))
    with pytest.raises(EventFileError, match="sensor_size"):
        open_events(path, sensor_size=(4,))


# -- writing -----------------------------------------------------------------------------------


def _outside():
    return make_events([0, 10], [1, 4], [1, 2], [1, 0])


def _unsorted():
    ev = np.zeros(2, dtype=EVENT_DTYPE)
    ev["t"] = [10, 0]
    return ev


def _wrong_dtype():
    return np.zeros(2, dtype=[("t", "<i8"), ("x", "<i4"), ("y", "<u2"), ("p", "u1")])


def _polarity_two():
    ev = make_events([0, 1], [0, 1], [0, 1], [1, 0])
    ev["p"][1] = 2
    return ev


BAD_EVENTS = {
    "outside": (_outside, "x out of range for sensor width 4: x=4 at index 1"),
    "unsorted": (_unsorted, "not sorted"),
    "wrong_dtype": (_wrong_dtype, "structured array of dtype"),
    "polarity_two": (_polarity_two, "p=2 at index 1"),
}


@pytest.mark.parametrize("suffix", WRITE_SUFFIXES)
@pytest.mark.parametrize("kind", sorted(BAD_EVENTS))
def test_bad_events_write_nothing(tmp_path, suffix, kind):
    make, message = BAD_EVENTS[kind]
    assert_write_fails(tmp_path / f"new{suffix}", make(), match=message)
    assert files_in(tmp_path) == []


@pytest.mark.parametrize("suffix", WRITE_SUFFIXES)
@pytest.mark.parametrize("kind", sorted(BAD_EVENTS))
def test_bad_events_leave_an_existing_target_unchanged(tmp_path, suffix, kind):
    target = tmp_path / f"old{suffix}"
    write_events(target, GOOD, SIZE)
    make, message = BAD_EVENTS[kind]
    assert_write_fails(target, make(), match=message)
    assert files_in(tmp_path) == [target.name]
    assert read_events(target).events["t"].tolist() == [0, 10, 20]


@pytest.mark.parametrize("suffix", WRITE_SUFFIXES)
def test_bad_sensor_size_writes_nothing(tmp_path, suffix):
    assert_write_fails(tmp_path / f"s{suffix}", GOOD, size=(0, 4), match="sensor_size")


def test_chunks_out_of_order_write_nothing(tmp_path):
    from edeflare.io import write_event_chunks

    path = tmp_path / "chunks.npz"
    with pytest.raises(EventFileError, match="chunks are not in time order"):
        write_event_chunks(path, [GOOD, make_events([5], [0], [0], [1])], SIZE)
    assert files_in(tmp_path) == []


def test_unknown_evt_version(tmp_path):
    assert_write_fails(tmp_path / "v.raw", GOOD, match="evt_version", evt_version="evt4")


def test_evt21_write_is_refused_by_name_before_any_file_is_opened(tmp_path):
    """``write_events`` accepts evt2 and evt3 only: faery 0.7 cannot encode EVT 2.1."""
    assert_write_fails(tmp_path / "v21.raw", GOOD, match="evt2 or evt3", evt_version="evt2.1")


def test_a_faery_panic_while_encoding_becomes_a_project_error(tmp_path):
    """Below that check, faery's EVT 2.1 encoder panics (``todo!``): a pyo3 PanicException,
    a BaseException, which ``write_faery`` must turn into an EventFileError naming the file."""
    from edeflare.io.faery_formats import write_faery

    target = tmp_path / "v21.raw"
    try:
        write_faery(target, [GOOD], SIZE, target=target, evt_version="evt2.1")
    except EventFileError as exc:
        assert str(target) in str(exc) and "cannot write" in str(exc)
    except BaseException as exc:  # a Rust panic is a BaseException: the point of the test
        pytest.fail(f"evt2.1 write raised {type(exc).__module__}.{type(exc).__name__}: {exc}")
    else:  # if faery ever encodes it, reading it back must give the events
        assert read_events(target).events["t"].tolist() == [0, 10, 20]


def test_evt21_raw_read_raises_a_project_error(tmp_path):
    """A '% evt 2.1' file: faery 0.7's decoder panics (todo!), which must become EventFileError."""
    path = tmp_path / "v21.raw"
    path.write_bytes(b"% evt 2.1\n% geometry 4x4\n% end\n" + bytes(64))
    try:
        read_events(path)
    except EventFileError as exc:
        assert str(path) in str(exc)
    except BaseException as exc:  # a Rust panic is a BaseException: the point of the test
        pytest.fail(f"reading EVT 2.1 raised {type(exc).__module__}.{type(exc).__name__}: {exc}")
    assert files_in(tmp_path) == ["v21.raw"]


def test_evt3_span_of_16_8_s_raises(tmp_path):
    ev = make_events([0, 1 << 24], [0, 1], [0, 1], [1, 0])
    message = r"EVT3 output must span less than 16\.8 s"
    assert_write_fails(tmp_path / "gap.raw", ev, match=message, evt_version="evt3")
    assert files_in(tmp_path) == []


def test_evt3_span_across_chunks_raises(tmp_path):
    from edeflare.io import write_event_chunks

    path = tmp_path / "gapchunks.raw"
    chunks = [
        make_events([5, 6], [0, 1], [0, 1], [1, 0]),
        make_events([6 + (1 << 24)], [0], [0], [1]),
    ]
    with pytest.raises(EventFileError, match=r"spans 16\.8 s"):
        write_event_chunks(path, chunks, SIZE, evt_version="evt3")
    assert files_in(tmp_path) == []


def test_evt3_gap_just_below_the_limit_is_written(tmp_path):
    ev = make_events([0, (1 << 24) - 1], [0, 1], [0, 1], [1, 0])
    path = tmp_path / "justok.raw"
    write_events(path, ev, SIZE)
    assert read_events(path).events["t"].tolist() == [0, (1 << 24) - 1]


def test_evt2_accepts_long_gaps(tmp_path):
    ev = make_events([0, 1 << 24, 100_000_000], [0, 1, 2], [0, 1, 2], [1, 0, 1])
    path = tmp_path / "gap2.raw"
    write_events(path, ev, SIZE, evt_version="evt2")
    assert read_events(path).events["t"].tolist() == [0, 1 << 24, 100_000_000]


@pytest.mark.parametrize("suffix", [".raw", ".es"])
def test_negative_times_cannot_be_stored(tmp_path, suffix):
    ev = make_events([-5, 3], [0, 1], [0, 1], [1, 0])
    assert_write_fails(tmp_path / f"neg{suffix}", ev, match="negative timestamps")


def test_target_inside_a_regular_file_raises_a_project_error(tmp_path):
    """The folder of the target cannot be created: a clear EventFileError, not a bare OSError."""
    blocker = tmp_path / "not_a_folder"
    blocker.write_bytes(b"data")
    target = blocker / "out.npz"
    with pytest.raises(EventFileError) as info:
        write_events(target, GOOD, SIZE)
    assert str(target) in str(info.value)
    assert files_in(tmp_path) == ["not_a_folder"] and blocker.read_bytes() == b"data"


def test_target_that_is_a_directory_raises_a_project_error(tmp_path):
    target = tmp_path / "taken.npz"
    target.mkdir()
    with pytest.raises(EventFileError) as info:
        write_events(target, GOOD, SIZE)
    assert str(info.value) == f"{target}: is a folder, not an event file"
    assert files_in(tmp_path) == ["taken.npz"] and target.is_dir() and not list(target.iterdir())
