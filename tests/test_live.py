"""The live filter: chunks of any sizes, fed then flushed, give deflare's result on the whole."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import same_events
from edeflare import deflare
from edeflare.baselines.efr import efr_bias
from edeflare.data.toy import toy_flare_pair
from edeflare.errors import EventsError, ParameterError
from edeflare.events import EVENT_DTYPE, make_events
from edeflare.live import Deflarer
from edeflare.methods import create_method

SIZE = (64, 48)
T0 = 1_633_953_690_975_950  # absolute time: windows align to it, not to the first event


@pytest.fixture(scope="module")
def stream() -> np.ndarray:
    """200 ms of a toy flare scene (a bar, a 100 Hz lamp and its halo), ties included."""
    events = toy_flare_pair(SIZE, duration_us=200_000, rng=3).observed.copy()
    events["t"] += T0
    assert (np.diff(events["t"]) == 0).any()
    return events


@pytest.fixture(scope="module")
def methods(stream):
    """One method object per case, made once (the model loads its network once)."""
    return {
        "model": create_method("model"),  # the default: the bundled model
        "efr": create_method("efr", bias=efr_bias(stream[: stream.size // 3], SIZE)),
        "pfd-b": create_method("pfd-b"),
        "raw": create_method("raw"),
        "voxel": create_method("voxel"),
    }


def random_chunks(events: np.ndarray, seed: int, n: int) -> list[np.ndarray]:
    """``n`` cuts anywhere (inside windows, empty chunks), one inside a run of equal times."""
    rng = np.random.default_rng(seed)
    tie = int(np.flatnonzero(np.diff(events["t"]) == 0)[rng.integers(0, 10)]) + 1
    cuts = np.sort(np.append(rng.integers(0, events.size + 1, n - 1), tie))
    return np.split(events, cuts)


def run(live: Deflarer, chunks: list[np.ndarray]) -> list[np.ndarray]:
    """What ``live`` returns for each chunk, then what ``flush`` returns."""
    return [live(chunk) for chunk in chunks] + [live.flush()]


@pytest.mark.parametrize("n_chunks", [4, 300])
@pytest.mark.parametrize("name", ["model", "efr", "pfd-b", "raw", "voxel"])
def test_chunks_then_flush_equal_deflare_on_the_whole_stream(stream, methods, name, n_chunks):
    method = methods[name]
    expected = deflare(stream, SIZE, method, rng=5)
    before = stream.copy()
    chunks = random_chunks(stream, seed=n_chunks, n=n_chunks)
    live = Deflarer(SIZE, method, rng=5, max_lag_us=None)
    outputs = run(live, chunks)
    got = np.concatenate(outputs)
    assert same_events(got, expected)  # event for event, in the same order
    assert same_events(stream, before)  # chunks unchanged
    assert all(o.dtype == EVENT_DTYPE for o in outputs)
    assert not any(np.shares_memory(o, stream) for o in outputs)
    assert np.all(np.diff(got["t"]) >= 0)  # each output sorted, each at or after the last
    assert (live.events_in, live.events_out, live.late_dropped) == (stream.size, got.size, 0)
    # a live filter: most outputs come before the end (efr: once no earlier one can come)
    share_before_flush = 1 - outputs[-1].size / got.size
    assert share_before_flush > (0.03 if name == "efr" else 0.7)


def test_the_default_method_is_the_bundled_model(stream, methods):
    live = Deflarer(SIZE)
    assert live.method.name == "model"
    assert live.method.params == methods["model"].params
    part = stream[stream["t"] < T0 + 60_000]
    got = np.concatenate(run(live, random_chunks(part, 1, 20)))
    assert same_events(got, deflare(part, SIZE, "model"))


def test_outputs_wait_only_for_what_the_method_needs(stream):
    """raw and pfd-b hold back only the latest microsecond (more events may come at it)."""
    for name in ("raw", "pfd-b"):
        live = Deflarer(SIZE, name)
        whole = deflare(stream, SIZE, name)
        seen = 0
        for chunk in random_chunks(stream, 7, 50):
            seen += live(chunk).size
            if chunk.size:
                final = int(np.searchsorted(whole["t"], chunk["t"][-1], side="left"))
                assert seen == final
        assert seen + live.flush().size == whole.size


def test_efr_needs_a_bias_map_or_a_prepass():
    with pytest.raises(ParameterError, match=r"pass bias= .* or prepass_us="):
        Deflarer(SIZE, "efr")
    with pytest.raises(ParameterError, match="prepass_us is for methods with a first pass"):
        Deflarer(SIZE, "pfd-b", prepass_us=10_000)
    with pytest.raises(ParameterError, match="prepass_us must be an int >= 1"):
        Deflarer(SIZE, "efr", prepass_us=0)


def test_efr_prepass_over_the_whole_stream_is_deflare(stream):
    live = Deflarer(SIZE, "efr", prepass_us=10_000_000, max_lag_us=None)
    outputs = run(live, random_chunks(stream, 2, 40))
    assert all(o.size == 0 for o in outputs[:-1])  # everything waits for the prepass
    assert same_events(outputs[-1], deflare(stream, SIZE, "efr"))


def test_efr_prepass_takes_the_bias_of_the_stream_start(stream):
    prepass_us = 50_000
    start = stream[stream["t"] < stream["t"][0] + prepass_us]
    expected = deflare(stream, SIZE, "efr", bias=efr_bias(start, SIZE))
    live = Deflarer(SIZE, "efr", prepass_us=prepass_us, max_lag_us=None)
    got = np.concatenate(run(live, random_chunks(stream, 3, 40)))
    assert same_events(got, expected)
    assert not same_events(got, deflare(stream, SIZE, "efr"))  # not the whole-stream bias


def test_efr_outputs_lagging_more_than_max_lag_are_dropped_with_a_warning(stream, methods):
    live = Deflarer(SIZE, methods["efr"], max_lag_us=20_000)
    with pytest.warns(UserWarning, match="lagged their input by more than max_lag_us=20000"):
        got = np.concatenate(run(live, random_chunks(stream, 4, 100)))
    exact = deflare(stream, SIZE, methods["efr"])
    assert live.late_dropped > 0 and got.size == exact.size - live.late_dropped
    assert np.all(np.diff(got["t"]) >= 0)


def test_chunk_errors_leave_the_filter_as_it_was(stream):
    live = Deflarer(SIZE, "pfd-b")
    chunks = random_chunks(stream, 5, 6)
    out = [live(chunks[0]), live(chunks[1])]
    with pytest.raises(EventsError, match="chunks must come in time order: this chunk starts"):
        live.accept(chunks[0])
    unsorted = chunks[2][::-1].copy()
    with pytest.raises(EventsError, match="timestamps are not sorted"):
        live.accept(unsorted)
    with pytest.raises(EventsError, match="structured array of dtype"):
        live.accept(np.zeros(3, dtype=[("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "?")]))
    with pytest.raises(EventsError, match="x out of range"):
        live.accept(make_events([T0 + 300_000], [SIZE[0]], [0], [1]))
    out += run(live, chunks[2:])
    assert same_events(np.concatenate(out), deflare(stream, SIZE, "pfd-b"))
    with pytest.raises(ParameterError, match="flushed"):
        live.accept(chunks[-1])
    assert live.flush().size == 0


def test_chunks_are_copied_and_empty_streams_give_nothing(stream):
    live = Deflarer(SIZE, "raw")
    buffer = stream[:100].copy()
    live.accept(buffer)
    buffer["x"] = 0  # a driver reusing its buffer
    assert same_events(live.flush(), stream[:100])
    empty = Deflarer(SIZE, "pfd-b")
    assert empty(np.zeros(0, dtype=EVENT_DTYPE)).size == 0
    out = empty.flush()
    assert out.dtype == EVENT_DTYPE and out.size == 0


def test_parameters_go_to_the_method_once():
    assert Deflarer(SIZE, "pfd-b", window_us=10_000).method.params["window_us"] == 10_000
    with pytest.raises(ParameterError, match="not both"):
        Deflarer(SIZE, create_method("raw"), window_us=10_000)
    with pytest.raises(ParameterError, match="has no parameter 'windo_us'"):
        Deflarer(SIZE, "pfd-b", windo_us=10_000)
    with pytest.raises(ParameterError, match="max_lag_us must be an int >= 0"):
        Deflarer(SIZE, "raw", max_lag_us=-1)
    with pytest.raises(EventsError, match="sensor_size"):
        Deflarer((0, 4), "raw")
