"""ONNX export: parity with torch on real windows, self-describing files, clear errors."""

from __future__ import annotations

from itertools import islice

import numpy as np
import pytest
import torch

from conftest import random_events, real_data_dir, same_events
from edeflare.cli import main
from edeflare.errors import EdeflareError
from edeflare.io import open_events, read_events, write_events
from edeflare.methods import deflare_file
from edeflare.models import create_model
from edeflare.models.export import OnnxNetwork, export_onnx, onnx_parity
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.weights import ModelCard, WeightsError, read_card, save_model

GEN3 = "prophesee_gen3_rotating_light.raw"


def _trained_like(preset: str) -> torch.nn.Module:
    """A model of ``preset`` with random weights everywhere (its zero-initialised
    last layer too), so that it drops events and its outputs vary."""
    torch.manual_seed(0)
    model = create_model(preset)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(0.1 * torch.randn_like(p))
    return model.eval()


@pytest.fixture
def mask_weights(tmp_path):
    path = tmp_path / "mask.safetensors"
    save_model(path, _trained_like("mask.lite"), ModelCard(preset="mask.lite", seed=7))
    return path


def test_mask_model_export_matches_torch_on_real_windows(mask_weights, tmp_path):
    src = open_events(real_data_dir() / GEN3)
    onnx_path = tmp_path / "mask.onnx"
    card = export_onnx(mask_weights, onnx_path, src.sensor_size)
    assert card == read_card(onnx_path)  # the card travels in the ONNX metadata
    parity = onnx_parity(mask_weights, onnx_path, islice(src.windows(20_000), 3), src.sensor_size)
    assert parity.windows == 3
    assert parity.decisions == sum(ev.size for _, ev in islice(src.windows(20_000), 3))
    assert 0.1 < parity.max_abs_value  # the random weights do make a mask
    assert parity.max_abs_diff <= 1e-4 * max(1.0, parity.max_abs_value)
    # a logit within float rounding of the threshold may flip: at most 1 event in 10,000
    assert parity.decisions_differing <= parity.decisions // 10_000


def test_bundled_voxel_model_export_matches_torch_on_a_real_window(tmp_path):
    src = open_events(real_data_dir() / GEN3)
    onnx_path = tmp_path / "eflare.onnx"
    weights = bundled_weights("eflare")
    export_onnx(weights, onnx_path, src.sensor_size)
    parity = onnx_parity(weights, onnx_path, islice(src.windows(20_000), 1), (640, 480))
    assert parity.unit == "cell" and parity.decisions == 8 * 640 * 480
    # float32 sums in another order: relative error ~1e-4, a handful of cells round differently
    assert parity.max_abs_diff <= 1e-3 * parity.max_abs_value
    assert parity.decisions_differing <= parity.decisions // 10_000


@pytest.mark.parametrize("preset", ["mask.lite", "mask.pixel"])
def test_deflare_runs_an_exported_file_and_the_onnx_runtime_on_weights(preset, tmp_path, rng):
    # mask.pixel: its per-pixel refinement travels in the ONNX metadata and runs per event
    mask_weights = tmp_path / "mask.safetensors"
    save_model(mask_weights, _trained_like(preset), ModelCard(preset=preset, seed=7))
    size = (96, 64)
    events = random_events(rng, 20_000, size, t0=0, span_us=100_000)
    events = np.concatenate([events, random_events(rng, 20_000, (8, 8), t0=0, span_us=100_000)])
    events = events[np.argsort(events["t"], kind="stable")]
    write_events(tmp_path / "in.h5", events, size)
    export_onnx(mask_weights, tmp_path / "m.onnx", size)
    outputs = {}
    for name, params in {
        "torch": {"weights": str(mask_weights), "runtime": "torch"},
        "onnx-file": {"weights": str(tmp_path / "m.onnx")},
        "onnx-weights": {"weights": str(mask_weights), "runtime": "onnx"},
    }.items():
        out = tmp_path / f"{name}.h5"
        deflare_file(tmp_path / "in.h5", out, "model", params=params, progress=False)
        outputs[name] = read_events(out).events
    assert 0 < outputs["torch"].size < events.size  # the model does drop events
    assert same_events(outputs["onnx-file"], outputs["torch"])
    assert same_events(outputs["onnx-weights"], outputs["torch"])
    if preset == "mask.pixel":
        assert OnnxNetwork(tmp_path / "m.onnx").pixel_params is not None


def test_exported_file_refuses_another_sensor_size(mask_weights, tmp_path):
    export_onnx(mask_weights, tmp_path / "m.onnx", (64, 48))
    deflarer = ModelDeflarer(tmp_path / "m.onnx")
    with pytest.raises(EdeflareError, match=r"m\.onnx: exported for a 64x48 sensor.*80x48"):
        deflarer(random_events(np.random.default_rng(0), 10, (80, 48), span_us=20_000), (80, 48))
    with pytest.raises(EdeflareError, match=r"outside \[0, 20000\)"):
        ev = random_events(np.random.default_rng(0), 10, (64, 48))
        list(deflarer.windows([(0, ev)], (64, 48)))


def test_foreign_and_corrupt_onnx_files_are_refused(mask_weights, tmp_path):
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x08\x07not a model at all")
    with pytest.raises(WeightsError, match=r"garbage\.onnx: not a loadable ONNX model"):
        OnnxNetwork(garbage)
    import onnx

    export_onnx(mask_weights, tmp_path / "m.onnx", (32, 16))
    proto = onnx.load(tmp_path / "m.onnx")
    del proto.metadata_props[:]
    onnx.save(proto, tmp_path / "plain.onnx")
    with pytest.raises(WeightsError, match=r"plain\.onnx: not an edeflare ONNX export"):
        read_card(tmp_path / "plain.onnx")
    with pytest.raises(EdeflareError, match="runtime 'onnx', not 'torch'"):
        ModelDeflarer(tmp_path / "m.onnx", runtime="torch")
    with pytest.raises(EdeflareError, match="runtime must be one of"):
        ModelDeflarer(mask_weights, runtime="tensorrt")


def test_cli_export_checks_parity_and_refuses_bad_requests(mask_weights, tmp_path, capsys):
    size = (64, 48)
    write_events(tmp_path / "in.h5", random_events(np.random.default_rng(1), 3000, size), size)
    out = tmp_path / "m.onnx"
    check = ["--check", str(tmp_path / "in.h5"), "--check-windows", "60"]  # all 50 of them
    code = main(["export", str(out), "--model", str(mask_weights), *check])
    text = capsys.readouterr().out
    assert code == 0 and out.is_file()
    assert "mask.lite: wrote" in text and "for a 64x48 sensor" in text
    assert "0 of 3,000 event decisions differ" in text
    assert main(["export", str(tmp_path / "x.onnx"), "--model", str(mask_weights)]) == 1
    assert "give --sensor-size" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "x.pt"), "--sensor-size", "64x48"]) == 1
    assert "must be a .onnx file" in capsys.readouterr().err
    assert not (tmp_path / "x.onnx").exists() and not (tmp_path / "x.pt").exists()


def test_a_graph_is_exported_once_per_model_size_and_opset(monkeypatch):
    from edeflare.models import export

    monkeypatch.setattr(export, "_EXPORTED", type(export._EXPORTED)())
    made = []
    real_export = export._export

    def counting(*args):
        made.append(args[2:])
        return real_export(*args)

    monkeypatch.setattr(export, "_export", counting)
    model, card = _trained_like("mask.lite"), ModelCard(preset="mask.lite", seed=7)
    first = export.onnx_bytes(model, card, (64, 48))
    assert export.onnx_bytes(model, card, (64, 48)) == first and len(made) == 1
    export.onnx_bytes(model, card, (32, 24))  # another size: its own graph
    assert made == [((64, 48), export.DEFAULT_OPSET), ((32, 24), export.DEFAULT_OPSET)]
    with torch.no_grad():  # new weights, same object: a new graph, not the stale one
        next(model.parameters()).add_(1.0)
    assert export.onnx_bytes(model, card, (64, 48)) != first and len(made) == 3
    other = ModelCard(preset="mask.lite", seed=8)  # the card travels in the metadata
    assert export.onnx_bytes(model, other, (64, 48)) != first and len(made) == 4
    for k in range(export._EXPORTED_MAX + 2):  # the oldest graphs go first
        export.onnx_bytes(model, card, (16 + k, 16))
    assert len(export._EXPORTED) == export._EXPORTED_MAX
    assert ((64, 48), export.DEFAULT_OPSET) not in [key[1:] for key in export._EXPORTED]
