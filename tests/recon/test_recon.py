"""The reconstructor: network, training clips, weights, streaming inference, training resume."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from edeflare.errors import EdeflareError
from edeflare.events import make_events
from edeflare.models.weights import WeightsError
from edeflare.recon import train as recon_train
from edeflare.recon.clips import NIGHT, centre_image, draw_clip, intensity_to_image
from edeflare.recon.infer import Reconstructor, reconstruct_events
from edeflare.recon.network import FireNet, normalise_voxels
from edeflare.recon.weights import ReconCard, load_reconstructor, save_reconstructor
from edeflare.sim.background import SyntheticBackground


@pytest.fixture
def weights(tmp_path):
    torch.manual_seed(3)
    path = tmp_path / "r.safetensors"
    save_reconstructor(path, FireNet(), ReconCard(iterations=0))
    return path


def test_firenet_is_firenet_sized_and_any_size():
    net = FireNet()
    assert 30_000 < sum(p.numel() for p in net.parameters()) < 50_000
    image, state = net(torch.zeros(2, 5, 13, 17), None)
    assert image.shape == (2, 1, 13, 17) and all(s.shape[-2:] == (13, 17) for s in state)


def test_integrator_state_adds_signed_events_and_decays():
    net = FireNet()
    v = torch.zeros(1, 5, 2, 2)
    v[0, 0, 0, 0] = 3.0  # three ON events
    v[0, 4, 1, 1] = -1.0  # one OFF event
    with torch.no_grad():
        _, state = net(v, None)
        _, later = net(torch.zeros_like(v), state)
    c = net.contrast.item()
    np.testing.assert_allclose(state[2][0, 0].numpy(), [[3 * c, 0.0], [0.0, -c]], rtol=1e-6)
    keep = torch.sigmoid(net.keep_logit).item()
    assert later[2][0, 0, 0, 0].item() == pytest.approx(3 * c * keep)


def test_normalise_voxels_is_scale_free():
    v = torch.randn(2, 5, 8, 8)
    v[v.abs() < 1] = 0
    assert torch.allclose(normalise_voxels(v), normalise_voxels(7.0 * v))
    assert normalise_voxels(torch.zeros(1, 5, 4, 4)).abs().sum() == 0


def test_clip_images_are_the_simulators_frames_at_window_ends():
    clip = draw_clip((40, 30), 3, window_us=10_000, rng=5)
    background = SyntheticBackground(NIGHT).draw(30_000, (40, 30), rng=5)
    for k in range(3):
        end = min((k + 1) * 10_000, 30_000 - 1)
        want = centre_image(intensity_to_image(background.video(end)))
        np.testing.assert_array_equal(clip.images[k, 0], want)
        # the voxels hold that window's events, signed
        sel = (background.events["t"] >= k * 10_000) & (background.events["t"] < (k + 1) * 10_000)
        signed = np.where(background.events["p"][sel] > 0, 1, -1).sum()
        assert clip.voxels[k].sum() == signed


def test_intensity_mapping_and_centring_by_hand():
    assert intensity_to_image(np.array([0.0, np.e - 1])).tolist() == pytest.approx(
        [0.0, 1.0 / np.log1p(255.0)]
    )
    # mean 0.75 -> shift by -0.25; the 0 clips at 0
    np.testing.assert_allclose(
        centre_image(np.array([[0.0, 1.0], [1.0, 1.0]])), [[0.0, 0.75], [0.75, 0.75]]
    )


def test_weights_round_trip_and_refusals(weights, tmp_path):
    model, card = load_reconstructor(weights)
    torch.manual_seed(3)
    fresh = FireNet()
    for (name, a), b in zip(model.state_dict().items(), fresh.state_dict().values(), strict=True):
        assert torch.equal(a, b), name
    assert card.iterations == 0 and card.window_us == 20_000
    pickle = tmp_path / "p.safetensors"
    torch.save(fresh.state_dict(), pickle)
    with pytest.raises(WeightsError, match="pickle"):
        load_reconstructor(pickle)
    from edeflare.models import create_model
    from edeflare.models.weights import ModelCard, save_model

    deflarer = tmp_path / "m.safetensors"
    save_model(deflarer, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    with pytest.raises(WeightsError, match="no reconstructor card"):
        load_reconstructor(deflarer)


def test_streaming_steps_equal_the_whole_stream_and_reset(weights):
    rng = np.random.default_rng(0)
    n = 400
    ev = make_events(
        np.sort(rng.integers(5_000, 65_000, n)),
        rng.integers(0, 16, n),
        rng.integers(0, 12, n),
        rng.integers(0, 2, n),
    )
    times, images = reconstruct_events(ev, (16, 12), weights=weights)
    assert times.tolist() == [20_000, 40_000, 60_000, 80_000]
    rec = Reconstructor(weights)
    for k, start in enumerate(range(0, 80_000, 20_000)):
        part = ev[(ev["t"] >= start) & (ev["t"] < start + 20_000)]
        np.testing.assert_array_equal(rec.step(part, (16, 12), start), images[k])
    with pytest.raises(Exception, match="reset"):
        rec.step(ev[:0], (8, 8), 80_000)
    rec.reset()
    np.testing.assert_array_equal(rec.step(ev[ev["t"] < 20_000], (16, 12), 0), images[0])


def test_training_resumes_exactly(tmp_path, monkeypatch):
    config = recon_train.ReconTrainConfig(
        iterations=4, batch_size=2, clips=3, windows=3, width=24, height=16, checkpoint_every=2
    )
    straight = recon_train.train_reconstructor(tmp_path / "a", config, progress=False)
    calls = {"n": 0}
    real = recon_train.clip_loss

    def dies_on_third(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt  # killed after the checkpoint of iteration 2
        return real(*args, **kwargs)

    monkeypatch.setattr(recon_train, "clip_loss", dies_on_third)
    with pytest.raises(KeyboardInterrupt):
        recon_train.train_reconstructor(tmp_path / "b", config, progress=False)
    assert not (tmp_path / "b" / "model.safetensors").exists()
    monkeypatch.setattr(recon_train, "clip_loss", real)
    resumed = recon_train.train_reconstructor(tmp_path / "b", config, progress=False)
    a, b = load_reconstructor(straight)[0], load_reconstructor(resumed)[0]
    for (name, x), y in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        assert torch.equal(x, y), name
    log = (tmp_path / "b" / "train_log.csv").read_text().splitlines()
    assert [row.split(",")[0] for row in log] == ["iteration", "1", "2", "3", "4"]
    # only the iteration count may change on resume
    other = dataclasses.replace(config, lr=config.lr / 2)
    with pytest.raises(EdeflareError, match=r"\['lr'\]"):
        recon_train.train_reconstructor(tmp_path / "b", other, progress=False)


def test_the_module_command_records_itself_and_the_held_out_score(tmp_path, capsys):
    argv = [str(tmp_path / "run"), "--iterations", "2", "--batch-size", "2", "--clips", "2"]
    argv += ["--windows", "3", "--width", "24", "--height", "16"]
    assert recon_train.main(argv) == 0
    _, card = load_reconstructor(tmp_path / "run" / "model.safetensors")
    assert card.command.startswith("python -m edeflare.recon.train " + " ".join(argv))
    assert "train_reconstructor" in card.command and card.iterations == 2
    assert set(card.metrics) == {"held_out_l1", "flat_gray_l1", "ratio"}  # held_out_error's
    assert card.metrics["ratio"] == pytest.approx(
        card.metrics["held_out_l1"] / card.metrics["flat_gray_l1"]
    )
    assert json.loads(capsys.readouterr().out.splitlines()[-1]) == card.metrics
