"""Tests of edeflare.baselines.dv: dv-processing's noise filters as methods."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import edeflare
from conftest import random_events, same_events
from edeflare.baselines import dv as dvmod
from edeflare.errors import DependencyError, ParameterError
from edeflare.events import make_events

SIZE = (32, 24)


def test_parameters_and_validation():
    assert dvmod.dv_filter_parameters("fastdecay") == {
        "half_life_us": 10_000,
        "subdivision_factor": 4,
        "noise_threshold": 6.0,
    }
    assert edeflare.create_method("dv-bafilter").params == {"duration_us": 2_000}
    with pytest.raises(ParameterError, match="positive int"):
        edeflare.create_method("dv-bafilter", duration_us=0)
    with pytest.raises(ParameterError, match="no parameter 'window'"):
        edeflare.create_method("dv-knoise", window=3)
    with pytest.raises(ParameterError, match="unknown dv filter"):
        dvmod.dv_filter_parameters("median")


def test_missing_dependency_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "dv_processing", None)  # import fails
    with pytest.raises(DependencyError, match=r"edeflare\[dv\]"):
        edeflare.deflare(make_events([0], [0], [0], [1]), SIZE, "dv-fastdecay")


def test_bafilter_keeps_supported_events():
    pytest.importorskip("dv_processing")
    ev = make_events([10_000, 10_100, 10_200, 20_000], [3, 4, 7, 4], [3, 3, 0, 4], [1, 1, 1, 0])
    out = dvmod.dv_filter(ev, (8, 8), "bafilter")
    # (4, 3) has (3, 3) 100 us before; (7, 0) has no neighbour; (4, 4) 9.8 ms after (4, 3).
    assert out["x"].tolist() == [4] and out["t"].tolist() == [10_100]


@pytest.mark.parametrize("name", ["dv-fastdecay", "dv-bafilter", "dv-knoise"])
def test_streaming_in_chunks_equals_one_pass(name, rng, tmp_path):
    pytest.importorskip("dv_processing")
    ev = random_events(rng, 30_000, SIZE, t0=1_000_000, span_us=300_000)
    whole = edeflare.deflare(ev, SIZE, name)
    assert 0 < whole.size < ev.size
    # a subset of the input, in order
    keys = ev["t"] * 10_000 + ev["x"].astype(np.int64) * 100 + ev["y"]
    assert np.isin(whole["t"] * 10_000 + whole["x"].astype(np.int64) * 100 + whole["y"], keys).all()
    src, dst = tmp_path / "in.h5", tmp_path / "out.h5"
    edeflare.write_events(src, ev, SIZE)
    edeflare.deflare_file(src, dst, name, window_us=7_000)
    streamed, _ = edeflare.read_events(dst)
    assert same_events(streamed, whole)


def test_cli_deflare_with_a_dv_filter(tmp_path, rng):
    pytest.importorskip("dv_processing")
    from edeflare.cli import main

    ev = random_events(rng, 5_000, SIZE, t0=1_000_000, span_us=100_000)
    src, dst = tmp_path / "in.h5", tmp_path / "out.h5"
    edeflare.write_events(src, ev, SIZE)
    assert main(["deflare", str(src), str(dst), "-m", "dv-fastdecay"]) == 0
    out, size = edeflare.read_events(dst)
    assert size == SIZE and same_events(out, edeflare.deflare(ev, SIZE, "dv-fastdecay"))
