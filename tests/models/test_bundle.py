"""Bundling: a run's tensors copied unchanged, the card's fields set and checked."""

from __future__ import annotations

import json

import pytest
import torch

from edeflare.cli import main
from edeflare.errors import ParameterError
from edeflare.models import create_model
from edeflare.models.bundle import bundle_weights, parse_card_fields
from edeflare.models.infer import bundled_weights
from edeflare.models.weights import (
    ModelCard,
    WeightsError,
    load_model,
    read_card,
    read_tensors,
    save_model,
)
from edeflare.recon.network import FireNet
from edeflare.recon.weights import ReconCard, load_reconstructor, save_reconstructor


@pytest.fixture
def run_weights(tmp_path):
    torch.manual_seed(0)
    path = tmp_path / "run" / "model.safetensors"
    card = ModelCard(preset="mask.fast", command="edeflare train DATA --out RUN", seed=0)
    save_model(path, create_model("mask.fast"), card)
    return path


def _same_tensors(a, b):
    ta, tb = read_tensors(a), read_tensors(b)
    return ta.keys() == tb.keys() and all(
        ta[k].dtype == tb[k].dtype and torch.equal(ta[k], tb[k]) for k in ta
    )


def test_fields_are_set_metrics_merged_and_tensors_copied(run_weights, tmp_path):
    out = tmp_path / "bundled.safetensors"
    save_model(run_weights, *_with_metrics(run_weights, {"iteration": 12}))
    card = bundle_weights(
        run_weights,
        out,
        {"keep_threshold": 0.4, "halo_shift": 3, "data": "DAY NIGHT", "command": "edeflare ..."},
        metrics={"score": 0.9},
    )
    read = read_card(out)
    assert read.to_dict() == card
    assert (read.keep_threshold, read.rules, read.data) == (0.4, {"halo_shift": 3.0}, "DAY NIGHT")
    assert isinstance(read.rules["halo_shift"], float)  # an int given for a float knob
    assert read.metrics == {"iteration": 12, "score": 0.9}  # merged, not replaced
    assert read.preset == "mask.fast" and read.seed == 0  # the rest kept
    assert _same_tensors(run_weights, out)
    load_model(out)


def _with_metrics(path, metrics):
    model, card = load_model(path)
    return model, ModelCard.from_dict({**card.to_dict(), "metrics": metrics})


def test_rebundling_a_bundled_model_with_its_own_card_gives_the_same_bytes(tmp_path):
    out = tmp_path / "night.safetensors"
    card = read_card(bundled_weights("night")).to_dict()
    bundle_weights(bundled_weights("night"), out, {k: card[k] for k in ("data", "notes")})
    assert out.read_bytes() == bundled_weights("night").read_bytes()


def test_half_stores_float16_and_loads_back(run_weights, tmp_path):
    out = tmp_path / "half.safetensors"
    bundle_weights(run_weights, out, half=True)
    assert {t.dtype for t in read_tensors(out).values()} == {torch.float16}
    a, b = load_model(run_weights)[0], load_model(out)[0]
    for (name, x), y in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.allclose(x, y, atol=1e-2, rtol=1e-3), name


def test_unknown_fields_wrong_types_and_other_presets_are_refused(run_weights, tmp_path):
    out = tmp_path / "out.safetensors"
    with pytest.raises(ParameterError, match=r"unknown ModelCard field\(s\) \['threshold'\]"):
        bundle_weights(run_weights, out, {"threshold": 0.4})
    with pytest.raises(ParameterError, match="'keep_threshold' must be float, got 'high'"):
        bundle_weights(run_weights, out, {"keep_threshold": "high"})
    with pytest.raises(ParameterError, match="'seed' must be int or null, got True"):
        bundle_weights(run_weights, out, {"seed": True})
    with pytest.raises(WeightsError, match=r"do not fit preset 'mask\.pixel'"):
        bundle_weights(run_weights, out, {"preset": "mask.pixel"})
    with pytest.raises(WeightsError, match="no such weights file"):
        bundle_weights(tmp_path / "none.safetensors", out)
    assert not out.exists()


def test_a_reconstructors_card_is_set_the_same_way(tmp_path):
    src, out = tmp_path / "recon.safetensors", tmp_path / "firenet.safetensors"
    save_reconstructor(src, FireNet(5, 4), ReconCard(features=4, iterations=3))
    bundle_weights(src, out, {"command": "python -m edeflare.recon.train RUN"})
    _, card = load_reconstructor(out)
    assert card.command == "python -m edeflare.recon.train RUN" and card.features == 4
    assert _same_tensors(src, out)
    with pytest.raises(ParameterError, match="unknown ReconCard field"):
        bundle_weights(src, out, {"keep_threshold": 0.4})


def test_card_fields_are_json_except_text_fields_which_are_as_written():
    fields = parse_card_fields(["seed=3", "notes=night, day", "other=null", 'data="3"', "x="])
    assert fields == {"seed": 3, "notes": "night, day", "other": None, "data": "3", "x": ""}
    fields = parse_card_fields(["data=3", 'command={"a": 1}', "notes=[1,2]", "seed=null"])
    assert fields == {"data": "3", "command": '{"a": 1}', "notes": "[1,2]", "seed": None}
    recon = parse_card_fields(['data={"clips": 256}', "iterations=5"], ReconCard)
    assert recon == {"data": '{"clips": 256}', "iterations": 5}
    with pytest.raises(ParameterError, match="KEY=VALUE"):
        parse_card_fields(["=3"])


def test_the_command_writes_the_card_and_reads_metrics_from_a_file(run_weights, tmp_path, capsys):
    out = tmp_path / "b.safetensors"
    scores = tmp_path / "scores.json"
    scores.write_text(json.dumps({"score_gen3_combined": 0.968}))
    argv = ["bundle", str(run_weights), str(out), "--card", "keep_threshold=0.4"]
    argv += ["--card", "data=MIX = NIGHT and DAY", "--metrics", str(scores)]
    assert main(argv) == 0
    card = read_card(out)
    assert card.keep_threshold == 0.4 and card.data == "MIX = NIGHT and DAY"
    assert card.metrics == {"score_gen3_combined": 0.968}
    assert json.loads(capsys.readouterr().out.split("\n", 1)[1]) == card.to_dict()
    assert main(["bundle", str(run_weights), str(out), "--metrics", '{"a": 1}']) == 0
    assert read_card(out).metrics == {"a": 1}


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--card", "keep_threshold=high"], "must be float"),
        (["--card", "nothing"], "KEY=VALUE"),
        (["--metrics", "[1, 2]"], "must be a JSON object"),
        (["--metrics", "{not json"], "is not JSON"),
    ],
)
def test_the_commands_user_errors_are_one_line(run_weights, tmp_path, capsys, extra, message):
    out = tmp_path / "b.safetensors"
    assert main(["bundle", str(run_weights), str(out), *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("name", ["night", "eflare", "paper", "firenet"])
def test_every_bundled_card_names_package_commands_only(name):
    """A bundled model rebuilds from the package's commands (no script outside it)."""
    from edeflare.models.weights import read_metadata

    card = json.loads(next(iter(read_metadata(bundled_weights(name)).values())))
    text = f"{card['command']} {card['data']} {card.get('notes', '')}"
    assert "experiments/" not in text and "python experiments" not in text
    assert card["command"].startswith(("edeflare ", "python -m edeflare."))
