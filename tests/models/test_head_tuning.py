"""A trained keep head fitted further to annotated real recordings (edeflare.models.head_tuning)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from conftest import random_events
from edeflare import deflare
from edeflare.cli import main
from edeflare.errors import EdeflareError
from edeflare.events import make_events, sort_events
from edeflare.io import write_events
from edeflare.lights import Lights, LightSource, save_lights
from edeflare.models.event_head import EventHead, EventHeadEnsemble, head_logits
from edeflare.models.head_training import HeadTrainingConfig, train_head
from edeflare.models.head_tuning import (
    REGIONS,
    LabelledRecording,
    TuningConfig,
    fit_members,
    real_rows,
    recording_inputs,
    region_labels,
    time_split,
    tune_head,
)
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.weights import read_card


def test_regions_are_the_scorers_by_hand():
    # a light of radius 3 at (20, 20) on 100x80: its halo from 5 px to 18 px, its ghost a
    # disc of 6 px round the reflection (79, 59)
    ev = make_events([0, 1, 2, 3, 4], [20, 30, 79, 60, 21], [20, 20, 59, 20, 21], [1, 1, 0, 0, 1])
    scored = Lights((LightSource.circle(20, 20, 3),))
    names = [REGIONS[c] for c in region_labels(ev, (100, 80), scored)]
    assert names == ["light", "flare", "flare", "scene", "light"]
    unscored = Lights((LightSource.circle(20, 20, 3),), score_background=False)
    assert [REGIONS[c] for c in region_labels(ev, (100, 80), unscored)][3] == "unlabelled"
    assert region_labels(ev, (100, 80), None).tolist() == [3] * 5  # no light: all scene


def test_real_rows_weigh_each_recording_and_each_region_alike():
    lit = LabelledRecording(
        "lit",
        np.arange(2 * 115, dtype=np.float32).reshape(2, 115, 1),
        np.array([1] * 10 + [2] * 5 + [3] * 100, np.int8),
    )
    dark = LabelledRecording("dark", np.zeros((2, 50, 1), np.float32), np.full(50, 3, np.int8))
    x, y, w = real_rows([lit, dark], 12.0, TuningConfig(per_region=20))
    # lit: 20 of its 2 x 10 light rows, all 10 flare rows, 20 of 200 scene rows; dark: 20
    assert x.shape == (70, 1) and y.tolist() == [True] * 20 + [False] * 10 + [True] * 40
    assert w.sum() == pytest.approx(12.0)
    assert [round(float(w[a:b].sum()), 4) for a, b in ((0, 20), (20, 30), (30, 50), (50, 70))] == [
        2.0, 2.0, 2.0, 6.0]  # fmt: skip
    # balanced: the 10 flare rows weigh as much as the 60 kept ones (which had 10 of the 12)
    _, yb, wb = real_rows([lit, dark], 12.0, TuningConfig(per_region=20, balance_classes=True))
    assert (yb == y).all() and wb.sum() == pytest.approx(12.0)
    assert wb[~yb].sum() == pytest.approx(6.0) and wb[yb].sum() == pytest.approx(6.0)
    assert wb[50:70].sum() / wb[:20].sum() == pytest.approx(3.0)  # shares within a class kept
    # the flare rows are the flare events' own inputs, in either windowing
    assert set(x[20:30, 0].tolist()) == {*range(10, 15), *range(125, 130)}
    with pytest.raises(EdeflareError, match="no labelled event"):
        LabelledRecording("none", np.zeros((1, 3, 1), np.float32), np.zeros(3, np.int8))


def _context_ensemble() -> EventHeadEnsemble:
    torch.manual_seed(0)
    ctx = {"channels": 2, "inputs": 33, "widths": [4, 8]}
    return EventHeadEnsemble([EventHead(["net_logit", "support"], (8,), ctx) for _ in range(2)])


def test_fitting_members_learns_the_real_labels_and_leaves_the_contexts_alone(rng):
    head = _context_ensemble()
    frozen = {k: v.clone() for k, v in head.state_dict().items() if "layers" not in k}
    sim_x = rng.normal(size=(2_000, 6)).astype(np.float32)
    sim_y = rng.random(2_000) < 0.5  # the simulated rows say nothing
    inputs = rng.normal(size=(2, 1_000, 6)).astype(np.float32)
    codes = np.where(inputs[0, :, 1] > 0, 2, 3).astype(np.int8)  # flare where support > 0
    inputs[1, :, 1] = inputs[0, :, 1]
    rec = LabelledRecording("r", inputs, codes)
    config = TuningConfig(real_weight=4.0, epochs=20, lr=1e-2, batch_size=256)
    fit_members(head, sim_x, sim_y, [rec], config)
    logits = head_logits(head.numpy_params(), inputs[0])
    assert np.mean((logits > np.median(logits)) == (codes == 3)) > 0.9
    after = head.state_dict()
    assert all(torch.equal(v, after[k]) for k, v in frozen.items())  # contexts, scales
    with pytest.raises(EdeflareError, match="columns"):
        fit_members(head, sim_x[:, :5], sim_y, [], TuningConfig())


def test_holding_the_simulated_rows_keeps_what_the_head_did_on_them(rng):
    sim_x = rng.normal(size=(2_000, 6)).astype(np.float32)
    sim_y = sim_x[:, 0] > 0  # the simulated rows: keep where net_logit > 0
    inputs = rng.normal(size=(1, 1_000, 6)).astype(np.float32)
    inputs[..., 1] += 6.0  # real rows elsewhere (their support far larger): keep all
    rec = LabelledRecording("r", inputs, np.full(1_000, 3, np.int8))
    before = head_logits(_context_ensemble().numpy_params(), sim_x)
    moved = {}
    for hold in (False, True):
        head = _context_ensemble()
        config = TuningConfig(epochs=10, lr=1e-2, batch_size=256, hold_simulated=hold)
        fit_members(head, sim_x, sim_y, [rec], config)
        moved[hold] = float(np.mean(np.abs(head_logits(head.numpy_params(), sim_x) - before)))
    assert moved[True] < 0.5 * moved[False]


def test_a_recordings_inputs_give_the_models_own_logits(rng):
    d = ModelDeflarer(bundled_weights("learned-absolute"), runtime="torch")
    ev = random_events(rng, 3_000, (64, 48), t0=3_000, span_us=50_000)
    inputs = recording_inputs(d, ev, (64, 48), (0, 5_000))
    assert inputs.shape == (2, 3_000, 45)
    base = d.rule_terms(ev, (64, 48), (0, 5_000)).base
    for v in range(2):
        np.testing.assert_allclose(head_logits(d.head_params, inputs[v]), base[v], atol=1e-4)


def _pairs(folder, rng, size=(48, 32)):
    """Pairs whose flare is a dense burst in the left half (not in gt), sparse scene right."""
    from edeflare.io.dsec import write_dsec_groups

    for split, k in (("train", 2), ("test", 1)):
        for i in range(k):
            scene = random_events(rng, 300, (size[0] // 2, size[1]), t0=0, span_us=60_000)
            scene["x"] += size[0] // 2
            flare = random_events(rng, 3_000, (size[0] // 2, size[1]), t0=0, span_us=60_000)
            inp = sort_events(np.concatenate([scene, flare]))
            write_dsec_groups(folder / split / f"s{i}.h5", {"input": inp, "gt": scene}, size)


def test_tune_head_keeps_what_a_recordings_annotation_calls_light(tmp_path, rng, capsys):
    # a head trained to remove the pairs' dense left half, then told by a real recording
    # of the same kind that its dense left half is a light, to be kept
    from edeflare.io.sequence import read_sequence
    from edeflare.models import create_model
    from edeflare.models.weights import ModelCard, save_model

    _pairs(tmp_path / "sim", rng)
    base = tmp_path / "base.safetensors"
    save_model(base, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    config = HeadTrainingConfig(features=("net_logit", "rate_8", "polarity"), hidden=(8,),
                                epochs=20, batch_size=256, per_window=500)  # fmt: skip
    train_head([tmp_path / "sim"], base, tmp_path / "head", config, progress=False)
    trained = tmp_path / "head" / "model.safetensors"
    _pairs(tmp_path / "real", rng)
    events, _, size, *_ = read_sequence(tmp_path / "real" / "test" / "s0.h5")
    rec = tmp_path / "rec.h5"
    write_events(rec, events, size)
    lights = tmp_path / "rec.json"  # a light over the whole left half
    save_lights(lights, Lights((LightSource.polygon([(0, 0), (23.5, 0), (23.5, 31.5),
                                                     (0, 31.5)]),)), sensor_size=size)  # fmt: skip
    left = events["x"] < 24

    def left_kept(weights) -> float:
        out = deflare(events, size, "model", weights=weights)
        return float((out["x"] < 24).sum() / left.sum())

    out = tmp_path / "tuned"
    args = ["tune-head", str(trained), str(tmp_path / "sim"), "--real", f"{rec}:{lights}",
            "--out", str(out), "--real-weight", "4", "--epochs", "30", "--lr", "1e-2",
            "--keep-threshold", "0.5", "--no-progress"]  # fmt: skip
    assert main(args) == 0
    before, after = left_kept(trained), left_kept(out / "model.safetensors")
    assert before < 0.1 and after > 0.9
    card = read_card(out / "model.safetensors")
    summary = json.loads((out / "tune.json").read_text())
    assert card.keep_threshold == summary["keep_threshold"] == 0.5
    assert summary["threshold_chosen_on"] == "given"
    assert summary["recordings"]["rec"]["light"] == int(left.sum())
    assert card.head == read_card(trained).head  # the layout unchanged
    # its recipe: the base's command, then this one
    assert card.command.startswith(read_card(trained).command + " && edeflare ")
    assert card.data.endswith(f"tuned on {tmp_path / 'sim'} rec")
    cached = sorted(p.name for p in out.glob("*.npz"))
    assert len(cached) == 3  # the two splits' rows and the recording's
    # without a threshold it is chosen on the test splits; the rerun reads the cached rows
    assert main([*args[:-3], "--no-progress"]) == 0
    summary = json.loads((out / "tune.json").read_text())
    assert read_card(out / "model.safetensors").keep_threshold == summary["simulated_threshold"]
    assert sorted(p.name for p in out.glob("*.npz")) == cached
    assert summary["validation"] == {}

    # validated on its last 30 %: three copies of it one after another (180 ms), fitted on
    # what lies before the cut less a window and the largest delay (35 ms)
    copies = [events.copy() for _ in range(3)]
    for k, c in enumerate(copies):
        c["t"] += k * 60_000
    longer = tmp_path / "longer.h5"
    write_events(longer, np.concatenate(copies), size)
    validated = tmp_path / "validated"
    assert main([args[0], str(trained), str(tmp_path / "sim"), "--real", f"{longer}:{lights}",
                 *args[7:-1], "--out", str(validated), "--validate-last", "0.3",
                 "--no-progress"]) == 0  # fmt: skip
    summary = json.loads((validated / "tune.json").read_text())
    t = np.concatenate(copies)["t"]
    fit, val = time_split(t, 0.3, 35_000)
    cut = t[-1] + 1 - 0.3 * (t[-1] + 1 - t[0])  # about 126 ms
    assert t[fit].max() < cut - 35_000 <= t[~fit & ~val].min()
    assert t[~val].max() < cut <= t[val].min()
    assert summary["recordings"]["longer"]["light"] == int((np.tile(left, 3) & fit).sum())
    v = summary["validation"]["longer"]
    assert v["events"] == int(val.sum())
    assert v["before"]["light kept"] < 0.1 and v["tuned"]["light kept"] > 0.9
    assert np.isnan(v["tuned"]["scene kept"]) == np.isnan(v["before"]["scene kept"])
    # 60 ms split at 90 %: nothing is left to fit before the cut and its 35 ms gap
    assert main([*args[:6], str(tmp_path / "short"), "--validate-last", "0.9",
                 "--no-progress"]) == 1  # fmt: skip
    assert "rec: no labelled event to fit before the last 90 %" in capsys.readouterr().err


def test_tune_head_refuses_bad_input_naming_it(tmp_path, capsys):
    assert main(["tune-head", "learned-absolute", str(tmp_path), "--out",
                 str(tmp_path / "r")]) == 1  # fmt: skip
    assert "--real" in capsys.readouterr().err
    rec = tmp_path / "r.h5"
    write_events(rec, make_events([0, 1], [1, 2], [1, 2], [1, 0]), (8, 8))
    assert main(["tune-head", "night", str(tmp_path), "--real", str(rec),
                 "--out", str(tmp_path / "r")]) == 1  # fmt: skip
    assert "no keep head" in capsys.readouterr().err
    assert main(["tune-head", "learned", str(tmp_path), "--real", str(rec),
                 "--out", str(tmp_path / "p")]) == 1  # fmt: skip
    assert "two experts (unlit_model 'learned-absolute')" in capsys.readouterr().err
    assert main(["tune-head", "learned-absolute", str(tmp_path), "--real", str(rec),
                 "--workers", "0", "--out", str(tmp_path / "w")]) == 1  # fmt: skip
    assert "--workers must be at least 1" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()
    with pytest.raises(EdeflareError, match="real_weight"):
        TuningConfig(real_weight=0.0)
    with pytest.raises(EdeflareError, match="lr must be a positive number, got nan"):
        TuningConfig(lr=float("nan"))
    with pytest.raises(EdeflareError, match="epochs must be a positive integer"):
        TuningConfig(epochs=0)
    with pytest.raises(EdeflareError, match=r"validate_last must be in \[0, 1\), got 1.0"):
        TuningConfig(validate_last=1.0)
    empty = tmp_path / "empty.h5"
    write_events(empty, make_events([], [], [], []), (8, 8))
    assert main(["tune-head", "learned-absolute", str(tmp_path), "--real", str(empty),
                 "--out", str(tmp_path / "r")]) == 1  # fmt: skip
    assert "empty: the recording holds no events" in capsys.readouterr().err
    with pytest.raises(EdeflareError, match="keep_threshold"):
        tune_head(bundled_weights("learned-absolute"), [tmp_path], [("r", None, (8, 8), None)],
                  tmp_path / "r", keep_threshold=1.5)  # fmt: skip
