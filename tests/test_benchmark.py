"""The dataset benchmark: per-sequence scoring, averaging over sequences, speed, CLI report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import random_events
from edeflare.cli import main
from edeflare.eval.benchmark import benchmark
from edeflare.eval.evaluate import evaluate_streams, summarize
from edeflare.events import merge_events
from edeflare.io.dsec import write_dsec_groups
from edeflare.io.sequence import read_sequence

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


def test_streamed_benchmark_equals_deflaring_whole_sequences_in_memory(split, monkeypatch):
    """The benchmark streams windows; EFR (outputs stamped in the past) and PFD
    score exactly as de-flaring each whole input in memory does."""
    from edeflare.io.dsec import DsecReader
    from edeflare.methods import create_method

    largest = []
    read = DsecReader.read

    def counting_read(self, start=0, stop=None):
        events = read(self, start, stop)
        largest.append(events.size)
        return events

    monkeypatch.setattr(DsecReader, "read", counting_read)
    benchmark(split, {"pfd-a": "pfd-a"}, progress=False)
    monkeypatch.setattr(DsecReader, "read", read)
    # window by window: no read held a whole group (800 input events over three
    # 20 ms windows); EFR's first pass reads 1 M-event chunks, not windows
    assert largest and max(largest) < 400
    result = benchmark(split, {"efr": "efr", "pfd-a": "pfd-a"}, progress=False)
    for row in ("efr", "pfd-a"):
        expected = []
        for path in sorted(split.glob("*.h5")):
            inp, gt, size, start, end = read_sequence(path)
            pred = create_method(row)(inp, size)
            segs = evaluate_streams(gt, pred, size, start_us=start, end_us=end)
            expected.append(summarize(m for _, m in segs).means)
        got = result.evaluation.methods[row].means
        for metric, value in got.items():
            assert value == pytest.approx(np.mean([e[metric] for e in expected]), nan_ok=True)


def test_cli_benchmark_report(split, tmp_path, capsys):
    out = tmp_path / "rep" / "t.md"
    assert main(["benchmark", str(split), "--methods", "raw", "pfd-b", "--report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| raw (input) |" in printed and "| pfd-b |" in printed and "windows/s" in printed
    payload = json.loads(out.with_suffix(".json").read_text())
    assert payload["benchmark"]["speed"]["pfd-b"]["windows"] == 6
    assert set(payload["values"]) == {"raw", "pfd-b"}


def test_cli_benchmark_compares_several_named_models(split, tmp_path, capsys):
    import torch

    from edeflare.models import create_model
    from edeflare.models.weights import ModelCard, save_model

    identity = tmp_path / "identity.safetensors"
    save_model(identity, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    adder = create_model("unet2d.tiny")
    with torch.no_grad():
        adder.final.bias.fill_(1.0)  # adds an ON event to every cell
    adds = tmp_path / "adds.safetensors"
    save_model(adds, adder, ModelCard(preset="unet2d.tiny"))
    out = tmp_path / "t.md"
    argv = ["benchmark", str(split), "--methods", "raw", "--report", str(out)]
    argv += ["--model", f"ident={identity}", "--model", f"adds={adds}"]
    assert main(argv) == 0
    values = json.loads(out.with_suffix(".json").read_text())["values"]
    assert list(values) == ["raw", "ident", "adds"]
    # the identity model with the keep decoder returns the input exactly
    assert values["ident"] == pytest.approx(values["raw"])
    assert values["adds"]["mse"] > values["ident"]["mse"]
    capsys.readouterr()
    # an unnamed --model adds the 'model' row; a clash or two unnamed ones are errors
    assert main(["benchmark", str(split), "--methods", "raw", "--model", str(identity)]) == 0
    assert "| model |" in capsys.readouterr().out
    assert main(["benchmark", str(split), "--model", f"raw={identity}"]) == 1
    assert "already has a row 'raw'" in capsys.readouterr().err
    assert main(["benchmark", str(split), "--model", str(identity), "--model", str(adds)]) == 1
    assert "one unnamed --model" in capsys.readouterr().err


@pytest.mark.slow
def test_forward_test_set_files_at_1280x720_are_benchmarked(tmp_path):
    """An eflare-forward-hd sequence (the forward model's groups, 1280x720) scores as any."""
    from edeflare.data.generate import RECIPES, generate_dataset

    one = RECIPES["eflare-forward-hd"].replace(sequences=1, test_sequences=1, duration_us=20_000)
    generate_dataset(one, tmp_path, progress=False)
    inp, gt, size, start, end = read_sequence(tmp_path / "test" / "seq_00000.h5")
    assert size == (1280, 720) and (start, end) == (0, 20_000) and inp.size > gt.size > 0
    result = benchmark(tmp_path / "test", {"raw": "raw", "pfd-a": "pfd-a"}, progress=False)
    for row in ("raw", "pfd-a"):
        summary = result.evaluation.methods[row]
        assert summary.n_segments == 1 and all(np.isfinite(v) for v in summary.means.values())
    assert result.speed["raw"].windows == 1
