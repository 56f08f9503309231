"""Metrics: hand-computed values for each of the eight, invariants, empty streams, brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import random_events
from edeflare.errors import EventsError
from edeflare.eval.metrics import (
    METRICS,
    SIGMA,
    chamfer_distance,
    deletion_shares,
    event_distances,
    f1_score,
    f1_scores,
    gaussian_distance,
    keep_only_oracle,
    mse,
    nearest_distances,
    normalize_events,
    pmse,
    segment_metrics,
)
from edeflare.events import make_events, merge_events
from edeflare.voxel import encode_polarity

# A 101x101 sensor makes one pixel exactly one normalised unit; a 1000 µs window makes 10 µs one.
SIZE = (101, 101)
WIN = 1000


def ev(t, x, y, p):
    return make_events(t, x, y, p)


def test_identical_streams_are_perfect(rng):
    e = random_events(rng, 3000, (64, 48), t0=40_000, span_us=20_000)
    m = segment_metrics(e, e, (64, 48), 40_000, 20_000)
    assert (m.chamfer, m.gaussian, m.mse, m.pmse_2, m.pmse_4) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert (m.r_f1, m.t_f1, m.tp_f1) == (1.0, 1.0, 1.0)
    assert (m.n_gt, m.n_pred) == (3000, 3000)


def test_normalisation_is_fixed_by_sensor_and_window():
    e = ev([500, 999], [0, 100], [100, 50], [0, 1])
    pts = normalize_events(e, SIZE, 0, WIN)
    np.testing.assert_allclose(pts, [[50.0, 0.0, 100.0, 0.0], [99.9, 100.0, 50.0, 100.0]])
    # A 1-pixel-wide sensor maps x to 0 rather than dividing by zero.
    assert normalize_events(ev([0], [0], [0], [1]), (1, 1), 0, WIN)[0, 1] == 0.0


def test_single_shifted_event_in_space_and_time():
    gt = ev([100], [10], [10], [1])
    pred = ev([100], [13], [14], [1])  # 3 px right, 4 px down: distance 5
    assert chamfer_distance(gt, pred, SIZE, 0, WIN) == pytest.approx(5.0)
    assert gaussian_distance(gt, pred, SIZE, 0, WIN) == pytest.approx(1 - math.exp(-25 / SIGMA))
    late = ev([120], [10], [10], [1])  # 20 µs of a 1000 µs window = 2 units
    assert chamfer_distance(gt, late, SIZE, 0, WIN) == pytest.approx(2.0)
    assert gaussian_distance(gt, late, SIZE, 0, WIN) == pytest.approx(1 - math.exp(-4 / 0.4))


def test_polarity_flip_costs_100_and_cross_polarity_neighbours_are_found():
    gt = ev([100], [10], [10], [0])
    pred = ev([100], [10], [10], [1])
    assert chamfer_distance(gt, pred, SIZE, 0, WIN) == pytest.approx(100.0)
    assert gaussian_distance(gt, pred, SIZE, 0, WIN) == pytest.approx(1.0)
    # Same-polarity neighbour 141 away, opposite-polarity one 100 away: the nearer wins.
    gt2 = merge_events(ev([100], [10], [10], [0]), ev([100], [100], [100], [1]))
    assert chamfer_distance(gt2, pred, SIZE, 0, WIN) == pytest.approx(100.0)
    # Opposite polarity 30 px away beats nothing of the same polarity.
    gt3 = ev([100], [40], [10], [0])
    assert chamfer_distance(gt3, pred, SIZE, 0, WIN) == pytest.approx(math.hypot(100, 30))


def test_chamfer_is_one_sided():
    gt = ev([100], [10], [10], [1])
    pred = ev([100], [12], [10], [1])
    base = chamfer_distance(gt, pred, SIZE, 0, WIN)
    extra_gt = merge_events(gt, ev([900], [90], [90], [0]))  # flare removed correctly elsewhere
    assert chamfer_distance(extra_gt, pred, SIZE, 0, WIN) == pytest.approx(base)
    extra_pred = merge_events(pred, ev([900], [90], [90], [0]))  # an added noise event costs
    assert chamfer_distance(gt, extra_pred, SIZE, 0, WIN) > base


def test_metrics_do_not_depend_on_where_events_lie():
    gt = ev([100, 300], [10, 20], [10, 20], [1, 0])
    pred = ev([110, 300], [12, 20], [10, 21], [1, 0])
    shifted = [make_events(e["t"] + 400, e["x"] + 50, e["y"] + 30, e["p"]) for e in (gt, pred)]
    a = event_distances(gt, pred, SIZE, 0, WIN)
    b = event_distances(*shifted, SIZE, 0, WIN)
    assert a == pytest.approx(b)


def test_nearest_distances_match_brute_force(rng):
    size, start, win = (80, 60), 20_000, 20_000
    gt = random_events(rng, 700, size, t0=start, span_us=win)
    pred = random_events(rng, 500, size, t0=start, span_us=win)
    d = nearest_distances(gt, pred, size, start, win)
    a = normalize_events(pred, size, start, win)
    b = normalize_events(gt, size, start, win)
    brute = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)).min(axis=1)
    np.testing.assert_allclose(d, brute, rtol=1e-12)
    cd, gd = event_distances(gt, pred, size, start, win)
    assert cd == pytest.approx(brute.mean())
    assert gd == pytest.approx(np.mean(1 - np.exp(-(brute**2) / SIGMA)))


def test_empty_streams_have_defined_results():
    one = ev([100], [10], [10], [1])
    none = ev([], [], [], [])
    assert all(math.isnan(v) for v in event_distances(one, none, SIZE, 0, WIN))
    cd, gd = event_distances(none, one, SIZE, 0, WIN)
    assert math.isnan(cd) and gd == 1.0
    m = segment_metrics(none, none, (8, 8), 0, WIN)
    assert math.isnan(m.chamfer) and math.isnan(m.gaussian)
    assert (m.mse, m.pmse_2, m.pmse_4, m.r_f1, m.t_f1, m.tp_f1) == (0, 0, 0, 1, 1, 1)
    m = segment_metrics(one.copy()[:0], ev([5], [1], [1], [1]), (8, 8), 0, WIN)
    assert (m.r_f1, m.t_f1, m.tp_f1) == (0.0, 0.0, 0.0)


def test_mse_one_extra_event():
    gt = ev([], [], [], [])
    pred = ev([0], [1], [2], [0])
    m = segment_metrics(gt, pred, (4, 4), 0, 8000)
    assert m.mse == pytest.approx(1 / (8 * 4 * 4))
    # Pooling: one count spread over a 2x2 block is 1/4, over 4x4 it is 1/16.
    n_cells = 2 * 8 * 4 * 4
    assert m.pmse_2 == pytest.approx((1 / 4) ** 2 / (n_cells / 4))
    assert m.pmse_4 == pytest.approx((1 / 16) ** 2 / (n_cells / 16))


def test_pooling_forgives_moves_within_a_block():
    gt = ev([0], [0], [0], [1])
    pred = ev([0], [1], [1], [1])  # same 2x2 block, same bin
    m = segment_metrics(gt, pred, (4, 4), 0, 8000)
    assert m.pmse_2 == 0.0 and m.pmse_4 == 0.0
    assert m.mse == pytest.approx(2 / (8 * 16))
    assert m.r_f1 == 0.0 and m.t_f1 == 0.0 and m.tp_f1 == 0.0
    # Into the next 2x2 block: PMSE-2 sees it, PMSE-4 (one block) does not.
    far = ev([0], [2], [0], [1])
    m = segment_metrics(gt, far, (4, 4), 0, 8000)
    assert m.pmse_2 == pytest.approx(2 * (1 / 4) ** 2 / (2 * 8 * 4))
    assert m.pmse_4 == 0.0


def test_pmse_drops_remainder_rows_like_avg_pool2d():
    gt = np.zeros((2, 1, 3, 3))
    pred = gt.copy()
    pred[0, 0, 2, 2] = 5.0  # in the dropped last row/column for k=2
    assert pmse(gt, pred, 2) == 0.0
    pred[0, 0, 1, 1] = 4.0
    assert pmse(gt, pred, 2) == pytest.approx(1.0 / 2)  # (4/4)^2 over 2 pooled cells
    assert math.isnan(pmse(gt, pred, 4))  # sensor smaller than one block


def test_f1_variants_on_bins_and_polarity():
    gt = ev([0], [1], [1], [1])
    later = ev([7000], [1], [1], [1])  # same pixel and polarity, another bin
    flipped = ev([0], [1], [1], [0])  # same pixel and bin, other polarity
    m = segment_metrics(gt, later, (4, 4), 0, 8000)
    assert (m.r_f1, m.t_f1, m.tp_f1) == (0.0, 1.0, 1.0)
    m = segment_metrics(gt, flipped, (4, 4), 0, 8000)
    assert (m.r_f1, m.t_f1, m.tp_f1) == (0.0, 0.0, 1.0)


def test_f1_threshold_edge_and_counts():
    gt = np.zeros((2, 1, 1, 3))
    gt[0, 0, 0, :] = [1.0, 0.001, 0.0011]  # 0.001 is not above the threshold
    pred = np.zeros_like(gt)
    pred[0, 0, 0, :] = [1.0, 0.0011, 0.0]
    # active gt: cells 0 and 2; active pred: cells 0 and 1 -> TP 1, FP 1, FN 1
    assert f1_scores(gt, pred)[0] == pytest.approx(0.5)
    assert f1_score(np.zeros(3, bool), np.zeros(3, bool)) == 1.0
    with pytest.raises(EventsError, match="shape"):
        f1_score(np.zeros(3, bool), np.zeros(4, bool))


def test_decoded_signed_sum_cancels_in_tp_f1_not_in_polarity_grids():
    # An ON and an OFF event in one cell: the signed grid is 0, the polarity grids are not.
    both = ev([0, 1], [2, 2], [2, 2], [1, 0])
    pol = encode_polarity(both, (4, 4), 0, 8000)
    assert pol[0].sum() == 1 and pol[1].sum() == 1
    m = segment_metrics(both, ev([], [], [], []), (4, 4), 0, 8000)
    assert m.mse == 0.0  # signed sum is zero
    assert m.r_f1 == 0.0


def test_grids_with_nan_are_rejected():
    a = np.zeros((1, 2, 2))
    b = a.copy()
    b[0, 0, 0] = np.nan
    with pytest.raises(EventsError, match="NaN"):
        mse(a, b)


def test_segment_metrics_validate_window_and_sensor():
    with pytest.raises(EventsError, match="outside the window"):
        segment_metrics(ev([0], [0], [0], [1]), ev([25_000], [0], [0], [1]), (4, 4), 0, 20_000)
    with pytest.raises(EventsError, match="x out of range"):
        segment_metrics(ev([0], [9], [0], [1]), ev([0], [0], [0], [1]), (4, 4), 0, 20_000)


def test_metric_names_in_table_order():
    assert METRICS == ("chamfer", "gaussian", "mse", "pmse_2", "pmse_4", "r_f1", "t_f1", "tp_f1")


def test_keep_only_oracle_keeps_what_lies_near_the_ground_truth():
    rng = np.random.default_rng(3)
    n = 4000
    gt = make_events(
        np.sort(rng.integers(0, 60_000, n)),
        rng.integers(0, 64, n),
        rng.integers(0, 48, n),
        rng.integers(0, 2, n),
    )
    flare = make_events(
        np.sort(rng.integers(0, 60_000, 500)),
        np.full(500, 63),
        rng.integers(0, 48, 500),
        np.ones(500, int),
    )
    both = np.concatenate([gt, flare])
    order = np.argsort(both["t"], kind="stable")
    inp, is_flare = both[order], np.r_[np.zeros(n, bool), np.ones(500, bool)][order]
    keep = keep_only_oracle(inp, gt, (64, 48), max_distance=2.0)
    # the ground truth's own events are at distance 0: all kept
    assert keep[~is_flare].all()
    # what is kept is within 2 units of the ground truth, so its Chamfer is below 2,
    # and the dropped events are all farther
    kept, dropped = inp[keep], inp[~keep]
    for s in (0, 20_000, 40_000):
        w = (kept["t"] >= s) & (kept["t"] < s + 20_000)
        g = gt[(gt["t"] >= s) & (gt["t"] < s + 20_000)]
        assert chamfer_distance(g, kept[w], (64, 48), s, 20_000) < 2.0
        wd = (dropped["t"] >= s) & (dropped["t"] < s + 20_000)
        if wd.any():
            assert nearest_distances(g, dropped[wd], (64, 48), s, 20_000).min() >= 2.0
    assert 0 < (~keep).sum() <= 500


def test_keep_only_oracle_empty_and_window_alignment():
    gt = make_events([19_999], [5], [5], [1])
    inp = make_events([19_999, 20_000], [5, 5], [5, 5], [1, 1])  # same place, next window
    assert keep_only_oracle(inp, gt, (16, 16)).tolist() == [True, False]
    assert keep_only_oracle(inp, gt[:0], (16, 16)).tolist() == [False, False]
    assert keep_only_oracle(inp[:0], gt, (16, 16)).size == 0
    with pytest.raises(EventsError, match="window_us"):
        keep_only_oracle(inp, gt, (16, 16), window_us=0)
    with pytest.raises(EventsError, match="not sorted"):
        keep_only_oracle(inp[::-1].copy(), gt, (16, 16))
    with pytest.raises(EventsError, match="out of range"):
        keep_only_oracle(inp, gt, (4, 4))


def test_deletion_shares_by_hand():
    inp = make_events([0, 5, 5, 9, 12], [1, 2, 2, 3, 0], [0, 0, 0, 1, 1], [1, 1, 0, 0, 1])
    gt = inp[[0, 2, 4]]  # events 1 and 3 are flare
    out = inp[[0, 1, 4]]  # removes one of the two flare events, keeps two of three true
    removed, kept = deletion_shares(inp, gt, out, (4, 2))
    assert removed == 0.5 and kept == pytest.approx(2 / 3)
    assert deletion_shares(inp, gt, inp, (4, 2)) == (0.0, 1.0)  # the input itself
    assert deletion_shares(inp, gt, inp[:0], (4, 2)) == (1.0, 0.0)  # nothing left
    removed, kept = deletion_shares(inp, inp, inp[[0]], (4, 2))  # no flare at all
    assert math.isnan(removed) and kept == 0.2
    with pytest.raises(EventsError, match="sorted"):
        deletion_shares(inp, gt, out[::-1], (4, 2))
