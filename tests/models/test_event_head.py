"""The learned keep head: its features by hand, its numpy form, its card, its training."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import torch

from conftest import random_events, same_events, write_left_flare_pairs
from edeflare import deflare
from edeflare.errors import EdeflareError, ParameterError
from edeflare.events import make_events
from edeflare.io.dsec import write_dsec_groups
from edeflare.models import create_model
from edeflare.models.event_features import (
    FEATURES,
    LIGHT_FREE_FEATURES,
    NO_LIGHT_RADII,
    RELATIVE_FEATURES,
    relative_features,
    window_features,
)
from edeflare.models.event_head import EventHead, head_logits
from edeflare.models.head_training import (
    LN3,
    HeadTrainingConfig,
    choose_threshold,
    context_at,
    keep_labels,
    teacher_targets,
    train_head,
)
from edeflare.models.infer import ModelDeflarer
from edeflare.models.weights import ModelCard, WeightsError, load_model, read_card, save_model
from edeflare.rules.context import WindowContext

NAMES = list(FEATURES)


def column(table: np.ndarray, name: str) -> list[float]:
    return [round(float(v), 5) for v in table[:, NAMES.index(name)]]


# ----------------------------------------------------------------------------- features


def test_features_of_a_small_window_by_hand():
    # three events at pixel (1, 1) (ON, OFF, ON at 0, 2, 5 ms), one at (9, 6) (ON at 7 ms)
    ev = make_events([0, 2_000, 5_000, 7_000], [1, 1, 1, 9], [1, 1, 1, 6], [1, 0, 1, 1])
    ctx = WindowContext(ev, (16, 8), 20_000)
    t = window_features(ctx, np.array([0.5, -1.0, 2.0, 0.0], np.float32))
    assert column(t, "net_logit") == [0.5, -1.0, 2.0, 0.0]
    assert column(t, "polarity") == [1.0, 0.0, 1.0, 1.0]
    assert column(t, "light_free") == [1.0] * 4
    assert column(t, "light_distance") == [round(math.log1p(NO_LIGHT_RADII), 5)] * 4
    assert column(t, "support") == [round(math.log1p(2), 5)] * 3 + [0.0]  # two others at (1, 1)
    assert column(t, "rate_pixel") == [round(math.log1p(3), 5)] * 3 + [round(math.log1p(1), 5)]
    assert column(t, "balance_pixel") == [round(1 / 3, 5)] * 3 + [1.0]
    # cells of 8x8: (1, 1) in cell (0, 0) with 3 events, (9, 6) in cell (0, 1) with 1
    assert column(t, "rate_8") == [round(math.log1p(3 / 64), 5)] * 3 + [
        round(math.log1p(1 / 64), 5)
    ]
    # 32x32 squares cover the whole 16x8 sensor: 4 events over 128 pixels, balance 2/4
    assert column(t, "rate_32") == [round(math.log1p(4 / 128), 5)] * 4
    assert column(t, "balance_32") == [0.5] * 4
    assert column(t, "rate_window") == [round(math.log1p(4 / 128), 5)] * 4
    # ms since the pixel's previous event; the window (20 ms) for a pixel's first
    assert column(t, "since_pixel") == [round(math.log1p(v), 5) for v in (20, 2, 3, 20)]
    half = 0.5 * math.hypot(16, 8)
    assert column(t, "centre_distance")[3] == round(math.hypot(9.5 - 8, 6.5 - 4) / half, 5)
    # the same polarity: (1, 1)'s second ON comes 5 ms after its first; its OFF is a first
    assert column(t, "since_same") == [round(math.log1p(v), 5) for v in (20, 20, 5, 20)]
    # one 64x64 block, bins of 1 ms from the first event (0..7: 8 bins); ON: one event in
    # bins 0, 5 and 7 (mean 3 / 8), OFF: one in bin 2 (mean 1 / 8)
    on, off = math.log(2 / (1 + 3 / 8)), math.log(2 / (1 + 1 / 8))
    assert column(t, "sync_64") == [round(v, 5) for v in (on, off, on, on)]


def test_rate_relative_features_of_a_small_window_by_hand():
    # the window of the test above: (1, 1) fires 3 events in cell (0, 0); (9, 6) one in (0, 1)
    ev = make_events([0, 2_000, 5_000, 7_000], [1, 1, 1, 9], [1, 1, 1, 6], [1, 0, 1, 1])
    t = window_features(WindowContext(ev, (16, 8), 20_000), np.zeros(4, np.float32))
    # the pixel's events over its cell's events per pixel: 3 / (3 / 64) and 1 / (1 / 64)
    assert column(t, "rel_pixel") == [round(math.log(64), 5)] * 4
    # the cell's rate over the window's 4 / 128 a pixel
    assert column(t, "rel_8") == [round(math.log(3 / 64 * 32), 5)] * 3 + [round(math.log(0.5), 5)]
    assert column(t, "rel_32") == [0.0] * 4  # the 32x32 square is the whole sensor
    # (1 + others in its 5x5) over 25 pixels' share of its cell: 3 / (75 / 64), 1 / (25 / 64)
    assert column(t, "rel_support") == [round(math.log(3 * 64 / 75), 5)] * 3 + [
        round(math.log(64 / 25), 5)
    ]
    # the gap (20 ms for a first, then 2 and 3 ms) x the pixel's events over the window's 20 ms
    gaps = [20 * 3, 2 * 3, 3 * 3, 20 * 1]
    assert column(t, "rel_since") == [round(math.log1p(g / 20), 5) for g in gaps]


def test_rate_relative_features_stay_when_a_window_is_thinned_at_random(rng):
    # a dense lamp-like block over a sparse background: at half the events every absolute
    # rate falls by log(2); the relative features keep their means
    lamp = random_events(rng, 40_000, (32, 32), t0=0, span_us=20_000)
    back = random_events(rng, 8_000, (256, 128), t0=0, span_us=20_000)
    lamp["x"] += 100
    lamp["y"] += 40
    ev = np.concatenate([lamp, back])
    ev = ev[np.argsort(ev["t"], kind="stable")]
    half = ev[rng.random(ev.size) < 0.5]
    names = ["rate_8", "rate_128", "rel_pixel", "rel_8", "rel_32", "rel_128", "rel_support"]

    def means(e: np.ndarray) -> np.ndarray:
        table = window_features(WindowContext(e, (256, 128), 20_000), np.zeros(e.size), names)
        in_lamp = (e["x"] >= 100) & (e["x"] < 132) & (e["y"] >= 40) & (e["y"] < 72)
        return table[in_lamp].mean(0)

    whole, thinned = means(ev), means(half)
    # the lamp's cells fire 40000 / 1024 ~ 39 a pixel: the absolute rate halves
    assert whole[0] - thinned[0] == pytest.approx(math.log(2), abs=0.05)
    assert whole[1] - thinned[1] > 0.3
    np.testing.assert_allclose(thinned[2:], whole[2:], atol=0.05)


def test_rate_relative_features_follow_from_the_stored_absolute_columns(rng):
    # rows drawn with the absolute features (float32, as a run's cache holds them) give the
    # relative ones as the window computes them
    ev = random_events(rng, 5000, (64, 48), t0=0, span_us=20_000)
    ctx = WindowContext(ev, (64, 48), 20_000)
    table = window_features(ctx, np.zeros(ev.size, np.float32))
    stored = {n: table[:, k] for k, n in enumerate(NAMES)}
    derived = relative_features(stored, list(RELATIVE_FEATURES))
    for name, values in derived.items():
        np.testing.assert_allclose(values, table[:, NAMES.index(name)], rtol=1e-4, atol=1e-5)
    with pytest.raises(ParameterError, match="'rate_8' is not a rate-relative feature"):
        relative_features(stored, ["rate_8"])


def test_light_free_features_are_the_absolute_ones_without_a_light_and_zero_with_one():
    # a 16x16 block at 1 event per pixel and ms is a light (window_lights' example); the
    # same events a tenth as fast are not, and there each free_* is its absolute feature
    yy, xx = np.mgrid[16:32, 40:56]
    names = [*LIGHT_FREE_FEATURES, *LIGHT_FREE_FEATURES.values(), "light_free"]

    def table(per_pixel: int) -> np.ndarray:
        n = per_pixel * xx.size
        ev = make_events(np.arange(n) * 20_000 // n, np.tile(xx.ravel(), per_pixel),
                         np.tile(yy.ravel(), per_pixel), np.ones(n))  # fmt: skip
        return window_features(WindowContext(ev, (96, 64), 20_000), np.zeros(n), names)

    k = len(LIGHT_FREE_FEATURES)
    lit, dim = table(20), table(2)
    assert lit[:, -1].max() == 0.0 and dim[:, -1].min() == 1.0
    assert not lit[:, :k].any()
    assert lit[:, k : 2 * k].min() > 0.0  # the absolute rates themselves are there
    np.testing.assert_array_equal(dim[:, :k], dim[:, k : 2 * k])
    assert dim[0, list(LIGHT_FREE_FEATURES).index("free_rate_pixel")] == pytest.approx(
        math.log1p(2)
    )
    assert set(LIGHT_FREE_FEATURES.values()) <= set(FEATURES)


def test_a_flickers_bursts_stand_out_in_sync_and_steady_events_do_not():
    # a block firing ON in the first 1 ms of every 10 ms (a 100 Hz flicker's rise) and a
    # block firing one ON event every ms (steady motion): 20 events each in 20 ms
    burst_t = np.repeat([0, 10_000], 10) + np.tile(np.arange(10) * 50, 2)
    steady_t = np.arange(20) * 1_000
    t = np.concatenate([burst_t, steady_t])
    x = np.concatenate([np.full(20, 5), np.full(20, 100)])
    order = np.argsort(t, kind="stable")
    ev = make_events(t[order], x[order], np.full(40, 5)[order], np.ones(40, int))
    table = window_features(WindowContext(ev, (128, 16), 20_000), np.zeros(40, np.float32))
    sync = np.array(column(table, "sync_64"))
    bins = (19_000 // 1_000) + 1  # from the first event to the last, 20 bins
    burst, steady = x[order] == 5, x[order] == 100
    assert sync[burst] == pytest.approx(math.log(11 / (1 + 20 / bins)), abs=1e-5)
    assert sync[steady] == pytest.approx(math.log(2 / (1 + 20 / bins)), abs=1e-5)


def test_rates_of_a_partly_covered_window_are_scaled_to_a_whole_one():
    ev = make_events([0, 1_000], [1, 1], [1, 1], [1, 1])
    whole = window_features(WindowContext(ev, (8, 8), 20_000), np.zeros(2, np.float32))
    quarter = window_features(WindowContext(ev, (8, 8), 5_000), np.zeros(2, np.float32))
    assert column(whole, "rate_pixel") == [round(math.log1p(2), 5)] * 2
    assert column(quarter, "rate_pixel") == [round(math.log1p(8), 5)] * 2


def test_distance_to_a_light_is_counted_in_its_radii():
    yy, xx = np.mgrid[16:32, 40:56]  # a 16x16 block firing 1 event per pixel and ms
    n = 20 * xx.size
    lamp = make_events(
        np.arange(n) * 20_000 // n, np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20), np.ones(n)
    )
    probe = make_events([19_999], [47 + 40], [23], [1])  # 40 px right of the centre (47.5, 23.5)
    ev = np.concatenate([lamp, probe])
    ctx = WindowContext(ev, (128, 64), 20_000)
    assert ctx.has_lights
    t = window_features(ctx, np.zeros(ev.size, np.float32), ["light_free", "light_distance"])
    assert t[0, 0] == 0.0
    assert np.expm1(t[-1, 1]) == pytest.approx(math.hypot(39.5, 0.5) / 8.0, rel=1e-4)  # radius 8


def test_a_feature_subset_is_the_full_tables_columns(rng):
    ev = random_events(rng, 3000, (64, 48), t0=0, span_us=20_000)
    logit = rng.normal(size=ev.size).astype(np.float32)
    full = window_features(WindowContext(ev, (64, 48), 20_000), logit)
    some = ["since_pixel", "net_logit", "crowded", "rate_128"]
    part = window_features(WindowContext(ev, (64, 48), 20_000), logit, some)
    np.testing.assert_array_equal(part, full[:, [NAMES.index(n) for n in some]])


# ----------------------------------------------------------------------------- the head


def test_numpy_head_equals_the_torch_head_with_its_standardisation():
    torch.manual_seed(0)
    head = EventHead(["net_logit", "support", "halo"], hidden=(8, 4))
    x = torch.randn(50, 3) * torch.tensor([3.0, 0.5, 1.0]) + torch.tensor([1.0, 2.0, 0.0])
    head.standardise_on(x)
    for layer in head.layers:  # random, not the initial, weights
        torch.nn.init.normal_(layer.weight)
        torch.nn.init.normal_(layer.bias)
    with torch.no_grad():
        want = head(x).numpy()
    np.testing.assert_allclose(
        head_logits(head.numpy_params(), x.numpy()), want, rtol=1e-5, atol=1e-5
    )


def test_numpy_head_in_blocks_equals_one_block(monkeypatch, rng):
    import edeflare.models.event_head as event_head

    head = EventHead(["net_logit", "support", "halo"], hidden=(8, 4))
    params = head.numpy_params()
    x = rng.normal(size=(1_000, 3)).astype(np.float32)
    whole = head_logits(params, x)
    monkeypatch.setattr(event_head, "HEAD_BLOCK", 64)  # 16 blocks, the last one short
    np.testing.assert_allclose(head_logits(params, x), whole, rtol=1e-6, atol=1e-6)
    assert head_logits(params, x[:0]).shape == (0,)


def passthrough_head() -> EventHead:
    """A head whose logit is the network's (a logistic layer of weight 1 on net_logit)."""
    head = EventHead(["net_logit", "polarity"], hidden=())
    with torch.no_grad():
        head.layers[0].weight.copy_(torch.tensor([[1.0, 0.0]]))
        head.layers[0].bias.zero_()
    return head


def save_with_head(path, head, threshold=0.5, preset="mask.lite", seed=0):
    torch.manual_seed(seed)
    net = create_model(preset)
    for p in net.parameters():  # not the identity: the network drops some events
        torch.nn.init.normal_(p, std=0.3)
    base = path.with_name("base.safetensors")
    save_model(base, net, ModelCard(preset=preset, keep_threshold=threshold))
    net.head = head
    card = ModelCard(preset=preset, keep_threshold=threshold, head=head.spec())
    save_model(path, net, card)
    return base


def test_a_passthrough_head_decides_as_the_network_alone(tmp_path, rng):
    base = save_with_head(tmp_path / "head.safetensors", passthrough_head())
    ev = random_events(rng, 20_000, (64, 48), t0=0, span_us=100_000)
    without = deflare(ev, (64, 48), "model", weights=base)
    with_head = deflare(ev, (64, 48), "model", weights=tmp_path / "head.safetensors")
    assert 0 < without.size < ev.size  # the network drops some, keeps some
    assert same_events(with_head, without)


def test_a_head_that_drops_everything_drops_everything(tmp_path, rng):
    head = passthrough_head()
    with torch.no_grad():
        head.layers[0].bias.fill_(-100.0)
    save_with_head(tmp_path / "h.safetensors", head)
    ev = random_events(rng, 5_000, (64, 48), t0=0, span_us=40_000)
    assert deflare(ev, (64, 48), "model", weights=tmp_path / "h.safetensors").size == 0


def test_the_head_rides_in_the_card_and_the_weights_file(tmp_path):
    save_with_head(tmp_path / "h.safetensors", passthrough_head())
    card = read_card(tmp_path / "h.safetensors")
    assert card.head == {"features": ["net_logit", "polarity"], "hidden": []}
    model, _ = load_model(tmp_path / "h.safetensors")
    assert isinstance(model.head, EventHead) and model.head.feature_names == (
        "net_logit",
        "polarity",
    )
    assert "head" not in ModelCard(preset="mask.lite").to_dict()  # cards without one unchanged


def test_a_card_naming_an_unknown_feature_fails_to_load_naming_it():
    with pytest.raises(WeightsError, match="unknown feature 'moon_phase'"):
        ModelCard.from_dict({"preset": "mask.lite", "head": {"features": ["moon_phase"]}})
    with pytest.raises(WeightsError, match=r"unknown keys \['hiden'\]"):
        ModelCard.from_dict(
            {"preset": "mask.lite", "head": {"features": ["net_logit"], "hiden": [3]}}
        )


def test_a_head_on_a_voxel_model_is_refused(tmp_path):
    net = create_model("unet2d.tiny")
    net.head = passthrough_head()
    save_model(
        tmp_path / "v.safetensors", net, ModelCard(preset="unet2d.tiny", head=net.head.spec())
    )
    with pytest.raises(Exception, match="keep head needs a mask model"):
        ModelDeflarer(tmp_path / "v.safetensors")


@pytest.mark.parametrize("size", [(64, 64), (16, 12), (1, 1)])
def test_sensors_smaller_than_the_context_are_de_flared(tmp_path, rng, size):
    save_with_head(tmp_path / "h.safetensors", passthrough_head())
    ev = random_events(rng, 3_000, size, t0=0, span_us=60_000)
    out = deflare(ev, size, "model", weights=tmp_path / "h.safetensors")
    assert out.size <= ev.size and np.isin(out["t"], ev["t"]).all()


def test_onnx_export_carries_the_head_and_decides_alike(tmp_path, rng):
    pytest.importorskip("onnxruntime")

    # a hidden layer of two units: logit 4 (log(1 + support) - 3.1), about half kept here
    head = EventHead(["net_logit", "support", "rate_8", "since_pixel"], hidden=(2,))
    with torch.no_grad():
        head.layers[0].weight.copy_(torch.tensor([[0.0, 1, 0, 0], [0.0, -1, 0, 0]]))
        head.layers[0].bias.copy_(torch.tensor([-3.1, 3.1]))
        head.layers[1].weight.copy_(torch.tensor([[4.0, -4.0]]))
        head.layers[1].bias.zero_()
    assert_onnx_decides_alike(tmp_path, rng, head, kept_share=(0.2, 0.8))


def assert_onnx_decides_alike(tmp_path, rng, head, kept_share):
    """The head over a random mask.lite, exported: within 0.1 % of the torch decisions, and
    keeping a share of the events within ``kept_share``."""
    from edeflare.models.export import export_onnx, onnx_parity

    save_with_head(tmp_path / "h.safetensors", head)
    export_onnx(tmp_path / "h.safetensors", tmp_path / "h.onnx", (64, 48))
    ev = random_events(rng, 8_000, (64, 48), t0=0, span_us=60_000)
    windows = [(s, ev[(ev["t"] >= s) & (ev["t"] < s + 20_000)]) for s in (0, 20_000, 40_000)]
    result = onnx_parity(tmp_path / "h.safetensors", tmp_path / "h.onnx", windows, (64, 48))
    assert result.decisions == ev.size and result.decisions_differing <= ev.size // 1000
    a = deflare(ev, (64, 48), "model", weights=tmp_path / "h.safetensors", runtime="torch")
    b = deflare(ev, (64, 48), "model", weights=tmp_path / "h.onnx")
    assert abs(a.size - b.size) <= ev.size // 1000
    assert kept_share[0] * ev.size < a.size < kept_share[1] * ev.size


# ----------------------------------------------------------------------------- training


def test_labels_match_one_to_one_within_the_tolerance():
    inp = make_events([0, 100, 200, 5_000], [2, 2, 2, 2], [3, 3, 3, 3], [1, 1, 1, 1])
    gt = make_events([150, 4_500], [2, 2], [3, 3], [1, 1])
    # 150 takes the first input within 1 ms of it (0); 100 and 200 find it taken
    assert keep_labels(inp, gt, 1_000).tolist() == [True, False, False, True]
    other_polarity = make_events([0], [2], [3], [0])
    assert keep_labels(inp, other_polarity, 1_000).tolist() == [False] * 4
    assert keep_labels(inp, inp[[1, 3]], 0).tolist() == [False, True, False, True]  # a subset


def test_labels_of_time_sorted_streams_match_those_of_any_order(rng):
    # time-sorted streams are grouped by a counting sort, others sorted by pixel and time:
    # one matching either way (distinct times, so no tie decides it)
    n, m = 6_000, 4_000
    t_in = np.sort(rng.choice(10**6, n, replace=False))
    inp = make_events(t_in, rng.integers(0, 9, n), rng.integers(0, 7, n), rng.integers(0, 2, n))
    t_gt = np.sort(rng.choice(10**6, m, replace=False) + 0.5).astype(np.int64)
    gt = make_events(t_gt, rng.integers(0, 9, m), rng.integers(0, 7, m), rng.integers(0, 2, m))
    sorted_labels = keep_labels(inp, gt, 20_000)
    shuffle_in, shuffle_gt = rng.permutation(n), rng.permutation(m)
    any_order = keep_labels(inp[shuffle_in], gt[shuffle_gt], 20_000)
    assert any_order.tolist() == sorted_labels[shuffle_in].tolist()
    assert 0.3 < sorted_labels.mean() < 0.9  # both answers occur
    assert keep_labels(inp, gt[:0]).tolist() == [False] * n and keep_labels(inp[:0], gt).size == 0


def test_the_threshold_maximises_the_mean_of_both_datasets_scores():
    # dataset a: keep-probability 0.9 scene, 0.2 flare; b: 0.6 scene, 0.45 flare
    p = np.array([0.9, 0.2, 0.6, 0.45])
    logits = np.log(p / (1 - p)) - math.log(3)
    y = np.array([True, False, True, False])
    groups = np.array(["a", "a", "b", "b"])
    threshold, table = choose_threshold(logits, y, groups)
    assert threshold == 0.45  # 0.45 < t < 0.6 separates both; the lowest such candidate
    assert max(r["score"] for r in table) == 1.0


def _two_parts_and_a_base(tmp_path, rng):
    """Two datasets of :func:`_pairs` (two training files each) and an untrained mask.lite."""
    parts = [tmp_path / "mix" / "a", tmp_path / "mix" / "b"]
    for part in parts:
        write_left_flare_pairs(part, rng, 2)
    base = tmp_path / "base.safetensors"
    save_model(base, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    return parts, base


def test_train_head_learns_where_the_flare_is_and_resumes_from_its_features(tmp_path, rng):
    parts, base = _two_parts_and_a_base(tmp_path, rng)
    config = HeadTrainingConfig(
        features=("net_logit", "rate_8", "rate_32", "polarity"),
        hidden=(8,),
        epochs=20,
        batch_size=256,
        per_window=500,
    )
    summary = train_head(parts, base, tmp_path / "run", config, progress=False)
    assert summary["chosen_on"] == "the datasets' test splits: a, b"
    cached = sorted(p.name for p in (tmp_path / "run").glob("features-*.npz"))
    assert len(cached) == 2
    card = read_card(tmp_path / "run" / "model.safetensors")
    assert card.head["features"] == list(config.features) and card.rules == {}
    assert card.keep_threshold == summary["keep_threshold"]
    assert json.loads((tmp_path / "run" / "head.json").read_text())["keep_threshold"] == (
        card.keep_threshold
    )
    write_left_flare_pairs(tmp_path / "new", rng, 0)  # a fresh pair: flare left, scene right
    from edeflare.io.sequence import read_sequence

    inp, gt, size, *_ = read_sequence(tmp_path / "new" / "test" / "s0.h5")
    out = deflare(inp, size, "model", weights=tmp_path / "run" / "model.safetensors")
    left = out["x"] < size[0] // 2
    assert left.sum() < 0.1 * (inp["x"] < size[0] // 2).sum()  # flare removed
    assert (~left).sum() > 0.9 * gt.size  # scene kept
    # a rerun reads the cached features (same names), and fits the same head
    again = train_head(parts, base, tmp_path / "run", config, progress=False)
    assert again["keep_threshold"] == summary["keep_threshold"]
    assert sorted(p.name for p in (tmp_path / "run").glob("features-*.npz")) == cached
    # a head of another size and schedule reuses them too; other features do not
    wider = dataclasses.replace(config, hidden=(16, 4), epochs=3, lr=1e-3)
    train_head(parts, base, tmp_path / "run", wider, progress=False)
    assert sorted(p.name for p in (tmp_path / "run").glob("features-*.npz")) == cached
    assert read_card(tmp_path / "run" / "model.safetensors").head["hidden"] == [16, 4]
    fewer = dataclasses.replace(config, features=("net_logit", "rate_8"))
    train_head(parts, base, tmp_path / "run", fewer, progress=False)
    assert len(list((tmp_path / "run").glob("features-*.npz"))) == 4


@pytest.mark.slow  # two processes started: about 10 s
def test_rows_drawn_by_worker_processes_are_the_rows_one_process_draws(tmp_path, rng):
    import pickle

    from edeflare.models.head_training import NetworkLogits, collect_features

    parts, base = _two_parts_and_a_base(tmp_path, rng)
    model = create_model("mask.lite")  # untrained, its logits all 0: perturbed
    torch.manual_seed(0)
    with torch.no_grad():
        for param in model.parameters():
            param.add_(0.1 * torch.randn_like(param))
    save_model(base, model, ModelCard(preset="mask.lite"))
    files = [f for part in parts for f in sorted((part / "train").glob("*.h5"))]
    # thinned windows and a context: every draw of the generator and the cells too
    config = HeadTrainingConfig(
        features=("net_logit", "rate_8", "support", "since_pixel"),
        per_window=200,
        thin=0.3,
        context=4,
    )
    logits = NetworkLogits(base)
    assert pickle.loads(pickle.dumps(logits)).weights == base  # its path, not the network
    one = collect_features(files, logits, 20_000, config, balanced=True, progress=False)
    two = collect_features(files, logits, 20_000, config, balanced=True, progress=False, workers=2)
    assert sorted(one) == sorted(two) and np.unique(one["source"]).tolist() == [0, 1, 2, 3]
    assert one["x"][:, 0].std() > 0  # the network ran: its logits differ between events
    assert sum(k.startswith("cells_") for k in one) == one["sizes"].shape[0] > len(files)
    for key in one:
        np.testing.assert_array_equal(one[key], two[key], err_msg=key)
    with pytest.raises(ParameterError, match="workers must be a positive integer, got 0"):
        collect_features(files, logits, 20_000, config, balanced=True, workers=0)


def test_the_scene_alone_is_learned_from_with_every_event_kept(tmp_path, rng):
    from edeflare.models.head_training import collect_features

    scene = random_events(rng, 400, (32, 24), t0=0, span_us=40_000)
    flare = random_events(rng, 300, (32, 24), t0=0, span_us=40_000)
    inp = np.sort(np.concatenate([scene, flare]), order="t", kind="stable")
    path = tmp_path / "p.h5"
    write_dsec_groups(path, {"input": inp, "gt": scene, "background": scene}, (32, 24))

    def logits(batch, size):
        return [np.zeros(ev.size, np.float32) for _, ev in batch]

    config = HeadTrainingConfig(features=("polarity",), val_per_window=10_000)
    got = collect_features([path], logits, 20_000, config, balanced=False, progress=False)
    pair, alone = got["source"] == 0, got["source"] == -1
    assert pair.sum() == inp.size and alone.sum() == scene.size
    assert got["y"][alone].all() and got["y"][pair].sum() == scene.size
    off = dataclasses.replace(config, light_free_windows=False)
    got = collect_features([path], logits, 20_000, off, balanced=False, progress=False)
    assert (got["source"] == 0).all()


def test_the_flare_free_recording_is_learned_from_with_every_event_kept(tmp_path, rng):
    from edeflare.models.head_training import FLARE_FREE_SOURCE, _group, collect_features

    scene = random_events(rng, 400, (32, 24), t0=0, span_us=40_000)
    flare = random_events(rng, 300, (32, 24), t0=0, span_us=40_000)
    inp = np.sort(np.concatenate([scene, flare]), order="t", kind="stable")
    paths = [tmp_path / "a" / "test" / "p0.h5", tmp_path / "a" / "test" / "p1.h5"]
    for path in paths:  # no background stream: the ground truth is the clean twin
        write_dsec_groups(path, {"input": inp, "gt": scene}, (32, 24))

    def logits(batch, size):
        return [np.zeros(ev.size, np.float32) for _, ev in batch]

    config = HeadTrainingConfig(features=("polarity",), val_per_window=10_000)
    on = dataclasses.replace(config, flare_free_windows=True)
    got = collect_features(paths, logits, 20_000, on, balanced=False, progress=False)
    for k in (0, 1):
        pair, twin = got["source"] == k, got["source"] == FLARE_FREE_SOURCE - k
        assert pair.sum() == inp.size and twin.sum() == scene.size
        assert got["y"][twin].all() and got["y"][pair].sum() == scene.size
    files = [str(p) for p in paths]
    assert [_group(files, s) for s in (1, -1, -2, FLARE_FREE_SOURCE - 1)] == [
        "a", "scene without a light", "scene without a light", "flare-free recording"
    ]  # fmt: skip
    got = collect_features(paths, logits, 20_000, config, balanced=False, progress=False)
    assert set(got["source"].tolist()) == {0, 1}  # off by default


def test_rate_augmentation_thins_training_windows_only_and_keeps_labels(tmp_path, rng):
    from edeflare.models.head_training import collect_features

    scene = random_events(rng, 4_000, (32, 24), t0=0, span_us=400_000)
    flare = random_events(rng, 4_000, (32, 24), t0=0, span_us=400_000)
    inp = np.sort(np.concatenate([scene, flare]), order="t", kind="stable")
    path = tmp_path / "p.h5"
    write_dsec_groups(path, {"input": inp, "gt": scene}, (32, 24))
    seen = []

    def logits(batch, size):  # records how many events each window's network sees
        seen.extend(ev.size for _, ev in batch)
        return [np.zeros(ev.size, np.float32) for _, ev in batch]

    # every event of both classes drawn (per_window above a window's count)
    config = HeadTrainingConfig(features=("polarity",), per_window=10_000, val_per_window=10_000)
    full = collect_features([path], logits, 20_000, config, balanced=True, progress=False)
    assert full["x"].shape[0] == inp.size and sum(seen) == inp.size
    counts, seen = np.array(seen), []
    thin = dataclasses.replace(config, thin=0.1)
    got = collect_features([path], logits, 20_000, thin, balanced=True, progress=False)
    windows = np.array(seen)
    assert windows.size == counts.size == 20 and got["x"].shape[0] == windows.sum()
    # a random half of the windows thinned, to between a tenth and all of their events
    whole = windows == counts
    assert 4 <= whole.sum() <= 16 and (windows[~whole] >= 0.05 * counts[~whole]).all()
    assert got["x"].shape[0] < 0.9 * inp.size
    # the labels stay each drawn event's own: a thinned scene event is still scene
    assert 0.4 < got["y"].mean() < 0.6
    seen.clear()  # the validation rows (balanced=False) are never thinned
    val = collect_features([path], logits, 20_000, thin, balanced=False, progress=False)
    assert val["x"].shape[0] == inp.size and sum(seen) == inp.size
    with pytest.raises(ParameterError, match="thin must be in"):
        HeadTrainingConfig(thin=0.0)
    # the caches' names: thinned training rows are other rows, the test rows the same
    from edeflare.models.head_training import _identity

    names = {k: [_identity([path], path, c, k) for c in (config, thin)] for k in ("train", "test")}
    assert names["train"][0] != names["train"][1] and names["test"][0] == names["test"][1]


def test_the_lights_own_events_are_flagged_at_collection(tmp_path, rng):
    from edeflare.models.head_training import collect_features

    scene = random_events(rng, 400, (32, 24), t0=0, span_us=40_000)
    flare = random_events(rng, 300, (32, 24), t0=0, span_us=40_000)
    light = make_events(np.arange(50) * 800, np.full(50, 31), np.full(50, 23), np.ones(50))
    inp = np.sort(np.concatenate([scene, flare, light]), order="t", kind="stable")
    path = tmp_path / "p.h5"
    groups = {"input": inp, "gt": scene, "light": light, "background": scene}
    write_dsec_groups(path, groups, (32, 24))

    def logits(batch, size):
        return [np.zeros(ev.size, np.float32) for _, ev in batch]

    config = HeadTrainingConfig(features=("polarity",), val_per_window=10_000)
    got = collect_features([path], logits, 20_000, config, balanced=False, progress=False)
    pair = got["source"] == 0
    # the light's 50 events (its own pixel, none of the scene's or flare's there) are
    # flagged and kept; the scene alone's rows never are
    corner = keep_labels(inp, light, config.tolerance_us).sum()
    assert got["light"].sum() == corner == 50
    assert got["y"][got["light"]].all() and not got["light"][~pair].any()
    assert got["y"][pair].sum() == scene.size + 50


def test_loss_weights_raise_the_lights_and_the_lone_scenes_rows_only():
    from edeflare.models.head_training import FLARE_FREE_SOURCE, loss_weights

    y = np.array([False, True, True, True, True])
    source = np.array([0, 0, 0, -1, FLARE_FREE_SOURCE])
    light = np.array([False, True, False, False, False])
    plain = loss_weights(y, HeadTrainingConfig()).tolist()
    assert plain == pytest.approx([2.5, 0.625, 0.625, 0.625, 0.625])  # 0.5 / 0.2, 0.5 / 0.8
    both = HeadTrainingConfig(light_weight=3.0, scene_weight=2.0)
    got = loss_weights(y, both, light=light, source=source).tolist()
    assert got == pytest.approx([2.5, 1.875, 0.625, 1.25, 0.625])  # flare-free twin: x1
    with pytest.raises(EdeflareError, match="light_weight needs the rows' light flags"):
        loss_weights(y, both, source=source)
    with pytest.raises(EdeflareError, match="light_weight must be a positive number"):
        HeadTrainingConfig(light_weight=-1.0)


def test_a_heavier_light_raises_the_keep_probability_of_what_features_cannot_tell(rng):
    from edeflare.models.head_training import _keep_probability, fit_head

    # one feature that says nothing: the best constant keep probability is the weighed
    # share of kept rows; half the kept rows are the light's
    n = 4_000
    x = rng.normal(size=(n, 1))
    y = np.arange(n) % 2 == 0
    light = y & (np.arange(n) % 4 == 0)
    config = HeadTrainingConfig(features=("polarity",), hidden=(4,), epochs=40, batch_size=500)
    means = []
    for weight in (1.0, 3.0):  # keep weight 0.5 -> 0.25 * 3 + 0.25 = 1.0 against flare 0.5
        cfg = dataclasses.replace(config, light_weight=weight)
        head = fit_head(x, y, cfg, light=light, source=np.zeros(n, int), progress=False)
        logits = head_logits(head.numpy_params(), x.astype(np.float32))
        means.append(float(_keep_probability(logits).mean()))
    assert means[0] == pytest.approx(0.5, abs=0.04)
    assert means[1] == pytest.approx(2 / 3, abs=0.04)


def test_a_model_with_a_head_is_bundled_with_its_tensors_unchanged(tmp_path):
    from edeflare.models.bundle import bundle_weights
    from edeflare.models.weights import read_tensors

    save_with_head(tmp_path / "h.safetensors", passthrough_head())
    card = bundle_weights(tmp_path / "h.safetensors", tmp_path / "b.safetensors", {"data": "x"})
    assert card["head"] == {"features": ["net_logit", "polarity"], "hidden": []}
    a, b = read_tensors(tmp_path / "h.safetensors"), read_tensors(tmp_path / "b.safetensors")
    assert sorted(a) == sorted(b) and all(torch.equal(a[k], b[k]) for k in a)
    assert "head.layers.0.weight" in b


def test_time_since_the_pixels_last_event_equals_a_sort_by_pixel(rng):
    from edeflare.models.event_features import _since_pixel

    ev = random_events(rng, 50_000, (64, 48), t0=0, span_us=20_000)
    pixel = ev["y"].astype(np.int64) * 64 + ev["x"]
    order = np.argsort(pixel, kind="stable")  # time order within each pixel
    p, t = pixel[order], ev["t"].astype(np.int64)[order]
    gap = np.full(ev.size, 20_000, np.int64)
    same = p[1:] == p[:-1]
    gap[1:][same] = (t[1:] - t[:-1])[same]
    want = np.empty(ev.size, np.int64)
    want[order] = gap
    np.testing.assert_array_equal(_since_pixel(ev, 64, 48, 20_000), want)
    np.testing.assert_array_equal(_since_pixel(ev, 64, 48, 20_000), want)  # frame left reset


# ----------------------------------------------------------------------------- context


def test_a_context_head_learns_what_its_features_cannot_tell(tmp_path, rng):
    # polarity alone cannot tell the left half's flare from the right half's scene: the
    # plain head keeps both or neither, the context (a map of the whole window) learns it
    parts, base = _two_parts_and_a_base(tmp_path, rng)
    plain = HeadTrainingConfig(features=("polarity",), hidden=(8,), epochs=20, per_window=500)
    with_context = dataclasses.replace(
        plain, context=2, context_widths=(4, 8), batch_windows=2, epochs=40, lr=1e-2
    )
    write_left_flare_pairs(tmp_path / "new", rng, 0)
    from edeflare.io.sequence import read_sequence

    inp, gt, size, *_ = read_sequence(tmp_path / "new" / "test" / "s0.h5")
    left_in = (inp["x"] < size[0] // 2).sum()
    kept = {}
    for name, config in (("plain", plain), ("context", with_context)):
        train_head(parts, base, tmp_path / name, config, progress=False)
        out = deflare(inp, size, "model", weights=tmp_path / name / "model.safetensors")
        left = out["x"] < size[0] // 2
        kept[name] = (left.sum() / left_in, (~left).sum() / gt.size)
    assert kept["plain"][0] > 0.3 or kept["plain"][1] < 0.7  # no better than a coin
    assert kept["context"][0] < 0.1 and kept["context"][1] > 0.9  # flare gone, scene kept
    card = read_card(tmp_path / "context" / "model.safetensors")
    assert card.head["context"] == {"channels": 2, "inputs": 33, "widths": [4, 8]}
    # the windows' cells are cached with the rows; a rerun reads them and fits alike
    cached = sorted(p.name for p in (tmp_path / "context").glob("features-*.npz"))
    with np.load(tmp_path / "context" / cached[0]) as z:
        assert {"window", "cell", "sizes", "cells_000000"} <= set(z.files)
        assert z["cells_000000"].shape == (33, 8, 12)  # 17 inputs, 16 logits; 4x4-pixel cells
    again = train_head(parts, base, tmp_path / "context", with_context, progress=False)
    assert again["keep_threshold"] == card.keep_threshold
    assert sorted(p.name for p in (tmp_path / "context").glob("features-*.npz")) == cached


def test_context_columns_and_their_gradients_are_the_same_to_the_bit_every_time():
    # rows of several windows in any order: advanced indexing's backward, which the fit
    # used, gave other gradients on each run with two threads (two fits of one command
    # on the same drawn rows scored 0.852 and 0.873 in validation)
    gen = torch.Generator().manual_seed(1)
    maps = torch.randn(8, 8, 30, 40, generator=gen)
    window = torch.randint(0, 8, (64_000,), generator=gen)
    cell = torch.randint(0, 30 * 40, (64_000,), generator=gen)  # 7 rows a cell
    upstream = torch.randn(64_000, 8, generator=gen)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        grads = []
        for _ in range(5):
            m = maps.clone().requires_grad_()
            columns = context_at(m, window, cell)
            (columns * upstream).sum().backward()
            grads.append(m.grad)
    finally:
        torch.set_num_threads(before)
    assert torch.equal(columns, maps.reshape(8, 8, -1)[window, :, cell])  # the same values
    assert all(torch.equal(grads[0], g) for g in grads[1:])


def test_a_card_with_a_malformed_context_fails_to_load_naming_it():
    head = {"features": ["net_logit"], "context": {"channels": 2, "inputs": 17}}
    with pytest.raises(WeightsError, match=r"context holds channels, inputs, widths \(and"):
        ModelCard.from_dict({"preset": "mask.lite", "head": head})
    head["context"] = {"channels": 0, "inputs": 17, "widths": [4]}
    with pytest.raises(WeightsError, match="context sizes must be positive integers"):
        ModelCard.from_dict({"preset": "mask.lite", "head": head})
    head["context"] = {"channels": 2, "inputs": 17, "widths": [4], "relative_counts": 18}
    with pytest.raises(WeightsError, match="context relative_counts 18 exceeds its 17 inputs"):
        ModelCard.from_dict({"preset": "mask.lite", "head": head})
    head["context"]["relative_counts"] = True
    with pytest.raises(WeightsError, match="relative_counts must be positive integers"):
        ModelCard.from_dict({"preset": "mask.lite", "head": head})


RELATIVE = {"channels": 2, "inputs": 33, "widths": [4, 8], "relative_counts": 16}


def test_a_relative_context_reads_a_window_the_same_at_any_rate(rng):
    # a window's counts all scaled by one share: the relative context's maps do not move,
    # the absolute one's do; the share of firing pixels and the logits are read as given
    n = rng.poisson(rng.uniform(0, 40, (1, 16, 6, 8))).astype(np.float32)
    rest = torch.from_numpy(rng.normal(size=(1, 17, 6, 8)).astype(np.float32))
    maps = {}
    for name, context in (("relative", RELATIVE), ("absolute", {**RELATIVE, "relative_counts": 0})):
        torch.manual_seed(0)
        head = EventHead(["net_logit"], (4,), context)
        assert ("relative_counts" in head.spec()["context"]) == (name == "relative")
        with torch.no_grad():
            maps[name] = [
                head.context_maps(torch.cat([torch.log1p(torch.from_numpy(q * n)), rest], 1))
                for q in (1.0, 0.5)
            ]
    torch.testing.assert_close(maps["relative"][0], maps["relative"][1], atol=1e-5, rtol=1e-5)
    assert (maps["absolute"][0] - maps["absolute"][1]).abs().max() > 1e-3
    head = EventHead(["net_logit"], (4,), RELATIVE)
    empty = torch.zeros(1, 33, 6, 8)  # a window without events: its counts stay 0
    assert torch.equal(head.context_input(empty), empty)


def test_a_relative_context_is_trained_recorded_and_standardised_as_it_reads(tmp_path, rng):
    parts, base = _two_parts_and_a_base(tmp_path, rng)
    config = HeadTrainingConfig(features=("polarity",), hidden=(4,), epochs=1, per_window=200,
                                context=2, context_widths=(4,), relative_context=True)  # fmt: skip
    train_head(parts, base, tmp_path / "run", config, progress=False)
    card = read_card(tmp_path / "run" / "model.safetensors")
    assert card.head["context"]["relative_counts"] == 16  # mask.lite: 8 bins, 2 polarities
    net = load_model(tmp_path / "run" / "model.safetensors")[0]
    # the count channels standardised as read: log(1 + n / mean n) has a mean of order 1
    # (log(1 + n) of sparse windows' counts, of order 0.01-0.1)
    means = net.head.context_mean[:16]
    assert float(means.mean()) > 0.1 and torch.isfinite(means).all()


def test_a_context_reading_other_cells_than_the_network_gives_is_refused(tmp_path):
    head = EventHead(["net_logit"], (), {"channels": 2, "inputs": 17, "widths": [4]})
    save_with_head(tmp_path / "h.safetensors", head)  # mask.lite: 8 bins, 33 channels
    with pytest.raises(WeightsError, match="context reads 17 channels of cells; a mask.lite "
                       r"network gives 33 \(8 bins\)"):  # fmt: skip
        load_model(tmp_path / "h.safetensors")


def test_context_columns_are_read_at_each_events_cell(tmp_path, rng):
    head = EventHead(["net_logit"], hidden=(), context={"channels": 1, "inputs": 17,
                                                       "widths": [4]})  # fmt: skip
    from edeflare.models.event_head import gather_context

    maps = np.arange(2 * 3, dtype=np.float32).reshape(1, 2, 3)
    ev = make_events([0, 1, 2], [0, 5, 11], [0, 4, 7], [1, 1, 0])
    assert gather_context(maps, ev, 4).tolist() == [[0.0], [4.0], [5.0]]
    assert head.columns == 2 and head.numpy_params()["context"] == 1


@pytest.mark.parametrize("relative", [0, 16])
def test_onnx_export_of_a_context_head_decides_alike(tmp_path, rng, relative):
    pytest.importorskip("onnxruntime")

    head = EventHead(["net_logit", "support"], hidden=(4,),
                     context={**RELATIVE, "relative_counts": relative})  # fmt: skip
    torch.manual_seed(0)
    with torch.no_grad():
        for p in head.parameters():
            torch.nn.init.normal_(p, std=0.5)
    assert_onnx_decides_alike(tmp_path, rng, head, kept_share=(0.05, 0.95))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--context", "-1"], "--context must be 0 or more, got -1"),
        (["--context", "2", "--context-widths", ""], "--context-widths needs at least one width"),
        (["--context-widths", "8,0"], "widths must be positive integers"),
        (["--members", "0"], "--members must be at least 1"),
        (["--workers", "0"], "--workers must be at least 1"),
        (["--device", "tpu"], "device must be auto, cpu, cuda or cuda:N, got 'tpu'"),
        pytest.param(
            ["--device", "cuda"],
            "device 'cuda': torch sees no CUDA device here",
            marks=pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is here"),
        ),
        (["--light-weight", "0"], "--light-weight must be positive, got 0.0"),
        (["--scene-weight", "nan"], "--scene-weight must be positive, got nan"),
        (["--thin", "0"], "thin must be in (0, 1]"),
        (["--thin", "1.5"], "thin must be in (0, 1]"),
        (["--relative-context"], "--relative-context needs a context (--context K)"),
    ],
)
def test_train_head_refuses_a_bad_context_before_reading_data(tmp_path, capsys, args, message):
    from edeflare.cli import main

    try:  # argparse exits on a value it cannot parse; the command returns on the others
        code = main(["train-head", str(tmp_path / "none"), "--out", str(tmp_path / "run"), *args])
    except SystemExit as exc:
        code = exc.code
    assert code != 0 and message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


# ----------------------------------------------------------------------------- ensembles


def _random_context_head(seed: int) -> EventHead:
    torch.manual_seed(seed)
    head = EventHead(["net_logit", "support"], hidden=(4,),
                     context={"channels": 2, "inputs": 33, "widths": [4, 8]})  # fmt: skip
    with torch.no_grad():
        for p in head.parameters():
            torch.nn.init.normal_(p, std=0.5)
    return head


def test_an_ensemble_decides_by_the_mean_of_its_members_logits(tmp_path, rng):
    from edeflare.models.event_head import EventHeadEnsemble

    heads = [_random_context_head(s) for s in (1, 2, 3)]
    ev = random_events(rng, 6_000, (64, 48), t0=0, span_us=40_000)
    windows = [(s, ev[(ev["t"] >= s) & (ev["t"] < s + 20_000)]) for s in (0, 20_000)]
    alone = []
    for i, head in enumerate(heads):  # each member over the same network, on its own
        save_with_head(tmp_path / f"m{i}.safetensors", head)
        d = ModelDeflarer(tmp_path / f"m{i}.safetensors", runtime="torch")
        alone.append(d.window_logits(windows, (64, 48)))
    save_with_head(tmp_path / "ens.safetensors", EventHeadEnsemble(heads))
    card = read_card(tmp_path / "ens.safetensors")
    assert card.head["members"] == 3 and card.head["context"]["channels"] == 2
    d = ModelDeflarer(tmp_path / "ens.safetensors", runtime="torch")
    assert isinstance(d.model.head, EventHeadEnsemble) and d.head_params["context"] == 6
    for k, got in enumerate(d.window_logits(windows, (64, 48))):
        want = np.mean([a[k] for a in alone], axis=0)
        assert got.shape == (windows[k][1].size,)
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-4)
        assert np.abs(alone[0][k] - alone[1][k]).max() > 0.1  # the members do differ


def test_numpy_ensemble_equals_torch_in_blocks_of_any_size(monkeypatch, rng):
    import edeflare.models.event_head as event_head
    from edeflare.models.event_head import EventHeadEnsemble

    heads = [_random_context_head(s) for s in (6, 7, 8)]
    heads[1].standardise_on(torch.randn(40, 2) * 3.0 + 1.0)  # folded into its first layer
    ensemble = EventHeadEnsemble(heads)
    x = rng.normal(size=(1_000, 2 + 3 * 2)).astype(np.float32)  # features, 3 x 2 context
    with torch.no_grad():
        want = ensemble(torch.from_numpy(x)).numpy().ravel()
    params = ensemble.numpy_params()
    np.testing.assert_allclose(head_logits(params, x), want, rtol=1e-5, atol=1e-5)
    monkeypatch.setattr(event_head, "HEAD_BLOCK", 96)  # 11 blocks, the last one short
    np.testing.assert_allclose(head_logits(params, x), want, rtol=1e-5, atol=1e-5)
    assert np.abs(want).max() > 0.1 and head_logits(params, x[:0]).shape == (0,)


def test_context_read_per_cell_equals_the_columns_it_replaces(monkeypatch, rng):
    import edeflare.models.event_head as event_head
    from edeflare.models.event_head import (
        EventHeadEnsemble,
        event_cells,
        gather_context,
        head_logits_at_cells,
    )

    ensemble = EventHeadEnsemble([_random_context_head(s) for s in (4, 5, 6)])
    params = ensemble.numpy_params()
    ev = random_events(rng, 2_000, (40, 24), t0=0, span_us=20_000)
    maps = rng.normal(size=(6, 3, 5)).astype(np.float32)  # 3 members x 2 maps, 8-px cells
    x = rng.normal(size=(ev.size, 2)).astype(np.float32)
    want = head_logits(params, np.hstack([x, gather_context(maps, ev, 8)]))
    cells = event_cells(ev, 8, 5)
    assert np.unique(cells).size == 15  # every cell read
    got = head_logits_at_cells(params, x, maps, cells)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)
    monkeypatch.setattr(event_head, "HEAD_BLOCK", 96)  # 21 blocks, the last one short
    np.testing.assert_allclose(head_logits_at_cells(params, x, maps, cells), want, atol=1e-5)
    assert np.abs(want).max() > 0.1
    with pytest.raises(ValueError, match="5 context maps for a head that reads 6"):
        head_logits_at_cells(params, x, maps[:5], cells)
    plain = EventHead(("net_logit",), (4,)).numpy_params()
    with pytest.raises(ValueError, match="no context"):
        head_logits_at_cells(plain, x[:, :1], maps, cells)


def test_onnx_export_of_an_ensemble_decides_alike(tmp_path, rng):
    pytest.importorskip("onnxruntime")
    from edeflare.models.event_head import EventHeadEnsemble

    ensemble = EventHeadEnsemble([_random_context_head(s) for s in (4, 5)])
    assert_onnx_decides_alike(tmp_path, rng, ensemble, kept_share=(0.05, 0.95))


def test_malformed_ensembles_are_refused_naming_the_problem():
    from edeflare.errors import ParameterError
    from edeflare.models.event_head import EventHeadEnsemble

    for members in (0, True, "2"):
        with pytest.raises(WeightsError, match="members must be a positive integer"):
            ModelCard.from_dict(
                {"preset": "mask.lite", "head": {"features": ["net_logit"], "members": members}}
            )
    # one member is a plain head: the card's entry leaves it out
    card = ModelCard.from_dict(
        {"preset": "mask.lite", "head": {"features": ["net_logit"], "members": 1}}
    )
    assert "members" not in card.head
    with pytest.raises(ParameterError, match="share one layout"):
        EventHeadEnsemble([EventHead(["net_logit"], (4,)), EventHead(["net_logit"], (8,))])
    with pytest.raises(ParameterError, match="at least two heads"):
        EventHeadEnsemble([EventHead(["net_logit"], (4,))])


def test_train_head_fits_members_from_successive_seeds_on_the_same_events(tmp_path, rng):
    from edeflare.models.event_head import EventHeadEnsemble

    parts, base = _two_parts_and_a_base(tmp_path, rng)
    one = HeadTrainingConfig(features=("net_logit", "rate_8", "polarity"), hidden=(8,),
                             epochs=5, batch_size=256, per_window=300, seed=7)  # fmt: skip
    train_head(parts, base, tmp_path / "one", one, progress=False)
    three = dataclasses.replace(one, members=3)
    summary = train_head(parts, base, tmp_path / "three", three, progress=False)
    card = read_card(tmp_path / "three" / "model.safetensors")
    assert card.head["members"] == 3 and card.keep_threshold == summary["keep_threshold"]
    ens, _ = load_model(tmp_path / "three" / "model.safetensors")
    single, _ = load_model(tmp_path / "one" / "model.safetensors")
    assert isinstance(ens.head, EventHeadEnsemble) and len(ens.head.members) == 3
    # member 0 is the single run's head (seed 7), the others other seeds' (8, 9)
    first, second = ens.head.members[0].layers[0].weight, ens.head.members[1].layers[0].weight
    assert torch.equal(first, single.head.layers[0].weight)
    assert not torch.equal(first, second)
    # the members share the events drawn once (the seed of the features is the run's)
    assert len(list((tmp_path / "three").glob("features-*.npz"))) == 2
    assert HeadTrainingConfig().members == 1
    with pytest.raises(Exception, match="members must be at least 1"):
        HeadTrainingConfig(members=0)
    # with a context: each member's maps one after another, and the run de-flares
    ctx = dataclasses.replace(one, context=2, context_widths=(4,), batch_windows=2, members=2)
    train_head(parts, base, tmp_path / "ctx", ctx, progress=False)
    d = ModelDeflarer(tmp_path / "ctx" / "model.safetensors")
    assert d.card.head["members"] == 2 and d.head_params["context"] == 4
    inp = random_events(rng, 2_000, (48, 32), t0=0, span_us=40_000)
    assert 0 <= d(inp, (48, 32)).size <= inp.size


# ----------------------------------------------------------------------------- distillation


def _constant_teacher(base, path, features, keep_probability):
    """A head over ``base``'s network that gives every event ``keep_probability``."""
    net, card = load_model(base)
    net.head = EventHead(features, (4,))
    with torch.no_grad():
        for p in net.head.parameters():
            p.zero_()
        net.head.layers[-1].bias.fill_(math.log(keep_probability / (1 - keep_probability)) - LN3)
    save_model(path, net, dataclasses.replace(card, head=net.head.spec()))
    return path


def test_a_distilled_head_learns_its_teachers_probabilities_not_the_labels(tmp_path, rng):
    parts, base = _two_parts_and_a_base(tmp_path, rng)
    features = ("net_logit", "rate_8", "polarity")
    config = HeadTrainingConfig(features=features, hidden=(4,), epochs=20, batch_size=256,
                                per_window=300)  # fmt: skip
    teacher = _constant_teacher(base, tmp_path / "teacher.safetensors", features, 0.7)
    summary = train_head(parts, base, tmp_path / "student", config, teacher=teacher,
                         progress=False)  # fmt: skip
    assert summary["teacher"] == str(teacher) and len(summary["teacher_sha256"]) == 64
    card = read_card(tmp_path / "student" / "model.safetensors")
    assert "distilled from teacher.safetensors" in card.notes
    train_head(parts, base, tmp_path / "labels", config, progress=False)
    (cache,) = (tmp_path / "student").glob("features-train-*.npz")
    with np.load(cache) as z:
        data = {k: z[k] for k in z.files}
    np.testing.assert_allclose(teacher_targets(teacher, base, features, data), 0.7, atol=1e-6)
    student = teacher_targets(tmp_path / "student" / "model.safetensors", base, features, data)
    labels = teacher_targets(tmp_path / "labels" / "model.safetensors", base, features, data)
    assert np.abs(student - 0.7).mean() < 0.05  # the teacher's 0.7 everywhere
    # learned from the labels, the same head tells the dense left from the sparse right
    assert labels[data["y"]].mean() - labels[~data["y"]].mean() > 0.5


def test_a_teacher_that_does_not_fit_the_student_is_refused(tmp_path, capsys):
    base, other_base = tmp_path / "base.safetensors", tmp_path / "b2.safetensors"
    for path, seed in ((base, 0), (other_base, 1)):
        torch.manual_seed(seed)
        save_model(path, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    features = ("net_logit", "rate_8")
    data = {"x": np.zeros((3, 2), np.float32)}
    with pytest.raises(Exception, match="the teacher has no keep head"):
        teacher_targets(base, base, features, data)
    other = _constant_teacher(base, tmp_path / "t.safetensors", ("net_logit", "support"), 0.5)
    with pytest.raises(Exception, match=r"reads the features \['net_logit', 'support'\]"):
        teacher_targets(other, base, features, data)
    teacher = _constant_teacher(base, tmp_path / "t2.safetensors", features, 0.5)
    with pytest.raises(Exception, match="the teacher's network differs from that of"):
        teacher_targets(teacher, other_base, features, data)
    ctx = EventHead(features, (4,), {"channels": 2, "inputs": 33, "widths": [4]})
    net, card = load_model(base)
    net.head = ctx
    save_model(tmp_path / "t3.safetensors", net, dataclasses.replace(card, head=ctx.spec()))
    with pytest.raises(Exception, match="train the student with a context too"):
        teacher_targets(tmp_path / "t3.safetensors", base, features, data)
    # the command refuses such a teacher before it reads data or makes the run folder
    from edeflare.cli import main

    code = main(["train-head", str(tmp_path / "none"), "--out", str(tmp_path / "run"),
                 "--weights", str(base), "--teacher", str(other)])  # fmt: skip
    assert code != 0 and not (tmp_path / "run").exists()
    assert "the teacher reads the features" in capsys.readouterr().err


def test_train_head_reads_the_default_features_and_default_stands_for_them(monkeypatch, tmp_path):
    from edeflare.cli import main
    from edeflare.models import head_training
    from edeflare.models.event_features import DEFAULT_FEATURES

    # the bundled heads' 21 features: their commands, which name none, rebuild them
    assert HeadTrainingConfig().features == DEFAULT_FEATURES
    assert len(DEFAULT_FEATURES) == 21 and "sync_64" not in DEFAULT_FEATURES
    seen = {}

    def fake(data, base, run, config, **kwargs):
        seen["features"] = config.features
        return {"keep_threshold": 0.5, "threshold_table": [{"score": 1.0}], "chosen_on": "x",
                "train_events": 1}  # fmt: skip

    monkeypatch.setattr(head_training, "train_head", fake)
    args = ["train-head", str(tmp_path), "--out", str(tmp_path / "run")]
    assert main([*args, "--features", "default,since_same,sync_64"]) == 0
    assert seen["features"] == (*DEFAULT_FEATURES, "since_same", "sync_64")
    assert main(args) == 0
    assert seen["features"] == DEFAULT_FEATURES
