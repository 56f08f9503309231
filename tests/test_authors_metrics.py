"""The authors' convention (edeflare.eval.authors): each behaviour on a hand-computed case.

Every test states the value the authors' rule gives and, where it differs, what
another reading would give, so that a change of rule fails here.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import random_events, same_events
from edeflare.cli import main
from edeflare.errors import ParameterError
from edeflare.eval.authors import (
    CONVENTIONS,
    authors_chunks,
    authors_event_distances,
    authors_f1,
    authors_metrics,
    authors_voxel,
    authors_voxel_scores,
    check_convention,
    minmax_points,
    polarity_parts,
)
from edeflare.eval.benchmark import benchmark
from edeflare.eval.evaluate import evaluate, evaluate_events
from edeflare.eval.report import write_report
from edeflare.events import make_events, merge_events
from edeflare.io import write_events
from edeflare.io.dsec import write_dsec_groups
from edeflare.io.sequence import read_sequence

N_CELLS = 8 * 480 * 640  # the authors' grid, whatever the sensor
N_POOLED_2 = 2 * 8 * 240 * 320  # positive and negative parts after 2x2 pooling
N_POOLED_4 = 2 * 8 * 120 * 160


def ev(*rows: tuple[int, int, int, int]) -> np.ndarray:
    """Events from ``(t, x, y, p)`` rows."""
    t, x, y, p = zip(*rows, strict=True)
    return make_events(list(t), list(x), list(y), list(p))


# --- loading and min-max scaling -------------------------------------------------------


def test_minmax_scaling_over_the_stream_itself_with_the_1e8_epsilon():
    # t from the first event in seconds: 0, 0.0005, 0.002 s; x 10..30; y one value; p +-1
    points = minmax_points(ev((1_000, 10, 5, 1), (1_500, 20, 5, 0), (3_000, 30, 5, 1)))
    scale_t = 100 / (0.002 + 1e-8)  # seconds, not microseconds: 1e-8 shows in t
    assert points[:, 0] == pytest.approx([0.0, 0.0005 * scale_t, 0.002 * scale_t], rel=1e-12)
    assert points[1, 0] == pytest.approx(24.999875000625, rel=1e-12)
    assert points[:, 1] == pytest.approx([0.0, 1000 / (20 + 1e-8), 2000 / (20 + 1e-8)])
    assert points[:, 2].tolist() == [0.0, 0.0, 0.0]  # one value: 0, not 100
    # polarity +1 where p == 1, else -1, then scaled: ON 200/(2+1e-8), OFF 0
    assert points[:, 3] == pytest.approx([200 / (2 + 1e-8), 0.0, 200 / (2 + 1e-8)], rel=1e-12)
    # one polarity only: all 0, the value OFF takes in a stream with both
    assert minmax_points(ev((0, 0, 0, 1), (9, 1, 1, 1)))[:, 3].tolist() == [0.0, 0.0]


def test_each_stream_is_scaled_over_its_own_extent():
    gt = ev((0, 0, 0, 1), (10_000, 100, 0, 1))
    half = ev((0, 0, 0, 1), (10_000, 50, 0, 1))  # the same shape at half the width
    late = ev((500_000, 0, 0, 1), (510_000, 100, 0, 1))  # the same, 0.5 s later
    assert authors_event_distances(gt, half) == pytest.approx((0.0, 0.0), abs=1e-8)
    assert authors_event_distances(gt, late) == (0.0, 0.0)
    # the edeflare convention scales by the sensor: 50 px apart on a 101-wide sensor
    assert evaluate_events(gt, half, (101, 1)).means["chamfer"] == pytest.approx(25.0)


# --- Chamfer and Gaussian ----------------------------------------------------------------

# Both streams span t 0..10 ms, x and y 0..100 and both polarities, so the scaling
# is the identity up to the epsilon; C lies 1 px right of A.
A, B = (0, 0, 0, 1), (10_000, 100, 100, 0)
C = (0, 1, 0, 1)
D = (5_000, 50, 50, 1)  # far from A, B and C
ONE_PX = 100 / (100 + 1e-8)


def test_chamfer_and_gaussian_by_hand_with_0_4_not_2_sigma_squared():
    chamfer, gaussian = authors_event_distances(ev(A, B), ev(A, C, B))
    assert chamfer == pytest.approx(ONE_PX / 3, rel=1e-9)
    assert gaussian == pytest.approx((1 - math.exp(-(ONE_PX**2) / 0.4)) / 3, rel=1e-9)
    assert gaussian == pytest.approx(0.305972, abs=1e-6)
    assert abs(gaussian - (1 - math.exp(-1 / (2 * 0.4**2))) / 3) > 0.01  # 2 sigma^2: 0.319
    assert abs(gaussian - (1 - math.exp(-1 / (2 * 0.4))) / 3) > 0.05  # 2 sigma: 0.238


def test_the_kd_query_is_one_sided_from_the_estimate():
    chamfer, _ = authors_event_distances(ev(A, B), ev(A, C, B))
    # a ground-truth event far from every estimated one changes nothing
    assert authors_event_distances(ev(A, D, B), ev(A, C, B))[0] == pytest.approx(chamfer)
    # the same event in the estimate adds its distance to A: sqrt(50^2 * 3) (t: 1e-8 off)
    with_d = authors_event_distances(ev(A, B), ev(A, C, D, B))[0]
    assert with_d == pytest.approx((ONE_PX + math.sqrt(3 * 50**2)) / 4, rel=1e-5)


def test_empty_streams_are_nan_or_the_gaussian_limit():
    gt = ev(A, B)
    assert all(math.isnan(v) for v in authors_event_distances(gt, gt[:0]))
    chamfer, gaussian = authors_event_distances(gt[:0], gt)
    assert math.isnan(chamfer) and gaussian == 1.0
    m = authors_metrics(gt, gt[:0])
    assert m.n_chunks == 0 and all(math.isnan(v) for v in m.as_dict().values())


# --- chunks and pairing ------------------------------------------------------------------


def test_chunks_start_at_the_streams_own_first_event_and_empty_ones_are_dropped():
    stream = ev((7_000, 0, 0, 1), (26_999, 0, 0, 1), (27_000, 0, 0, 1), (68_000, 0, 0, 1))
    chunks = authors_chunks(stream)
    # [7, 27) ms, [27, 47) ms, [47, 67) ms is empty and dropped, [67, 87) ms
    assert [c["t"].tolist() for c in chunks] == [[7_000, 26_999], [27_000], [68_000]]
    assert authors_chunks(stream[:0]) == []


def test_chunk_lists_are_paired_in_order_not_by_time():
    # the ground truth's second chunk is [40, 60) ms (the one between is empty), the
    # estimate's [20, 40) ms: paired with each other, their grids are the same
    gt = ev((0, 0, 0, 1), (45_000, 1, 0, 1))
    pred = ev((0, 0, 0, 1), (25_000, 1, 0, 1))
    m = authors_metrics(gt, pred)
    assert m.n_chunks == 2
    assert (m.mse, m.r_f1, m.t_f1, m.tp_f1) == (0.0, 1.0, 1.0, 1.0)
    # the edeflare convention compares aligned windows: the second event is missed twice
    assert evaluate_events(gt, pred, (2, 1)).means["r_f1"] < 1


def test_pairing_stops_at_the_shorter_list():
    gt = ev((0, 0, 0, 1), (20_000, 1, 0, 1), (40_000, 2, 0, 1))
    pred = ev((0, 0, 0, 1))
    m = authors_metrics(gt, pred)
    assert m.n_chunks == 1  # zip: the ground truth's last two chunks are not scored
    assert (m.mse, m.r_f1) == (0.0, 1.0)


def test_voxel_metrics_are_means_over_chunk_pairs():
    gt = ev((0, 0, 0, 1), (20_000, 0, 0, 1))
    pred = ev((0, 0, 0, 1), (20_000, 0, 0, 1), (20_000, 5, 5, 1))  # an extra cell in chunk 2
    m = authors_metrics(gt, pred)
    assert m.n_chunks == 2
    assert m.mse == pytest.approx((0 + 1 / N_CELLS) / 2)
    assert m.r_f1 == pytest.approx((1 + 2 / 3) / 2)  # chunk 2: 2 TP / (2 TP + 1 FP)


# --- voxels ------------------------------------------------------------------------------


def test_bins_count_2_5_ms_from_the_chunks_first_event_and_clip_at_7():
    offsets = [0, 2_499, 2_500, 17_499, 17_500, 19_999, 31_000]  # the last: past 20 ms
    chunk = ev(*((1_000 + dt, k, 0, 1) for k, dt in enumerate(offsets)))
    grid = authors_voxel(chunk, grid_size=(len(offsets), 1))
    bins = [int(np.flatnonzero(grid[:, 0, k])[0]) for k in range(len(offsets))]
    assert bins == [0, 0, 1, 6, 7, 7, 7]
    # a chunk of a stream starts where the stream's first event says; its bins where
    # the chunk's own first event is: 23 ms, then 25.4 ms (bin 0) and 25.6 ms (bin 1)
    stream = ev((0, 0, 0, 1), (23_000, 0, 0, 1), (25_400, 1, 0, 1), (25_600, 2, 0, 1))
    second = authors_chunks(stream)[1]
    assert np.argwhere(authors_voxel(second, grid_size=(3, 1))[:, 0, :]).tolist() == [
        [0, 0],
        [0, 1],
        [1, 2],
    ]


def test_on_and_off_in_one_cell_cancel():
    chunk = ev((0, 3, 2, 1), (100, 3, 2, 0), (2_600, 3, 2, 0), (2_700, 4, 2, 1), (2_800, 4, 2, 1))
    grid = authors_voxel(chunk)
    assert grid.shape == (8, 480, 640) and grid.dtype == np.float64
    assert grid[0, 2, 3] == 0  # +1 - 1
    assert (grid[1, 2, 3], grid[1, 2, 4]) == (-1.0, 2.0)
    assert np.count_nonzero(grid) == 2
    # an estimate with one ON/OFF pair more in one cell of one bin scores as the truth
    gt = ev((0, 0, 0, 1), (5_000, 9, 9, 0))
    pred = merge_events(gt, ev((1_000, 5, 5, 1), (1_200, 5, 5, 0)))
    m = authors_metrics(gt, pred)
    assert (m.mse, m.pmse_2, m.pmse_4, m.r_f1, m.t_f1, m.tp_f1) == (0, 0, 0, 1, 1, 1)


def test_events_beyond_640x480_are_left_out_of_the_grids_only():
    inside = ev((0, 639, 479, 1))
    beyond = ev((0, 640, 0, 1), (10, 0, 480, 0), (20, 1279, 719, 1))
    grid = authors_voxel(merge_events(inside, beyond))
    assert np.count_nonzero(grid) == 1 and grid[0, 479, 639] == 1
    m = authors_metrics(inside, merge_events(inside, beyond))
    assert (m.mse, m.r_f1, m.tp_f1) == (0.0, 1.0, 1.0)  # the grids are the same
    assert m.chamfer > 0  # the distances see every event


# --- MSE, PMSE ---------------------------------------------------------------------------


def _one_event_each(gt_xy_p: tuple[int, int, int], pred_xy_p: tuple[int, int, int]):
    (xg, yg, pg), (xp, yp, pp) = gt_xy_p, pred_xy_p
    m = authors_metrics(ev((0, xg, yg, pg)), ev((0, xp, yp, pp)))
    dense = authors_voxel_scores(
        authors_voxel(ev((0, xg, yg, pg))), authors_voxel(ev((0, xp, yp, pp)))
    )
    assert (m.mse, m.pmse_2, m.pmse_4) == pytest.approx(dense[:3], rel=1e-12)
    return m


def test_pmse_pools_the_positive_and_negative_parts():
    same_block = _one_event_each((0, 0, 1), (1, 1, 1))
    assert same_block.mse == pytest.approx(2 / N_CELLS)
    assert (same_block.pmse_2, same_block.pmse_4) == (0.0, 0.0)
    next_block = _one_event_each((0, 0, 1), (2, 0, 1))  # another 2x2 block, one 4x4 block
    assert next_block.pmse_2 == pytest.approx(2 * (1 / 4) ** 2 / N_POOLED_2)
    assert next_block.pmse_4 == 0.0
    far = _one_event_each((0, 0, 1), (4, 0, 1))
    assert far.pmse_4 == pytest.approx(2 * (1 / 16) ** 2 / N_POOLED_4)
    # OFF in the truth, ON in the estimate, one 2x2 block: each part is off by 1/4;
    # pooling the signed grid instead would give one cell off by 1/2 of half as many
    flipped = _one_event_each((0, 0, 0), (1, 1, 1))
    assert flipped.pmse_2 == pytest.approx(2 * (1 / 4) ** 2 / N_POOLED_2)
    assert flipped.pmse_2 != pytest.approx((1 / 2) ** 2 / (N_POOLED_2 / 2))


def test_pooling_drops_remainder_rows_and_columns_like_avg_pool2d():
    gt = np.zeros((1, 3, 5))
    pred = gt.copy()
    pred[0, 2, 4] = 1  # last row and column: outside every 2x2 block
    mse, pmse_2, pmse_4, *_ = authors_voxel_scores(gt, pred)
    assert mse == pytest.approx(1 / 15)
    assert pmse_2 == 0.0
    assert math.isnan(pmse_4)  # a 3-row grid has no 4x4 block
    pred[0, 1, 3] = 1  # inside block (0, 1): (1/4)^2 over 2 parts x 1 x 2 blocks
    assert authors_voxel_scores(gt, pred)[1] == pytest.approx((1 / 4) ** 2 / 4)


def test_polarity_parts():
    parts = polarity_parts(np.array([[3.0, -2.0], [0.0, 1.0]]))
    assert parts.tolist() == [[[3.0, 0.0], [0.0, 1.0]], [[0.0, 2.0], [0.0, 0.0]]]


# --- F1 ----------------------------------------------------------------------------------


def test_f1_threshold_is_strictly_above_0_001():
    gt = np.zeros((1, 1, 1))
    at, above = gt + 0.001, gt + 0.0011
    assert authors_voxel_scores(at, at)[3:] == (0.0, 0.0, 0.0)  # not active: no TP
    assert authors_voxel_scores(above, above)[3:] == (1.0, 1.0, 1.0)
    assert authors_voxel_scores(-above, -above)[3:] == (1.0, 1.0, 1.0)  # the negative part


def test_the_three_f1_variants_by_hand():
    gt = np.zeros((2, 1, 2))
    pred = np.zeros((2, 1, 2))
    gt[0, 0, 0] = gt[0, 0, 1] = 1  # ON at pixels 0 and 1, bin 0
    pred[1, 0, 0] = 1  # pixel 0: ON, but in bin 1
    pred[0, 0, 1] = -1  # pixel 1: OFF
    r_f1, t_f1, tp_f1 = authors_voxel_scores(gt, pred)[3:]
    assert r_f1 == 0.0  # no (polarity, bin, pixel) in common
    assert t_f1 == 0.5  # (ON, pixel 0) in common: 2 / (2 + 2)
    assert tp_f1 == 1.0  # both pixels active in both
    # summing the parts (not the signed values) over bins: +1 then -1 stays active
    gt = np.zeros((2, 1, 1))
    gt[0], gt[1] = 1, -1
    assert authors_voxel_scores(gt, np.abs(gt))[5] == 1.0


def test_f1_is_0_without_a_true_positive_even_for_two_empty_grids():
    empty = np.zeros((2, 3), bool)
    assert authors_f1(empty, empty) == 0.0  # the edeflare convention says 1
    one = empty.copy()
    one[0, 0] = True
    assert authors_f1(one, empty) == 0.0
    assert authors_f1(one, one) == 1.0
    # a chunk pair whose events all cancel scores 0 on the three F1s, MSE 0
    pair = ev((0, 1, 1, 1), (1, 1, 1, 0))
    m = authors_metrics(pair, pair)
    assert (m.mse, m.r_f1, m.t_f1, m.tp_f1) == (0.0, 0.0, 0.0, 0.0)


# --- the fast path, the file, the mean over files ----------------------------------------


@pytest.mark.parametrize("grid_size", [(640, 480), (7, 5)])
def test_file_metrics_equal_the_dense_reference_chunk_by_chunk(rng, grid_size):
    for n_gt, n_pred in ((3, 2), (400, 700), (20_000, 9_000)):
        gt = random_events(rng, n_gt, (700, 520), t0=3_000, span_us=50_000)
        pred = random_events(rng, n_pred, (700, 520), t0=4_000, span_us=70_000)
        copies = gt.copy(), pred.copy()
        m = authors_metrics(gt, pred, grid_size=grid_size)
        assert same_events(gt, copies[0]) and same_events(pred, copies[1])  # untouched
        pairs = list(zip(authors_chunks(gt), authors_chunks(pred), strict=False))
        dense = np.mean(
            [
                authors_voxel_scores(
                    authors_voxel(a, grid_size=grid_size), authors_voxel(b, grid_size=grid_size)
                )
                for a, b in pairs
            ],
            axis=0,
        )
        got = (m.mse, m.pmse_2, m.pmse_4, m.r_f1, m.t_f1, m.tp_f1)
        assert got == pytest.approx(tuple(dense), rel=1e-10, nan_ok=True)
        assert m.n_chunks == len(pairs) and (m.n_gt, m.n_pred) == (n_gt, n_pred)


def test_evaluate_averages_file_values_over_files(tmp_path):
    size = (32, 24)
    gt_dir, pred_dir = tmp_path / "gt", tmp_path / "pred"
    gt_a = ev((0, 0, 0, 1), (5_000, 3, 4, 0))
    write_events(gt_dir / "a.h5", gt_a, size)
    write_events(pred_dir / "a.h5", gt_a, size)  # exact: MSE 0, R-F1 1, Chamfer 0
    gt_b = ev((0, 0, 0, 1), (5_000, 3, 4, 0), (25_000, 5, 5, 1))  # two chunks
    pred_b = merge_events(gt_b, ev((26_000, 9, 9, 1)))  # chunk 2: MSE 1/N, R-F1 2/3
    write_events(gt_dir / "b.h5", gt_b, size)
    write_events(pred_dir / "b.h5", pred_b, size)
    result = evaluate(gt_dir, {"m": pred_dir}, convention="authors", progress=False)
    b = authors_metrics(gt_b, pred_b)
    assert result.per_file["m"]["b"].means == b.as_dict()
    assert (b.mse, b.r_f1) == pytest.approx(((0 + 1 / N_CELLS) / 2, (1 + 2 / 3) / 2))
    means = result.methods["m"].means
    # each file weighs the same (pooling the three chunks would give 1/(3N) and 8/9)
    assert means["mse"] == pytest.approx((0 + b.mse) / 2) == pytest.approx(1 / (4 * N_CELLS))
    assert means["r_f1"] == pytest.approx((1 + 5 / 6) / 2)
    assert means["chamfer"] == pytest.approx(b.chamfer / 2)
    assert result.methods["m"].n_segments == 3 and result.convention == "authors"
    assert result.to_dict()["convention"] == "authors"
    # a file without estimated events is undefined: left out of the means, counted
    write_events(gt_dir / "c.h5", gt_a, size)
    write_events(pred_dir / "c.h5", gt_a[:0], size)
    with_c = evaluate(gt_dir, {"m": pred_dir}, convention="authors", progress=False)
    assert with_c.methods["m"].means == pytest.approx(means)
    assert with_c.methods["m"].undefined["chamfer"] == 1


def test_evaluate_events_in_the_authors_convention():
    gt = ev((1_000, 0, 0, 1), (30_000, 1, 0, 1))
    pred = ev((1_000, 0, 0, 1))
    s = evaluate_events(gt, pred, (4, 4), convention="authors")
    assert s.means == authors_metrics(gt, pred).as_dict() and s.n_segments == 1
    # start_us / end_us select the span before scoring
    cut = evaluate_events(gt, gt, (4, 4), convention="authors", start_us=0, end_us=20_000)
    assert cut.n_segments == 1 and cut.means["r_f1"] == 1.0
    assert check_convention("edeflare") == "edeflare" and CONVENTIONS == ("edeflare", "authors")
    with pytest.raises(ParameterError, match="edeflare, authors"):
        evaluate_events(gt, pred, (4, 4), convention="paper")
    with pytest.raises(ParameterError, match="20 ms chunks of 8 bins"):
        evaluate_events(gt, pred, (4, 4), convention="authors", bins=4)


@pytest.fixture
def split(tmp_path):
    rng = np.random.default_rng(9)
    size = (32, 24)
    for k in range(2):
        gt = random_events(rng, 500, size, t0=1_000_000, span_us=60_000)
        flare = random_events(rng, 300, size, t0=1_000_000, span_us=60_000)
        write_dsec_groups(
            tmp_path / f"s{k}.h5",
            {"input": merge_events(gt, flare), "gt": gt},
            size,
            {"t_start_us": 1_000_000, "t_end_us": 1_060_000},
        )
    return tmp_path


def test_benchmark_scores_each_sequence_whole(split, tmp_path):
    outputs = {}

    def keep(*, row, path, gt, output, **_):
        outputs[row, path.stem] = gt, output

    rows = {"raw": "raw", "pfd-a": "pfd-a"}
    result = benchmark(split, rows, progress=False, on_output=keep, convention="authors")
    assert result.evaluation.convention == "authors"
    for path in sorted(split.glob("*.h5")):
        inp, gt, *_ = read_sequence(path)
        raw = result.evaluation.per_file["raw"][path.stem]
        assert raw.means == authors_metrics(gt, inp).as_dict()
        assert raw.n_segments == 3  # 60 ms from the first event: three chunks
        kept_gt, out = outputs["pfd-a", path.stem]
        expected = authors_metrics(kept_gt, out).as_dict()
        assert result.evaluation.per_file["pfd-a"][path.stem].means == expected
    files = result.evaluation.per_file["raw"].values()
    assert result.evaluation.methods["raw"].means["mse"] == pytest.approx(
        np.mean([f.means["mse"] for f in files])
    )
    default = benchmark(split, {"raw": "raw"}, progress=False)
    assert default.evaluation.convention == "edeflare"
    assert default.evaluation.methods["raw"].means != result.evaluation.methods["raw"].means
    # the HTML report says which convention its table follows
    for bench, name in ((result, "authors&#x27;"), (default, "edeflare")):
        page = write_report(bench, tmp_path / name[:7], progress=False)
        assert f"Metrics in the {name} convention" in page.read_text()


# --- command line ------------------------------------------------------------------------


def test_cli_evaluate_convention(tmp_path, capsys):
    size = (32, 24)
    gt = ev((0, 0, 0, 1), (25_000, 3, 4, 0))
    pred = merge_events(gt, ev((1_000, 9, 9, 1)))
    write_events(tmp_path / "gt.h5", gt, size)
    write_events(tmp_path / "pred.h5", pred, size)
    argv = ["evaluate", "--gt", str(tmp_path / "gt.h5"), "--pred", f"m={tmp_path / 'pred.h5'}"]
    report = tmp_path / "out" / "t.md"
    assert main([*argv, "--convention", "authors", "--report", str(report)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("Metrics in the authors' convention")
    assert "m: 2 chunk pairs" in printed
    payload = json.loads(report.with_suffix(".json").read_text())
    assert payload["convention"] == "authors"
    assert payload["evaluation"]["convention"] == "authors"
    assert payload["values"]["m"]["mse"] == pytest.approx(authors_metrics(gt, pred).mse)
    assert report.read_text().startswith("Metrics in the authors' convention")
    # the default prints the table alone; its report names the convention too
    assert main([*argv, "--report", str(report)]) == 0
    assert capsys.readouterr().out.startswith("| Method |")
    assert json.loads(report.with_suffix(".json").read_text())["convention"] == "edeflare"
    assert report.read_text().startswith("Metrics in the edeflare convention")
    assert main([*argv, "--convention", "authors", "--window-ms", "10"]) == 1
    assert "fixes 20 ms chunks of 8 bins" in capsys.readouterr().err


def test_cli_benchmark_convention(split, tmp_path, capsys):
    out = tmp_path / "rep" / "t.md"
    argv = ["benchmark", str(split), "--methods", "raw", "--convention", "authors"]
    assert main([*argv, "--report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("Metrics in the authors' convention") and "| raw (input) |" in printed
    payload = json.loads(out.with_suffix(".json").read_text())
    assert payload["convention"] == "authors"
    assert payload["benchmark"]["evaluation"]["convention"] == "authors"
