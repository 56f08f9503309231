"""The rules' registry: one declaration per knob makes the card, the options and the docs."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from edeflare.cli import main
from edeflare.errors import ParameterError
from edeflare.methods import ModelParams
from edeflare.models import create_model
from edeflare.models.weights import ModelCard, WeightsError, read_card, save_model
from edeflare.rules import RULES, RuleSet, knob_fields, reference_markdown

ROOT = Path(__file__).resolve().parents[1]


def test_every_knob_is_a_model_parameter_and_an_option_with_the_cards_default():
    knobs = knob_fields()
    params = {f.name: f for f in dataclasses.fields(ModelParams)}
    for name, (rule, field) in knobs.items():
        assert params[name].default is None  # None: the model card's value
        assert params[name].metadata["cli"].flag == "--" + name.replace("_", "-")
        assert getattr(rule.params(), name) == field.default == 0  # off unless the card says
    assert list(RULES) == ["ghost", "halo", "streak", "far", "light-free"]


def test_a_rule_set_checks_each_knob_by_name():
    assert RuleSet({"light_free_support": 2.0})["light_free_support"] == 2
    assert not RuleSet().active and RuleSet({"far_shift": 1}).active
    # a support alone shifts nothing; it gates the light-free shift
    assert not RuleSet({"light_free_support": 2}).active
    assert RuleSet({"light_free_support": 2, "light_free_shift": 1}).needs_support
    with pytest.raises(ParameterError, match="halo_shift must be a finite number >= 0"):
        RuleSet({"halo_shift": -1})
    with pytest.raises(ParameterError, match="light_free_support must be a whole number"):
        RuleSet({"light_free_support": 1.5})


def test_a_card_written_before_the_registry_still_loads_and_round_trips():
    flat = {"preset": "mask.lite", "keep_threshold": 0.4, "halo_shift": 3.0, "far_shift": 4}
    card = ModelCard.from_dict(flat)
    assert card.rules == {"far_shift": 4.0, "halo_shift": 3.0}
    assert ModelCard.from_dict(card.to_dict()) == card
    assert card.rule_set().changed() == {"halo_shift": 3.0, "far_shift": 4.0}


def test_an_unknown_rule_in_a_card_is_one_clear_error(tmp_path, capsys):
    with pytest.raises(WeightsError, match="unknown rule knob 'glow_shift'; known: far_shift"):
        ModelCard.from_dict({"preset": "mask.lite", "rules": {"glow_shift": 1.0}})
    path = tmp_path / "m.safetensors"
    save_model(path, create_model("mask.lite"), ModelCard(preset="mask.lite"))
    # a card edited by hand: the CLI names the file and the knob, one line, exit 1
    from safetensors import safe_open
    from safetensors.torch import save_file

    with safe_open(str(path), "pt") as f:
        meta = f.metadata()
        tensors = {k: f.get_tensor(k) for k in f.keys()}
    card = json.loads(meta["edeflare_card"])
    card["rules"] = {"glow_shift": 1.0}
    save_file(tensors, str(path), metadata={**meta, "edeflare_card": json.dumps(card)})
    with pytest.raises(WeightsError, match="glow_shift"):
        read_card(path)
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "glow_shift" in err[0] and err[0].startswith("edeflare: error:")


def test_the_rules_page_is_current():
    page = (ROOT / "docs" / "rules.md").read_text(encoding="utf-8")
    if page != reference_markdown() + "\n":
        pytest.fail("docs/rules.md is out of date: run python docs/make_rules_reference.py")
    for name in knob_fields():
        assert f"`{name}`" in page
