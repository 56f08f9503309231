"""Downstream scores: reconstructions of each stream against the simulator's clean frames."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from edeflare.cli import main
from edeflare.data.generate import RECIPES, generate_dataset
from edeflare.eval.benchmark import GROUND_TRUTH, benchmark
from edeflare.eval.downstream import image_scores
from edeflare.eval.flare_score import flare_geometry
from edeflare.events import make_events
from edeflare.io import open_events
from edeflare.io.sequence import read_frames, write_sequence
from edeflare.recon.clips import BURN_IN, centre_image, intensity_to_image
from edeflare.recon.infer import Reconstructor
from edeflare.recon.network import FireNet
from edeflare.recon.weights import ReconCard, save_reconstructor
from edeflare.sim.optics_scene import OpticsSceneConfig

SMALL = dataclasses.replace(
    RECIPES["eflare-r-sim-mini"],
    name="small-r-sim",
    sequences=2,
    sensor_size=(64, 48),
    duration_us=80_000,
    config=OpticsSceneConfig(psf_grid=128),
)


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds")
    generate_dataset(SMALL, out, progress=False)
    return out / "test"


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    torch.manual_seed(1)
    path = tmp_path_factory.mktemp("w") / "r.safetensors"
    save_reconstructor(path, FireNet(), ReconCard())
    return path


def test_image_scores_by_hand():
    ref = np.full((16, 16), 0.5)
    assert image_scores(ref, ref) == (np.inf, pytest.approx(1.0))
    psnr, _ = image_scores(ref + 0.01, ref)  # MSE 1e-4 -> 40 dB
    assert psnr == pytest.approx(40.0)


def test_benchmark_scores_each_stream_against_the_frames_after_the_burn_in(split, weights):
    result = benchmark(split, {"raw": "raw", "pfd-a": "pfd-a"}, progress=False, downstream=weights)
    assert list(result.downstream) == ["raw", "pfd-a", GROUND_TRUTH]
    per_seq = 80_000 // 20_000 - BURN_IN
    assert all(d["windows"] == 2 * per_seq for d in result.downstream.values())
    # the raw row by hand: reconstruct the input window by window, score windows 2 and 3
    psnr, ssim, flare = [], [], []
    for path in sorted(split.glob("*.h5")):
        times, frames = read_frames(path)
        assert times.tolist() == [20_000, 40_000, 60_000, 80_000]
        rec = Reconstructor(weights)
        src = open_events(path, group="input")
        for k, (start, events) in enumerate(src.windows(20_000, start_us=0, end_us=80_000)):
            image = rec.step(events, (64, 48), start)
            if k >= BURN_IN:
                p, s = image_scores(
                    centre_image(image), centre_image(intensity_to_image(frames[k]))
                )
                psnr.append(p)
                ssim.append(s)
                clean = centre_image(intensity_to_image(frames[k]))
                _, annulus, _ = flare_geometry(clean).masks(clean.shape)
                flare.append(np.sqrt(np.mean((centre_image(image) - clean)[annulus] ** 2)))
    assert result.downstream["raw"]["psnr"] == pytest.approx(np.mean(psnr))
    assert result.downstream["raw"]["ssim"] == pytest.approx(np.mean(ssim))
    assert result.downstream["raw"]["flare"] == pytest.approx(np.mean(flare))
    assert "flare-region RMSE" in result.downstream_markdown()
    # PFD-A removes events, so its reconstruction differs from the input's
    assert result.downstream["pfd-a"] != result.downstream["raw"]
    assert "| ground truth |" in result.downstream_markdown()
    # the first sequence's images, kept for the report's animation
    sample = result.downstream_sample
    assert set(sample) == {"raw", "pfd-a", GROUND_TRUTH, "clean"}
    assert all(v.shape == (4, 48, 64) for v in sample.values())
    assert np.allclose(sample["clean"].mean(axis=(1, 2)), 0.5, atol=0.05)


def test_cli_benchmark_downstream_and_its_errors(split, weights, tmp_path, capsys):
    html = tmp_path / "html"
    argv = ["benchmark", str(split), "--methods", "raw", "--downstream", str(weights)]
    assert main([*argv, "--html", str(html), "--report", str(tmp_path / "t.md")]) == 0
    out = capsys.readouterr().out
    assert "Reconstruction (downstream)" in out and "| raw |" in out
    page = (html / "index.html").read_text()
    assert 'id="downstream"' in page and 'src="downstream.gif"' in page
    import imageio.v3 as iio

    assert iio.imread(html / "downstream.gif", index=None).shape[0] == 4  # windows of one seq
    saved = json.loads((tmp_path / "t.json").read_text())["benchmark"]["downstream"]
    assert set(saved) == {"raw", "ground truth"} and saved["raw"]["windows"] == 4
    # a split without frames (a real pair, a flare dataset) cannot be scored downstream
    bare = tmp_path / "bare"
    bare.mkdir()
    ev = make_events([10, 30_000], [1, 2], [1, 1], [1, 0])
    write_sequence(
        bare / "s.h5", {"input": ev, "gt": ev}, (8, 8), {"t_start_us": 0, "t_end_us": 60_000}
    )
    assert main(["benchmark", str(bare), "--methods", "raw", "--downstream", str(weights)]) == 1
    assert "no sequence holds clean frames" in capsys.readouterr().err


def test_cli_reconstruct_writes_one_frame_per_window(split, weights, tmp_path, capsys):
    import imageio.v3 as iio

    src = sorted(split.glob("*.h5"))[0]
    gif = tmp_path / "r.gif"
    argv = ["reconstruct", str(src), str(gif), "--weights", str(weights)]
    assert main(argv) == 1  # a sequence file holds several groups: say which
    assert "group" in capsys.readouterr().err
    assert main([*argv, "--group", "input"]) == 0
    frames = iio.imread(gif, index=None)
    last = int(open_events(src, group="input").read()["t"][-1])
    assert frames.shape[0] == last // 20_000 + 1 and frames.shape[1:3] == (48, 64)
    assert "frames)" in capsys.readouterr().out
    assert main(["reconstruct", str(src), str(tmp_path / "r.png"), "--group", "input"]) == 1
    assert not (tmp_path / "r.png").exists()
