"""Reading the shared real recordings (``../shared/data/real``) against what is known of them.

The expected values come from ``SOURCES.md`` beside the files, refined by
measurement with faery 0.7.1 (the exact counts, first timestamps and spans),
and, for ``.dat`` and EVT 2.0, by the small independent numpy decoders below.
Every test skips when the shared folder is absent.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from conftest import same_events
from edeflare.events import iter_time_windows
from edeflare.io import iter_windows, open_events, read_events
from edeflare.io.faery_formats import read_raw_header

# name: (events, ON events, sensor size, first t, span = last t - first t, SOURCES ON fraction)
RECORDINGS = {
    "davis346_flicker_lamps.aedat4": (
        117_667,
        72_363,
        (346, 260),
        1_633_953_690_975_950,
        129_999,
        0.615,
    ),
    "davis346_lowlight_cradle.aedat4": (
        319_512,
        166_736,
        (346, 260),
        1_643_243_628_737_093,
        510_990,
        None,
    ),
    "davis346_street_cars.aedat4": (
        78_830,
        41_257,
        (346, 260),
        1_589_163_147_368_868,
        2_359_945,
        None,
    ),
    "prophesee_gen3_rotating_light.raw": (539_481, 367_855, (640, 480), 1_317_888, 50_000, 0.68),
    # SOURCES.md says "54 ms" for this file, but its EVT 3.0 TIME_HIGH words only run from
    # 2861 to 2863 (see test_gen41_street_time_high_words): the recording spans 8.8 ms.
    "prophesee_gen41_street.raw": (219_596, 115_532, (1280, 720), 11_718_656, 8_811, None),
    "atis_ncars_crop.dat": (2_009, 1_350, (304, 240), 0, 99_952, None),
}

SHA256 = {
    "davis346_street_cars.aedat4": "b383462d72122c69fd96ebf095c384e3f1a2f092cc1b2681be52ebc1d260cf8a",
    "atis_ncars_crop.dat": "37c942280817be4615f995f28877c81f9391eee639d0584ddb9a8c6e6833b4db",
    "davis346_flicker_lamps.aedat4": "140ed9a82548ec3c3e66baf5948adb8c0f2e22fac6d22344685b0dc26a2584f0",
    "davis346_lowlight_cradle.aedat4": "97ea11518d8b19581774c4a41ac8b87ca78bc66cdfd13d16a312c78891cc1b6c",
    "prophesee_gen3_rotating_light.raw": "27ca511eb34f92d8a041152dd0bbe3ba9972e6fec820353937fe55a31eabbd60",
    "prophesee_gen41_street.raw": "1c57e604b7f988a834bcf90f1be26d144fb5527aa15f9c61940f5916bff5b919",
}


def _body(data: bytes) -> int:
    """Offset of the first byte after the ``%`` header lines."""
    i = 0
    while data[i : i + 1] == b"%":
        i = data.index(b"\n", i) + 1
    return i


def test_every_recording_is_listed(real_data):
    present = sorted(p.name for p in real_data.iterdir() if p.name != "SOURCES.md")
    assert present == sorted(RECORDINGS)


@pytest.mark.parametrize("name", sorted(SHA256))
def test_files_are_the_documented_ones(real_data, name):
    assert hashlib.sha256((real_data / name).read_bytes()).hexdigest() == SHA256[name]


@pytest.mark.parametrize("name", sorted(RECORDINGS))
def test_counts_sizes_spans_and_on_fraction(real_data, name):
    n, n_on, size, first_t, span, on_fraction = RECORDINGS[name]
    kwargs = {"sensor_size": (304, 240)} if name.endswith(".dat") else {}
    events, sensor_size = read_events(real_data / name, **kwargs)
    assert events.size == n
    assert sensor_size == size
    assert int(events["t"][0]) == first_t
    assert int(events["t"][-1] - events["t"][0]) == span
    assert int(events["p"].sum()) == n_on
    assert (np.diff(events["t"]) >= 0).all()
    assert int(events["x"].max()) < size[0] and int(events["y"].max()) < size[1]
    if on_fraction is not None:  # as SOURCES.md rounds it
        digits = len(str(on_fraction).split(".")[1])
        assert round(n_on / n, digits) == on_fraction


def test_lamps_on_fraction_measured_value(real_data):
    events = read_events(real_data / "davis346_flicker_lamps.aedat4").events
    assert events["p"].mean() == pytest.approx(0.61498, abs=5e-6)
    # golden/README.md: 50,535 events share their t with the preceding event
    assert int((np.diff(events["t"]) == 0).sum()) == 50_535


def test_gen3_on_fraction_measured_value(real_data):
    events = read_events(real_data / "prophesee_gen3_rotating_light.raw").events
    assert events["p"].mean() == pytest.approx(0.68187, abs=5e-6)


def test_aedat4_times_are_absolute_unix_microseconds(real_data):
    for name in (
        "davis346_flicker_lamps.aedat4",
        "davis346_lowlight_cradle.aedat4",
        "davis346_street_cars.aedat4",
    ):
        first = RECORDINGS[name][3]
        assert 1.5e15 < first < 1.7e15  # 2017..2023


def test_raw_headers_give_version_and_size(real_data):
    gen3 = read_raw_header(real_data / "prophesee_gen3_rotating_light.raw")
    assert gen3.version == "evt2"
    assert gen3.plugin == "hal_plugin_gen3_fx3"
    assert gen3.sensor_size == (640, 480)  # no geometry line: from the plugin name
    assert not any("geometry" in line or "width=" in line for line in gen3.lines)
    gen41 = read_raw_header(real_data / "prophesee_gen41_street.raw")
    assert gen41.version == "evt3"
    assert gen41.plugin == "hal_plugin_gen41_evk3"
    assert gen41.sensor_size == (1280, 720)
    src = open_events(real_data / "prophesee_gen3_rotating_light.raw")
    assert src.sensor_size_source == "file"


def test_gen41_street_time_high_words(real_data):
    """The EVT 3.0 file's own clock: TIME_HIGH (type 0x8) holds bits 12..23 of t."""
    data = (real_data / "prophesee_gen41_street.raw").read_bytes()
    start = _body(data)
    words = np.frombuffer(data[start : start + (len(data) - start) // 2 * 2], dtype="<u2")
    time_high = words[words >> 12 == 0x8] & 0xFFF
    assert sorted(set(time_high.tolist())) == [2861, 2862, 2863]
    events = read_events(real_data / "prophesee_gen41_street.raw").events
    assert int(events["t"][0]) >> 12 == 2861
    assert int(events["t"][-1]) >> 12 == 2863
    # so the span is at most 3 * 4096 µs (about 12 ms), not the 54 ms SOURCES.md states
    assert events["t"][-1] - events["t"][0] < 3 * 4096


def test_gen3_matches_an_independent_evt2_decoder(real_data):
    data = (real_data / "prophesee_gen3_rotating_light.raw").read_bytes()
    start = _body(data)
    words = np.frombuffer(data[start : start + (len(data) - start) // 4 * 4], dtype="<u4")
    kind = words >> 28
    # TIME_HIGH (0x8) carries t >> 6; CD_OFF (0x0) / CD_ON (0x1) carry 6 low bits, x, y
    is_high = kind == 0x8
    high_index = np.maximum.accumulate(np.where(is_high, np.arange(words.size), -1))
    t_high = np.where(high_index >= 0, (words[np.maximum(high_index, 0)] & 0x0FFFFFFF), 0)
    cd = kind <= 1
    assert set(np.unique(kind).tolist()) <= {0x0, 0x1, 0x8}
    t = (t_high[cd].astype(np.int64) << 6) + ((words[cd] >> 22) & 0x3F)
    x = (words[cd] >> 11) & 0x7FF
    y = words[cd] & 0x7FF
    p = kind[cd]
    events = read_events(real_data / "prophesee_gen3_rotating_light.raw").events
    assert (np.diff(t) >= 0).all()  # the file's own times never go back: no clamping needed
    assert np.array_equal(events["t"], t)
    assert np.array_equal(events["x"], x)
    assert np.array_equal(events["y"], y)
    assert np.array_equal(events["p"], p)


def test_ncars_dat_matches_an_independent_decoder(real_data):
    data = (real_data / "atis_ncars_crop.dat").read_bytes()
    start = _body(data)
    assert data[start] == 0x00 and data[start + 1] == 8  # "Event2d" type, 8-byte records
    records = np.frombuffer(data[start + 2 :], dtype=[("t", "<u4"), ("data", "<u4")])
    events = read_events(real_data / "atis_ncars_crop.dat", sensor_size=(304, 240)).events
    assert np.array_equal(events["t"], records["t"])
    assert np.array_equal(events["x"], records["data"] & 0x3FFF)
    assert np.array_equal(events["y"], (records["data"] >> 14) & 0x3FFF)
    assert np.array_equal(events["p"], records["data"] >> 28)


def test_ncars_dat_without_size_warns_and_infers(real_data):
    path = real_data / "atis_ncars_crop.dat"
    with pytest.warns(UserWarning, match=r"no sensor size recorded; using 78x42 \(max \+ 1\)"):
        events, size = read_events(path)
    assert size == (78, 42)
    assert events.size == 2_009
    src = open_events(path, sensor_size=(304, 240))
    assert src.recorded_sensor_size is None and src.sensor_size_source == "option"
    assert src.sensor_size == (304, 240)


def test_golden_lamps_input_is_the_aedat4_minus_its_offset(real_data, golden_data):
    events = read_events(real_data / "davis346_flicker_lamps.aedat4").events
    with np.load(golden_data / "davis346_lamps_input.npz", allow_pickle=False) as golden:
        offset = int(golden["t_offset_us"])
        assert offset == 1_633_953_690_975_950
        assert (int(golden["width"]), int(golden["height"])) == (346, 260)
        assert golden["t"].size == events.size
        assert int((golden["t"] == 0).sum()) == 2  # golden/README.md: 2 events at t = 0
        assert np.array_equal(golden["t"] + offset, events["t"])
        assert np.array_equal(golden["x"], events["x"])
        assert np.array_equal(golden["y"], events["y"])
        assert np.array_equal(golden["p"], events["p"])


def test_golden_npz_reads_as_a_recording(golden_data):
    events, size = read_events(golden_data / "davis346_lamps_input.npz")
    assert size == (346, 260)
    assert events.size == 117_667 and int(events["p"].sum()) == 72_363
    assert int(events["t"][0]) == 0 and int(events["t"][-1]) == 129_999


@pytest.mark.parametrize(
    "name", ["davis346_flicker_lamps.aedat4", "prophesee_gen3_rotating_light.raw"]
)
def test_iter_windows_on_real_files(real_data, name):
    path = real_data / name
    events = read_events(path).events
    got = list(iter_windows(path, 7_000))
    expected = list(iter_time_windows(events, 7_000))
    assert [s for s, _ in got] == [s for s, _ in expected]
    for (_, a), (_, b) in zip(got, expected, strict=True):
        assert same_events(a, b)
