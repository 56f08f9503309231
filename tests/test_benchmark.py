"""The dataset benchmark: per-sequence scoring, averaging over sequences, speed, CLI report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import random_events
from edeflare.benchmark import benchmark, read_sequence
from edeflare.cli import main
from edeflare.evaluate import evaluate_streams, summarize
from edeflare.events import merge_events
from edeflare.io.dsec import write_dsec_groups

SIZE = (32, 24)


@pytest.fixture
def split(tmp_path):
    rng = np.random.default_rng(9)
    for k in range(2):
        gt = random_events(rng, 500, SIZE, t0=1_000_000, span_us=60_000)
        flare = random_events(rng, 300, SIZE, t0=1_000_000, span_us=60_000)
        write_dsec_groups(
            tmp_path / f"s{k}.h5",
            {"input": merge_events(gt, flare), "gt": gt},
            SIZE,
            {"t_start_us": 1_000_000, "t_end_us": 1_060_000},
        )
    return tmp_path


def test_raw_row_is_the_mean_over_sequences_of_segment_means(split):
    result = benchmark(split, {"raw": "raw", "voxel": "voxel"}, progress=False)
    expected = []
    for path in sorted(split.glob("*.h5")):
        inp, gt, size, start, end = read_sequence(path)
        assert (size, start, end) == (SIZE, 1_000_000, 1_060_000)
        segs = evaluate_streams(gt, inp, size, start_us=start, end_us=end)
        assert len(segs) == 3
        expected.append(summarize(m for _, m in segs).means)
    raw = result.evaluation.methods["raw"].means
    for metric in raw:
        assert raw[metric] == pytest.approx(np.mean([e[metric] for e in expected]))
    assert result.evaluation.methods["raw"].n_segments == 6
    speed = result.speed["voxel"]
    assert speed.windows == 6 and speed.stream_us == 120_000
    assert speed.real_time_factor == pytest.approx(speed.seconds / 0.12)
    table = result.table()
    assert table.best["chamfer"] == "voxel"  # the only ranked row


def test_cli_benchmark_report(split, tmp_path, capsys):
    out = tmp_path / "rep" / "t.md"
    assert main(["benchmark", str(split), "--methods", "raw", "pfd-b", "--report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| raw (input) |" in printed and "| pfd-b |" in printed and "windows/s" in printed
    payload = json.loads(out.with_suffix(".json").read_text())
    assert payload["benchmark"]["speed"]["pfd-b"]["windows"] == 6
    assert set(payload["values"]) == {"raw", "pfd-b"}
