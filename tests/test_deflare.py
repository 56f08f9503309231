"""Tests of edeflare.methods: the method registry, the method contract, streaming files, the CLI."""

from __future__ import annotations

import re
import sys
import time

import numpy as np
import pytest

import edeflare
from conftest import random_events, same_events
from edeflare.baselines.efr import efr, efr_bias
from edeflare.baselines.pfd import pfd
from edeflare.cli import main
from edeflare.errors import EdeflareError, ParameterError
from edeflare.events import EVENT_DTYPE, make_events
from edeflare.io import read_events, write_events
from edeflare.methods import (
    DeflareStats,
    Method,
    WindowStreamer,
    create_method,
    deflare_file,
    list_methods,
    method_parameters,
    register_method,
)
from edeflare.methods.classical import RawMethod
from edeflare.voxel import decode, encode

SIZE = (32, 24)
BASELINES = ["raw", "voxel", "efr", "pfd-a", "pfd-b"]


@pytest.fixture
def stream(rng):
    """Half a second of random events at an absolute time, ties included."""
    return random_events(rng, 20_000, SIZE, t0=1_633_953_690_975_950, span_us=500_000)


# --------------------------------------------------------------------------------------
# Registry


def test_the_paper_baselines_are_registered():
    assert set(BASELINES) <= set(list_methods())
    assert list_methods() == sorted(list_methods())
    assert edeflare.list_methods is list_methods and edeflare.create_method is create_method


def test_unknown_method_lists_the_registered_ones():
    with pytest.raises(
        ParameterError, match=r"unknown method 'efrr'; registered methods: dv-bafilter, "
    ):
        create_method("efrr")
    with pytest.raises(ValueError, match="pfd-a, pfd-b, raw, voxel"):  # a ValueError too
        create_method("nope")


def test_unknown_parameter_lists_the_valid_ones():
    with pytest.raises(
        ParameterError,
        match=r"method 'pfd-a' has no parameter 'neibor'; valid: stage1_window_us, window_us, ",
    ):
        create_method("pfd-a", neibor=3)
    with pytest.raises(ParameterError, match=r"no parameters 'a', 'b'"):
        create_method("efr", a=1, b=2)
    with pytest.raises(ParameterError, match=r"method 'raw' has no parameter 'x'; valid: \(none\)"):
        create_method("raw", x=1)


def test_bad_parameter_values_fail_at_creation():
    with pytest.raises(ParameterError, match="rho1 must be below 1"):
        create_method("efr", rho1=1.0)
    with pytest.raises(ParameterError, match="fifo_size must be an int >= 1"):
        create_method("pfd-b", fifo_size=0)
    with pytest.raises(ParameterError, match=r"window_us \(4\) must be at least bins \(8\)"):
        create_method("voxel", window_us=4)


def test_registering_twice_is_an_error_and_factories_must_make_methods():
    @register_method("test-twice")
    def make(scale: int = 1) -> Method:
        return RawMethod(scale=scale)

    try:
        assert "test-twice" in list_methods()
        m = create_method("test-twice", scale=3)
        assert m.name == "test-twice" and m.params == {"scale": 3}
        with pytest.raises(ParameterError, match="'test-twice' is already registered"):
            register_method("test-twice", make)
    finally:
        from edeflare.methods.base import _unregister

        _unregister("test-twice")
    register_method("test-bad", lambda: "not a method")
    try:
        with pytest.raises(ParameterError, match="returned str"):
            create_method("test-bad")
    finally:
        _unregister("test-bad")
    with pytest.raises(ParameterError, match="non-empty string"):
        register_method("", make)


def test_method_parameters_are_the_factory_defaults():
    assert method_parameters("efr")["frequency_hz"] == 50.0
    assert method_parameters("pfd-b") == {
        "stage1_window_us": 20_000,
        "window_us": 20_000,
        "min_support": 1,
        "min_active": 3,
        "fifo_size": 5,
        "flip_against_previous": False,
        "real_valued_score": False,
    }


# --------------------------------------------------------------------------------------
# The contract every registered method keeps


@pytest.fixture(scope="module")
def model_weights(tmp_path_factory):
    """Identity-initialised weights for the ``model`` method (no bundled model needed)."""
    from edeflare.models import create_model
    from edeflare.models.weights import ModelCard, save_model

    path = tmp_path_factory.mktemp("weights") / "tiny.safetensors"
    save_model(path, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    return path


def _create(name, model_weights):
    if name.startswith("dv-"):
        pytest.importorskip("dv_processing")
    return create_method(name, weights=model_weights) if name == "model" else create_method(name)


@pytest.mark.parametrize("name", list_methods())
def test_method_contract(name, stream, model_weights):
    method = _create(name, model_weights)
    before = stream.copy()
    out = method(stream, SIZE, rng=0)
    assert same_events(stream, before)  # input unchanged
    assert out.dtype == EVENT_DTYPE and out.ndim == 1
    assert np.all(np.diff(out["t"]) >= 0)  # sorted
    assert not np.shares_memory(out, stream)  # a new array
    assert out.size > 0
    assert int(out["x"].max()) < SIZE[0] and int(out["y"].max()) < SIZE[1]
    assert int(out["p"].max()) <= 1
    empty = method(np.zeros(0, dtype=EVENT_DTYPE), SIZE, rng=0)
    assert empty.dtype == EVENT_DTYPE and empty.size == 0


@pytest.mark.parametrize("name", list_methods())
def test_method_rejects_bad_input(name, model_weights):
    method = _create(name, model_weights)
    with pytest.raises(EdeflareError, match="x out of range"):
        method(make_events([0], [40], [0], [1]), SIZE)
    with pytest.raises(EdeflareError, match="structured array"):
        method(np.zeros((3, 4)), SIZE)


def test_methods_are_the_baselines(stream):
    assert same_events(create_method("raw")(stream, SIZE), stream)
    assert same_events(create_method("efr")(stream, SIZE), efr(stream, SIZE))
    assert same_events(
        create_method("efr", frequency_hz=120, shift_back=True)(stream, SIZE),
        efr(stream, SIZE, 120, shift_back=True),
    )
    assert same_events(create_method("pfd-a")(stream, SIZE), pfd(stream, SIZE, score="A"))
    assert same_events(
        create_method("pfd-b", real_valued_score=True)(stream, SIZE),
        pfd(stream, SIZE, score="B", real_valued_score=True),
    )
    assert same_events(
        edeflare.deflare(stream, SIZE, "pfd-b", window_us=10_000),
        pfd(stream, SIZE, 20_000, 10_000, score="B"),
    )


def test_voxel_is_encode_then_decode_per_aligned_window(stream):
    out = create_method("voxel")(stream, SIZE, rng=7)
    rng = np.random.default_rng(7)
    expected = []
    start = stream["t"][0] // 20_000 * 20_000
    while start <= stream["t"][-1]:
        window = stream[(stream["t"] >= start) & (stream["t"] < start + 20_000)]
        if window.size:
            expected.append(decode(encode(window, SIZE, start, 20_000), start, 20_000, rng=rng))
        start += 20_000
    assert same_events(out, np.concatenate(expected))
    assert same_events(out, create_method("voxel")(stream, SIZE, rng=7))  # seeded
    assert not same_events(out, create_method("voxel")(stream, SIZE, rng=8))


def test_deflare_takes_a_method_object_or_a_name(stream):
    pfd_b = create_method("pfd-b")
    by_name = edeflare.deflare(stream, SIZE, "pfd-b")
    assert same_events(edeflare.deflare(stream, SIZE, pfd_b), by_name)
    with pytest.raises(ParameterError, match="not both"):
        edeflare.deflare(stream, SIZE, pfd_b, window_us=5)


# --------------------------------------------------------------------------------------
# Streaming files


@pytest.mark.parametrize("name", BASELINES)
@pytest.mark.parametrize("window_us", [20_000, 7_000])
def test_streaming_a_file_equals_one_pass(tmp_path, stream, name, window_us):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    out = tmp_path / "out.npz"
    stats = deflare_file(src, out, name, window_us, rng=3, progress=False)
    expected = create_method(name)(stream, SIZE, rng=3)
    got, size = read_events(out)
    assert size == SIZE
    assert same_events(got, expected)
    assert stats == DeflareStats(stream.size, expected.size, 0)


def test_deflare_file_reports_its_speed_and_latency(tmp_path, stream, monkeypatch):
    write_events(tmp_path / "in.h5", stream, SIZE)
    real_process = WindowStreamer.process
    slow_us = 30_000

    def slow_process(self, events, until_us):  # every window takes at least 30 ms
        time.sleep(slow_us * 1e-6)
        return real_process(self, events, until_us)

    monkeypatch.setattr(WindowStreamer, "process", slow_process)
    stats = deflare_file(tmp_path / "in.h5", tmp_path / "out.h5", "voxel", 20_000, progress=False)
    assert stats.span_us == int(stream["t"][-1] - stream["t"][0])
    p50, p95, worst = stats.latency_ms
    assert slow_us / 1e3 <= p50 <= p95 <= worst
    n_windows = -(-stats.span_us // 20_000)
    assert stats.seconds >= n_windows * slow_us * 1e-6  # every window's call was timed
    assert stats.real_time_factor == pytest.approx(stats.seconds / (stats.span_us * 1e-6))


def test_streaming_efr_over_a_long_file_releases_outputs_as_it_goes(tmp_path, rng, monkeypatch):
    """Many windows and small batches: the reorder buffer releases early, still exact."""
    monkeypatch.setattr(sys.modules["edeflare.methods.streaming"], "_REORDER_BATCH", 1000)
    events = random_events(rng, 100_000, (16, 16), span_us=20_000_000)
    src = tmp_path / "long.npz"
    write_events(src, events, (16, 16))
    stats = deflare_file(src, tmp_path / "out.h5", "efr", progress=False, max_lag_us=None)
    expected = efr(events, (16, 16))
    got, _ = read_events(tmp_path / "out.h5")
    assert same_events(got, expected) and stats.events_out == expected.size > 10_000


def test_efr_outputs_lagging_more_than_max_lag_are_dropped_with_a_warning(
    tmp_path, rng, monkeypatch
):
    # Pixel (0, 0) goes silent for 3 s, then fires: its queues catch up, stamping outputs
    # back in the silence; meanwhile the other pixels keep the output flowing.
    monkeypatch.setattr(sys.modules["edeflare.methods.streaming"], "_REORDER_BATCH", 1000)
    busy = random_events(rng, 100_000, (8, 8), span_us=4_000_000)
    busy = busy[(busy["x"] != 0) | (busy["y"] != 0)]
    lonely = make_events([0, 30_000, 42_000, 3_100_000], [0] * 4, [0] * 4, [1, 1, 1, 0])
    events = np.concatenate([busy, lonely])
    events = events[np.argsort(events["t"], kind="stable")]
    src = tmp_path / "in.npz"
    write_events(src, events, (8, 8))
    exact = efr(events, (8, 8))
    lonely_out = (exact["x"] == 0) & (exact["y"] == 0)
    late = lonely_out & (exact["t"] > 50_000)
    # Emitted while handling the event at 3.1 s, stamped 3 s earlier (the queues converge).
    assert exact["t"][late].tolist() == [60_000, 70_000]
    with pytest.warns(UserWarning, match=r"2 output events lagged .* max_lag_us=500000"):
        stats = deflare_file(src, tmp_path / "a.h5", "efr", max_lag_us=500_000, progress=False)
    got, _ = read_events(tmp_path / "a.h5")
    assert stats.late_dropped == 2
    assert same_events(got, exact[~late])
    stats = deflare_file(src, tmp_path / "b.h5", "efr", max_lag_us=None, progress=False)
    assert stats.late_dropped == 0
    assert same_events(read_events(tmp_path / "b.h5").events, exact)


def test_efr_file_bias_comes_from_a_first_pass_or_a_given_map(tmp_path, stream):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    deflare_file(src, tmp_path / "a.npz", "efr", progress=False)
    bias = efr_bias(stream, SIZE)
    deflare_file(src, tmp_path / "b.npz", "efr", params={"bias": bias}, progress=False)
    zero = np.zeros((SIZE[1], SIZE[0]))
    deflare_file(src, tmp_path / "c.npz", "efr", params={"bias": zero}, progress=False)
    a, b, c = (read_events(tmp_path / f"{k}.npz").events for k in "abc")
    assert same_events(a, b) and same_events(a, efr(stream, SIZE))
    assert not same_events(a, c)


def test_deflare_file_writes_any_format_and_needs_a_sensor_size_for_text(tmp_path, stream):
    src = tmp_path / "in.txt"
    write_events(src, stream, SIZE)
    for suffix in (".raw", ".aedat4", ".csv"):
        out = tmp_path / f"out{suffix}"
        deflare_file(src, out, "pfd-a", sensor_size=SIZE, progress=False)
        got = read_events(out, SIZE).events
        assert same_events(got, pfd(stream, SIZE, score="A")), suffix


def test_deflare_file_rejects_bad_arguments(tmp_path, stream):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    with pytest.raises(ParameterError, match="window_us must be a positive int"):
        deflare_file(src, tmp_path / "o.h5", "raw", 0)
    with pytest.raises(ParameterError, match="unknown method"):
        deflare_file(src, tmp_path / "o.h5", "nope")
    with pytest.raises(ParameterError, match="not both"):
        deflare_file(src, tmp_path / "o.h5", create_method("raw"), params={"x": 1})
    assert not (tmp_path / "o.h5").exists()


# --------------------------------------------------------------------------------------
# edeflare deflare


def test_cli_deflare_end_to_end(tmp_path, stream, capsys):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    out = tmp_path / "out.npz"
    argv = ["deflare", str(src), str(out), "-m", "pfd-b", "--pfd-window-ms", "10"]
    assert main(argv) == 0
    expected = pfd(stream, SIZE, 10_000, 10_000, score="B")
    assert same_events(read_events(out).events, expected)
    line = capsys.readouterr().out
    assert f"pfd-b: 20,000 events in, {expected.size:,} out" in line

    assert main(["deflare", str(src), str(out), "-m", "efr", "--efr-frequency", "100"]) == 0
    assert same_events(read_events(out).events, efr(stream, SIZE, 100))
    assert main(["deflare", str(src), str(out), "-m", "efr", "--efr-shift-back"]) == 0
    assert same_events(read_events(out).events, efr(stream, SIZE, shift_back=True))
    argv = ["deflare", str(src), str(out), "-m", "voxel", "--seed", "5", "--voxel-bins", "4"]
    assert main(argv) == 0
    assert same_events(read_events(out).events, create_method("voxel", bins=4)(stream, SIZE, rng=5))


def test_cli_deflare_efr_options(tmp_path, stream):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    bias = tmp_path / "bias.npy"
    np.save(bias, np.full((SIZE[1], SIZE[0]), 0.25))
    out = tmp_path / "out.h5"
    argv = ["deflare", str(src), str(out), "-m", "efr", "--rho1", "0.5", "--efr-bias", str(bias)]
    argv += ["--no-efr-warmup", "--efr-merge-ms", "5", "--efr-threshold", "0.6"]
    assert main(argv) == 0
    expected = efr(
        stream, SIZE, 50, 0.5, 5_000, 0.6, bias=np.full((24, 32), 0.25), keep_warmup=False
    )
    assert same_events(read_events(out).events, expected)


def test_cli_deflare_bad_input_exits_1_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"this is not an HDF5 file")
    out = tmp_path / "out.h5"
    assert main(["deflare", str(bad), str(out), "-m", "efr"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("edeflare: error: ") and "bad.h5" in err and err.count("\n") == 1
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["bad.h5"]  # no temporary left either


def test_cli_deflare_unsorted_input_exits_1_and_writes_nothing(tmp_path, capsys):
    src = tmp_path / "in.csv"
    src.write_text("t,x,y,p\n10,1,1,1\n5,2,2,0\n")
    out = tmp_path / "out.h5"
    assert main(["deflare", str(src), str(out), "-m", "pfd-a", "--sensor-size", "4x4"]) == 1
    assert "not sorted" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["-m", "pfd-a", "--rho1", "0.5"], "--rho1 applies to --method efr"),
        (["-m", "efr", "--pfd-real-score"], "--pfd-real-score applies to --method pfd-a or pfd-b"),
        (["-m", "raw", "--no-efr-warmup"], "--no-efr-warmup applies to --method efr"),
        (["-m", "pfd-b", "--efr-bias", "b.npy"], "--efr-bias applies to --method efr"),
        (["-m", "efr", "--rho1", "1.5"], r"rho1 must lie in \[0.0, 1.0\]"),
        (["-m", "efr", "--efr-bias", "missing.npy"], "missing.npy: cannot read a bias map"),
        (["-m", "raw", "--window-ms", "0"], "--window-ms must be positive"),
        (["-m", "efr", "--max-lag-ms", "-1"], "--max-lag-ms must be >= 0 or inf"),
    ],
)
def test_cli_deflare_option_errors(tmp_path, stream, capsys, argv, message):
    src = tmp_path / "in.h5"
    write_events(src, stream, SIZE)
    out = tmp_path / "out.h5"
    assert main(["deflare", str(src), str(out), *argv]) == 1
    err = capsys.readouterr().err
    assert err.startswith("edeflare: error: ")
    assert re.search(message, err), err
    assert not out.exists()


def test_cli_deflare_unknown_method_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["deflare", "a.h5", "b.h5", "-m", "magic"])
    assert exc.value.code == 1
    assert "invalid choice: 'magic'" in capsys.readouterr().err
