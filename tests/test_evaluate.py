"""Evaluation harness and tables: segment averaging, file pairing, the paper's improvement row."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import random_events
from edeflare.cli import main
from edeflare.errors import EventFileError
from edeflare.eval.evaluate import evaluate, evaluate_files, evaluate_streams, pair_files, summarize
from edeflare.eval.metrics import METRICS, SegmentMetrics
from edeflare.eval.tables import ResultsTable
from edeflare.events import make_events, merge_events
from edeflare.io import write_events

SIZE = (101, 101)


def _two_windows():
    """Ground truth with one event per 20 ms window; the prediction is exact in the first
    window and 3 px off in the second, so the segment Chamfer distances are 0 and 3."""
    gt = make_events([5_000, 25_000], [10, 10], [10, 10], [1, 1])
    pred = make_events([5_000, 25_000], [10, 13], [10, 10], [1, 1])
    return gt, pred


def test_segments_are_aligned_and_averaged():
    gt, pred = _two_windows()
    segments = evaluate_streams(gt, pred, SIZE)
    assert [s for s, _ in segments] == [0, 20_000]
    assert [m.chamfer for _, m in segments] == pytest.approx([0.0, 3.0])
    summary = summarize(m for _, m in segments)
    assert summary.means["chamfer"] == pytest.approx(1.5)
    assert summary.n_segments == 2 and summary.undefined["chamfer"] == 0


def test_undefined_segments_are_counted_not_averaged():
    gt = make_events([5_000, 45_000], [10, 10], [10, 10], [1, 1])
    pred = make_events([5_000], [12], [10], [1])  # nothing restored in the third window
    segments = evaluate_streams(gt, pred, SIZE)
    assert len(segments) == 3  # the empty middle window counts too
    s = summarize(m for _, m in segments)
    assert s.means["chamfer"] == pytest.approx(2.0)  # only the first window is defined
    assert s.undefined["chamfer"] == 2
    # TP-F1: first window 0 (other pixel), empty middle window 1, missed third window 0.
    assert s.means["tp_f1"] == pytest.approx((0.0 + 1.0 + 0.0) / 3)


def test_summarize_nothing():
    s = summarize([])
    assert s.n_segments == 0 and all(math.isnan(v) for v in s.means.values())


def test_evaluate_files_streams_the_same_as_in_memory(tmp_path, rng):
    size = (64, 48)
    gt = random_events(rng, 4000, size, t0=3_000_000, span_us=95_000)
    noise = random_events(rng, 800, size, t0=3_010_000, span_us=100_000)
    pred = merge_events(gt[::2], noise)
    write_events(tmp_path / "gt.h5", gt, size)
    write_events(tmp_path / "pred.npz", pred, size)
    from_files = evaluate_files(tmp_path / "gt.h5", tmp_path / "pred.npz")
    in_memory = evaluate_streams(gt, pred, size)
    assert [s for s, _ in from_files] == [s for s, _ in in_memory]
    for (_, a), (_, b) in zip(from_files, in_memory, strict=True):
        assert a == b


def test_evaluate_files_rejects_mismatched_sensors(tmp_path):
    e = make_events([0], [0], [0], [1])
    write_events(tmp_path / "gt.h5", e, (8, 8))
    write_events(tmp_path / "pred.h5", e, (16, 8))
    with pytest.raises(EventFileError, match="differs from the ground truth"):
        evaluate_files(tmp_path / "gt.h5", tmp_path / "pred.h5")


def test_pairing_by_name_in_folders(tmp_path):
    e = make_events([0], [0], [0], [1])
    for folder, suffix in (("gt", ".h5"), ("m", ".npz")):
        (tmp_path / folder).mkdir()
        for name in ("a", "b"):
            write_events(tmp_path / folder / f"{name}{suffix}", e, (4, 4))
    (tmp_path / "m" / "notes.md").write_text("ignored")
    pairs = pair_files(tmp_path / "gt", tmp_path / "m")
    assert [(n, g.name, p.name) for n, g, p in pairs] == [
        ("a", "a.h5", "a.npz"),
        ("b", "b.h5", "b.npz"),
    ]
    (tmp_path / "m" / "b.npz").unlink()
    with pytest.raises(EventFileError, match=r"no restored file for \['b'\]"):
        pair_files(tmp_path / "gt", tmp_path / "m")
    with pytest.raises(EventFileError, match="no such file"):
        pair_files(tmp_path / "gt", tmp_path / "missing")


def test_evaluate_averages_over_files(tmp_path):
    gt, pred = _two_windows()  # file a: segment CDs 0 and 3 -> mean 1.5
    gt_b = make_events([5_000], [10], [10], [1])
    pred_b = make_events([5_000], [16], [10], [1])  # file b: one segment, CD 6
    for folder in ("gt", "m"):
        (tmp_path / folder).mkdir()
    write_events(tmp_path / "gt" / "a.h5", gt, SIZE)
    write_events(tmp_path / "m" / "a.h5", pred, SIZE)
    write_events(tmp_path / "gt" / "b.h5", gt_b, SIZE)
    write_events(tmp_path / "m" / "b.h5", pred_b, SIZE)
    result = evaluate(tmp_path / "gt", {"m": tmp_path / "m"}, progress=False)
    assert result.per_file["m"]["a"].means["chamfer"] == pytest.approx(1.5)
    assert result.per_file["m"]["b"].means["chamfer"] == pytest.approx(6.0)
    assert result.methods["m"].means["chamfer"] == pytest.approx((1.5 + 6.0) / 2)
    assert result.methods["m"].n_segments == 3


# Table 1 of the paper (E-Flare2.7K test set).
PAPER_TABLE_1 = {
    "raw": [1.3555, 0.5222, 0.8315, 0.3666, 0.3430, 0.5138, 0.6303, 0.6939],
    "EFR": [1.3237, 0.5439, 0.5357, 0.2019, 0.1755, 0.1616, 0.3572, 0.4811],
    "PFD-A": [1.3958, 0.5397, 0.8357, 0.3637, 0.3392, 0.4383, 0.5496, 0.6125],
    "PFD-B": [1.2496, 0.4613, 0.2851, 0.1159, 0.1021, 0.4460, 0.5155, 0.5727],
    "Voxel Transform": [1.2923, 0.5576, 0.3495, 0.1037, 0.0829, 0.2177, 0.5444, 0.6318],
    "E-DeflareNet": [0.4477, 0.2646, 0.1269, 0.0487, 0.0435, 0.7071, 0.7627, 0.7794],
}


def test_table_reproduces_the_papers_improvement_row():
    table = ResultsTable({k: dict(zip(METRICS, v, strict=True)) for k, v in PAPER_TABLE_1.items()})
    assert set(table.best.values()) == {"E-DeflareNet"}
    assert table.second == {
        "chamfer": "PFD-B",
        "gaussian": "PFD-B",
        "mse": "PFD-B",
        "pmse_2": "Voxel Transform",
        "pmse_4": "Voxel Transform",
        "r_f1": "PFD-B",
        "t_f1": "PFD-A",
        "tp_f1": "Voxel Transform",
    }  # raw is not ranked: its R-F1 0.5138 would otherwise be second
    got = [round(table.improvement[m], 1) for m in METRICS]
    assert got == [64.2, 42.6, 55.5, 53.0, 47.5, 58.5, 38.8, 23.4]
    md = table.to_markdown()
    assert md.splitlines()[2].startswith("| raw (input) | 1.3555 |")
    assert "| **0.4477** |" in md and "| *1.2496* |" in md
    assert md.strip().splitlines()[-1].startswith("| Improvement (%) | 64.2% | 42.6% |")
    rows = table.to_csv().splitlines()
    assert rows[0] == "method,chamfer,gaussian,mse,pmse_2,pmse_4,r_f1,t_f1,tp_f1"
    assert rows[-1].startswith("improvement_percent,64.1")
    payload = json.loads(table.to_json())
    assert payload["best"]["tp_f1"] == "E-DeflareNet" and payload["raw"] == "raw"


PAPER_TABLE_3 = {  # the ablation, Table 3 of the paper
    "raw": [1.7855, 0.7170, 0.8158, 0.3431, 0.3266, 0.2299, 0.2915, 0.3093],
    "Simple": [1.3434, 0.5564, 0.1816, 0.0734, 0.0688, 0.2703, 0.2768, 0.2644],
    "Simple + Random": [1.5257, 0.6449, 0.1957, 0.0769, 0.0715, 0.2301, 0.2769, 0.2811],
    "Physical + Random": [1.6811, 0.7203, 0.2020, 0.0834, 0.0788, 0.1567, 0.2001, 0.2103],
    "No Light": [1.9745, 0.8487, 0.1951, 0.0843, 0.0806, 0.0189, 0.0459, 0.0709],
    "Full": [1.1368, 0.4651, 0.1741, 0.0690, 0.0644, 0.3498, 0.3386, 0.3011],
}


def test_table_with_a_reference_row_reproduces_the_ablation_improvement_row():
    values = {k: dict(zip(METRICS, v, strict=True)) for k, v in PAPER_TABLE_3.items()}
    table = ResultsTable(values, reference="Full")
    got = [round(table.improvement[m], 1) for m in METRICS]
    assert got == [15.4, 16.4, 4.1, 6.0, 6.4, 29.4, 22.3, 7.1]
    # when the reference loses, the row is negative (not the winner's gain)
    values["Simple"]["chamfer"] = 1.0
    worse = ResultsTable(values, reference="Full").improvement["chamfer"]
    assert worse == pytest.approx(-13.68)
    with pytest.raises(ValueError, match="'Ful'"):
        ResultsTable(values, reference="Ful")


def test_table_with_one_method_has_no_improvement_and_nan_cells():
    table = ResultsTable(
        {"raw": {"chamfer": 1.0}, "only": {"chamfer": float("nan")}}, metrics=["chamfer"]
    )
    assert table.best == {"chamfer": None} and math.isnan(table.improvement["chamfer"])
    assert "| only | – |" in table.to_markdown()
    assert json.loads(table.to_json())["values"]["only"]["chamfer"] is None


def test_segment_metrics_as_dict_roundtrip():
    m = SegmentMetrics(1, 2, 3, 4, 5, 0.1, 0.2, 0.3)
    assert list(m.as_dict()) == list(METRICS)


def test_cli_evaluate_writes_report(tmp_path, capsys):
    gt, pred = _two_windows()
    write_events(tmp_path / "gt.h5", gt, SIZE)
    write_events(tmp_path / "pred.h5", pred, SIZE)
    argv = [
        "evaluate",
        "--gt",
        str(tmp_path / "gt.h5"),
        "--pred",
        f"raw={tmp_path / 'pred.h5'}",
        "--pred",
        f"same={tmp_path / 'gt.h5'}",
        "--report",
        str(tmp_path / "out" / "table.md"),
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "| raw (input) | 1.5000 |" in out
    assert "| same | **0.0000** |" in out
    payload = json.loads((tmp_path / "out" / "table.json").read_text())
    assert payload["values"]["raw"]["chamfer"] == pytest.approx(1.5)
    assert payload["evaluation"]["methods"]["raw"]["n_segments"] == 2
    assert (tmp_path / "out" / "table.csv").read_text().startswith("method,chamfer")


def test_cli_evaluate_errors(tmp_path, capsys):
    assert main(["evaluate", "--gt", str(tmp_path / "no.h5"), "--pred", f"a={tmp_path}"]) == 1
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["evaluate", "--gt", "x.h5", "--pred", "no-equals-sign"])
    np.testing.assert_equal(list(tmp_path.iterdir()), [])
