"""Weights files: safetensors round trip with a card; clear errors for everything else."""

from __future__ import annotations

import pickle

import pytest
import torch

from edeflare.models import create_model
from edeflare.models.weights import ModelCard, WeightsError, load_model, read_card, save_model


def _trained(name="unet2d.lite"):
    torch.manual_seed(1)
    model = create_model(name)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.01 * torch.randn_like(p))
    return model


def test_round_trip_keeps_every_tensor_and_the_card(tmp_path):
    model = _trained()
    card = ModelCard(
        preset="unet2d.lite", command="edeflare train x", seed=4, metrics={"val_mse": 0.01}
    )
    path = tmp_path / "m.safetensors"
    save_model(path, model, card)
    loaded, got = load_model(path)
    assert got == card and read_card(path) == card
    pairs = zip(model.state_dict().items(), loaded.state_dict().items(), strict=True)
    for (k, a), (k2, b) in pairs:
        assert k == k2 and torch.equal(a, b)
    assert not loaded.training


def test_file_of_another_preset_is_rejected(tmp_path):
    path = tmp_path / "m.safetensors"
    save_model(path, _trained("unet2d.lite"), ModelCard(preset="unet3d.lite"))  # lying card
    with pytest.raises(WeightsError, match=r"do not fit preset 'unet3d\.lite'"):
        load_model(path)


def test_pickles_are_never_loaded(tmp_path):
    torch_file = tmp_path / "m.pt"
    torch.save(create_model("unet2d.lite").state_dict(), torch_file)
    with pytest.raises(WeightsError, match="only loads safetensors"):
        load_model(torch_file)
    raw = tmp_path / "m.pkl"
    raw.write_bytes(pickle.dumps({"a": 1}, protocol=4))
    with pytest.raises(WeightsError, match="pickle"):
        load_model(raw)


def test_missing_corrupt_and_cardless_files(tmp_path):
    with pytest.raises(WeightsError, match="no such weights file"):
        load_model(tmp_path / "none.safetensors")
    path = tmp_path / "m.safetensors"
    save_model(path, _trained(), ModelCard(preset="unet2d.lite"))
    data = path.read_bytes()
    (tmp_path / "cut.safetensors").write_bytes(data[: len(data) // 2])
    with pytest.raises(WeightsError, match=r"corrupt|not a readable"):
        load_model(tmp_path / "cut.safetensors")
    from safetensors.torch import save_file

    save_file({"w": torch.zeros(2)}, str(tmp_path / "bare.safetensors"))
    with pytest.raises(WeightsError, match="no edeflare model card"):
        load_model(tmp_path / "bare.safetensors")


def test_card_rejects_unknown_keys_and_presets(tmp_path):
    with pytest.raises(WeightsError, match="unknown model card keys"):
        ModelCard.from_dict({"preset": "unet2d.lite", "colour": "red"})
    with pytest.raises(ValueError, match="unknown model"):
        save_model(tmp_path / "x.safetensors", _trained(), ModelCard(preset="resnet"))
    assert not (tmp_path / "x.safetensors").exists()
