"""The tonic transform: tonic's event layouts in, edeflare's result out, in the input's dtype."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from conftest import same_events
from edeflare import deflare
from edeflare.data.toy import toy_flare_pair
from edeflare.errors import EventsError, ParameterError
from edeflare.events import EVENT_DTYPE
from edeflare.methods import create_method
from edeflare.transforms import Deflare, from_structured, to_structured

SIZE = (64, 48)
TONIC_SIZE = (64, 48, 2)

# tonic's layouts: its events_struct (DSEC, ...), NMNIST's all-int, NeRDD's int32 times,
# float times with bool polarity, and t first with -1/+1 polarity
LAYOUTS = {
    "events_struct": [("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "?")],
    "nmnist": [("x", "<i8"), ("y", "<i8"), ("t", "<i8"), ("p", "<i8")],
    "int32-t": [("t", "<i4"), ("x", "<i2"), ("y", "<i2"), ("p", "?")],
    "float-t": [("x", "<i2"), ("y", "<i2"), ("t", "<f8"), ("p", "?")],
    "signed-p": [("t", "<i8"), ("x", "<u2"), ("y", "<u2"), ("p", "<i1")],
}


@pytest.fixture(scope="module")
def stream() -> np.ndarray:
    """120 ms of a toy flare scene in edeflare's layout, from t = 0 as tonic's samples."""
    return toy_flare_pair(SIZE, duration_us=120_000, rng=5).observed


def as_layout(events: np.ndarray, layout: list) -> np.ndarray:
    """``events`` written in a tonic layout, by hand (OFF as -1 in the signed-p layout)."""
    out = np.empty(events.size, dtype=layout)
    for name in ("x", "y", "t"):
        out[name] = events[name]
    off = -1 if layout == LAYOUTS["signed-p"] else 0
    out["p"] = np.where(events["p"] == 1, 1, off)
    return out


@pytest.mark.parametrize("layout", LAYOUTS)
def test_layouts_convert_both_ways(stream, layout):
    tonic_events = as_layout(stream, LAYOUTS[layout])
    before = tonic_events.copy()
    converted = from_structured(tonic_events)
    assert same_events(converted, stream)
    back = to_structured(converted, tonic_events)
    assert back.dtype == tonic_events.dtype and np.array_equal(back, tonic_events)
    assert np.array_equal(tonic_events, before)  # input unchanged


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("method", ["model", "pfd-b"])
def test_the_transform_is_deflare_in_the_inputs_layout(stream, layout, method):
    tonic_events = as_layout(stream, LAYOUTS[layout])
    out = Deflare(TONIC_SIZE, method)(tonic_events)
    expected = deflare(stream, SIZE, method)
    assert 0 < expected.size < stream.size  # the method removes something
    assert out.dtype == tonic_events.dtype  # the input's dtype, field order included
    assert same_events(from_structured(out), expected)  # event for event
    assert np.array_equal(out, as_layout(expected, LAYOUTS[layout]))


def test_unsorted_input_is_sorted_stably_first(stream):
    rng = np.random.default_rng(0)
    tonic_events = as_layout(stream, LAYOUTS["events_struct"])[rng.permutation(stream.size)]
    order = np.argsort(tonic_events["t"], kind="stable")
    sorted_events = from_structured(tonic_events[order])
    assert same_events(from_structured(tonic_events), sorted_events)
    out = Deflare(TONIC_SIZE, "pfd-b")(tonic_events)
    assert same_events(from_structured(out), deflare(sorted_events, SIZE, "pfd-b"))


def test_polarity_conventions():
    layout = [("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "i1")]
    on_off = np.array([(0, 0, 0, 1), (1, 0, 5, 0)], dtype=layout)
    plus_minus = np.array([(0, 0, 0, 1), (1, 0, 5, -1)], dtype=layout)
    for events in (on_off, plus_minus):
        assert from_structured(events)["p"].tolist() == [1, 0]
        assert np.array_equal(Deflare((2, 1, 2), "raw")(events), events)
    all_on = np.array([(0, 0, 0, 1)], dtype=layout)  # no OFF to copy: OFF is 0
    assert to_structured(from_structured(plus_minus), all_on)["p"].tolist() == [1, 0]
    floats = np.array(
        [(0, 0, 0.0, -1.0)], dtype=[("x", "f4"), ("y", "f4"), ("t", "f8"), ("p", "f4")]
    )
    assert from_structured(floats).tolist() == [(0, 0, 0, 0)]
    assert np.array_equal(Deflare((1, 1), "raw")(floats), floats)


@pytest.mark.parametrize(
    ("events", "match"),
    [
        (np.zeros(2, dtype=[("t", "i8"), ("x", "i8"), ("p", "i8")]), r"missing y"),
        (
            np.zeros(2, dtype=[("x", "i8"), ("y", "i8"), ("t", "i8"), ("p", "i8"), ("c", "i8")]),
            r"unexpected c",
        ),
        (np.zeros((2, 4)), r"structured array with fields x, y, t, p"),
        ([(0, 0, 0, 1)], r"structured array with fields x, y, t, p \(tonic's layout\), got list"),
        (np.array([(0, 0, 0.5, 1)], dtype=LAYOUTS["float-t"]), r"t must hold whole numbers"),
        (np.array([(0, 0, np.nan, 1)], dtype=LAYOUTS["float-t"]), r"t must hold whole numbers"),
        (np.array([(0, 0, 0, 2)], dtype=LAYOUTS["nmnist"]), r"p must lie in \[-1, 1\]"),
        (np.array([(0, 0, 0, 0), (0, 0, 1, -1)], dtype=LAYOUTS["nmnist"]), "mixes 0 and -1"),
        (np.array([(-1, 0, 0, 1)], dtype=LAYOUTS["nmnist"]), r"x must lie in \[0, 65535\]"),
    ],
)
def test_bad_events_get_a_clear_error(events, match):
    with pytest.raises(EventsError, match=match):
        Deflare(TONIC_SIZE, "raw")(events)


def test_events_off_the_sensor_and_bad_sensor_sizes():
    events = np.array([(64, 0, 0, 1)], dtype=LAYOUTS["nmnist"])
    with pytest.raises(EventsError, match="x out of range for sensor width 64"):
        Deflare(TONIC_SIZE, "raw")(events)
    for bad in [(64,), (64, 48, 3), (64, 48, 2, 1), 64]:
        with pytest.raises(ParameterError, match="sensor_size"):
            Deflare(bad, "raw")
    with pytest.raises(EventsError, match="sensor_size"):
        Deflare((0, 48, 2), "raw")


def test_a_frozen_dataclass_that_makes_its_method_once(stream):
    transform = Deflare(TONIC_SIZE, "pfd-b", window_us=10_000)
    assert transform == Deflare([64, 48, 2], "pfd-b", window_us=10_000)
    assert transform != Deflare(TONIC_SIZE, "pfd-b")
    assert hash(transform) == hash(Deflare(TONIC_SIZE, "pfd-b", window_us=10_000))
    assert repr(transform) == (
        "Deflare(sensor_size=(64, 48, 2), method='pfd-b', params={'window_us': 10000})"
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        transform.method = "raw"  # type: ignore[misc]
    made = transform._method
    events = as_layout(stream, LAYOUTS["events_struct"])
    out = transform(events)
    assert transform._method is made
    assert same_events(from_structured(out), deflare(stream, SIZE, "pfd-b", window_us=10_000))
    copy = pickle.loads(pickle.dumps(transform))  # a data loader's worker
    assert copy == transform and copy._method is None
    assert np.array_equal(copy(events), out)
    method = create_method("raw")
    assert Deflare(SIZE, method)._method is method
    with pytest.raises(ParameterError, match="not both"):
        Deflare(SIZE, method, window_us=10_000)
    with pytest.raises(ParameterError, match="has no parameter 'windo_us'"):
        Deflare(SIZE, "pfd-b", windo_us=10_000)


def test_empty_input_gives_an_empty_output_of_its_dtype():
    events = np.zeros(0, dtype=LAYOUTS["float-t"])
    out = Deflare(TONIC_SIZE, "pfd-b")(events)
    assert out.dtype == events.dtype and out.size == 0
    assert from_structured(events).dtype == EVENT_DTYPE


# --------------------------------------------------------------------------------------
# In tonic itself (the tonic extra)


@pytest.fixture(scope="module")
def tonic_dataset(tmp_path_factory):
    """A tiny tonic dataset of toy flare scenes, made here (nothing downloaded)."""
    tonic = pytest.importorskip("tonic")

    class FlareScenes(tonic.Dataset):
        sensor_size = TONIC_SIZE
        dtype = tonic.io.events_struct  # x int16, y int16, t int64, p bool
        ordering = dtype.names

        def __init__(self, save_to, transform=None):
            super().__init__(save_to, transform=transform)
            for seed in (5, 6):
                ev = toy_flare_pair(SIZE, duration_us=120_000, rng=seed).observed
                self.data.append(
                    tonic.io.make_structured_array(
                        ev["x"], ev["y"], ev["t"], ev["p"].astype(bool), dtype=self.dtype
                    )
                )
                self.targets.append(seed)

        def __getitem__(self, index):
            events = self.data[index]
            if self.transform is not None:
                events = self.transform(events)
            return events, self.targets[index]

        def __len__(self):
            return len(self.data)

    return tonic, FlareScenes, tmp_path_factory.mktemp("tonic")


@pytest.mark.parametrize("method", ["model", "pfd-b"])
def test_in_a_tonic_compose_on_a_tonic_dataset(tonic_dataset, method):
    tonic, scenes, folder = tonic_dataset
    raw = scenes(folder)
    transform = tonic.transforms.Compose([Deflare(raw.sensor_size, method)])
    deflared = scenes(folder, transform=transform)
    for k in range(len(raw)):
        events, target = raw[k]
        out, out_target = deflared[k]
        assert out_target == target
        assert out.dtype == events.dtype == tonic.io.events_struct
        expected = deflare(from_structured(events), SIZE, method)
        assert 0 < expected.size < events.size
        assert same_events(from_structured(out), expected)  # event for event


def test_between_tonic_transforms(tonic_dataset):
    tonic, scenes, folder = tonic_dataset
    sensor_size = scenes.sensor_size
    frames = tonic.transforms.ToFrame(sensor_size, n_time_bins=3)
    crop = tonic.transforms.CropTime(max=100_000)
    pipeline = tonic.transforms.Compose([crop, Deflare(sensor_size, "pfd-b"), frames])
    events, _ = scenes(folder)[0]
    got = scenes(folder, transform=pipeline)[0][0]
    cropped = events[events["t"] <= 100_000]
    expected = to_structured(deflare(from_structured(cropped), SIZE, "pfd-b"), cropped)
    assert got.shape == (3, 2, SIZE[1], SIZE[0])
    assert np.array_equal(got, frames(expected))
