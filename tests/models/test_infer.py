"""Model inference: both decoders, batching independence, determinism, bad weights."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from conftest import random_events, same_events
from edeflare.errors import EdeflareError
from edeflare.events import iter_time_windows, make_events
from edeflare.io import read_events, write_events
from edeflare.methods import create_method, deflare_file
from edeflare.models import create_model
from edeflare.models.infer import ModelDeflarer, _full_precision, bundled_weights
from edeflare.models.weights import ModelCard, WeightsError, save_model
from edeflare.voxel import decode_keep, encode

SIZE = (24, 16)


@pytest.fixture
def identity_weights(tmp_path):
    path = tmp_path / "id.safetensors"
    save_model(path, create_model("unet2d.tiny"), ModelCard(preset="unet2d.tiny"))
    return path


def test_identity_model_with_keep_decoder_returns_the_input_exactly(identity_weights, rng):
    ev = random_events(rng, 2000, SIZE, t0=0, span_us=100_000)
    deflarer = ModelDeflarer(identity_weights, decoder="keep", batch_windows=3)
    out = list(deflarer.windows(iter_time_windows(ev, 20_000), SIZE))
    assert [s for s, _ in out] == [0, 20_000, 40_000, 60_000, 80_000]
    assert same_events(np.concatenate([e for _, e in out]), ev)


def test_paper_decoder_keeps_cell_counts_not_times(identity_weights, rng):
    ev = random_events(rng, 2000, SIZE, t0=0, span_us=20_000)
    ((_, out),) = ModelDeflarer(identity_weights, decoder="paper").windows([(0, ev)], SIZE)
    np.testing.assert_array_equal(
        encode(out, SIZE, 0, 20_000), np.rint(encode(ev, SIZE, 0, 20_000))
    )
    assert not np.array_equal(out["t"], ev["t"])


def test_batching_and_resuming_do_not_change_the_output(identity_weights, rng):
    ev = random_events(rng, 3000, SIZE, t0=0, span_us=100_000)
    wins = list(iter_time_windows(ev, 20_000))
    one = list(
        ModelDeflarer(identity_weights, decoder="paper", batch_windows=1).windows(wins, SIZE)
    )
    four = list(
        ModelDeflarer(identity_weights, decoder="paper", batch_windows=4).windows(wins, SIZE)
    )
    tail = list(ModelDeflarer(identity_weights, decoder="paper").windows(wins[2:], SIZE))
    assert all(same_events(a, b) for (_, a), (_, b) in zip(one, four, strict=True))
    assert all(same_events(a, b) for (_, a), (_, b) in zip(one[2:], tail, strict=True))


def test_keep_decoder_keeps_a_subset_and_adds_only_what_the_grid_adds(rng):
    ev = random_events(rng, 3000, SIZE, t0=0, span_us=20_000)
    grid = encode(ev, SIZE, 0, 20_000)
    restored = grid.copy()
    restored[:, :8, :] = 0  # the model removes everything in the top rows
    restored[:, 15, 23] += 3  # and adds three ON events in one pixel per bin
    out = decode_keep(restored, ev, 0, 20_000, rng=1)
    np.testing.assert_array_equal(encode(out, SIZE, 0, 20_000), restored)
    keys = set(map(tuple, ev[["t", "x", "y", "p"]].tolist()))
    kept = [tuple(e) for e in out[["t", "x", "y", "p"]].tolist() if not (e[1] == 23 and e[2] == 15)]
    assert all(k in keys for k in kept)  # every event elsewhere is an input event
    # In the cleared rows only ON/OFF pairs that cancel in the signed grid survive.
    from edeflare.voxel import encode_polarity

    pol = encode_polarity(out, SIZE, 0, 20_000)[:, :, :8, :]
    np.testing.assert_array_equal(pol[0], pol[1])
    pol_in = encode_polarity(ev, SIZE, 0, 20_000)[:, :, :8, :]
    assert (out["y"] < 8).sum() == 2 * np.minimum(pol_in[0], pol_in[1]).sum()
    again = decode_keep(restored, ev, 0, 20_000, rng=1)
    assert same_events(out, again)


def test_keep_decoder_thins_cells_uniformly(rng):
    # 400 ON events in one cell; the grid keeps 100: a random subset spread over the bin.
    t = np.sort(rng.integers(0, 2500, 400))
    from edeflare.events import make_events

    ev = make_events(t, np.zeros(400, int), np.zeros(400, int), np.ones(400, int))
    grid = encode(ev, (1, 1), 0, 20_000)
    grid[0, 0, 0] = 100
    out = decode_keep(grid, ev, 0, 20_000, rng=0)
    assert len(out) == 100 and np.isin(out["t"], t).all()
    assert 800 < out["t"].mean() < 1700  # not the first 100 events (mean ~ 300)


def test_bad_configuration(identity_weights, tmp_path):
    with pytest.raises(EdeflareError, match="decoder must be one of"):
        ModelDeflarer(identity_weights, decoder="nearest")
    with pytest.raises(EdeflareError, match="batch_windows"):
        ModelDeflarer(identity_weights, batch_windows=0)
    with pytest.raises(WeightsError, match="no such weights file"):
        ModelDeflarer(tmp_path / "missing.safetensors")
    with pytest.raises(EdeflareError, match="no bundled model 'nope'"):
        bundled_weights("nope")


def test_model_method_streams_files_like_one_pass(identity_weights, tmp_path, rng):
    from edeflare.io import read_events, write_events
    from edeflare.methods import create_method, deflare_file

    ev = random_events(rng, 4000, SIZE, t0=1_000_000, span_us=150_000)
    write_events(tmp_path / "in.h5", ev, SIZE)
    stats = deflare_file(
        tmp_path / "in.h5",
        tmp_path / "out.npz",
        "model",
        params={"weights": identity_weights},
        progress=False,
    )
    out, size = read_events(tmp_path / "out.npz")
    assert size == SIZE and stats.events_in == stats.events_out == ev.size
    assert same_events(out, ev)  # identity model + keep decoder: the input itself
    paper = create_method("model", weights=identity_weights, decoder="paper")
    one_pass = paper(ev, SIZE, rng=3)
    deflare_file(tmp_path / "in.h5", tmp_path / "p.h5", paper, rng=3, progress=False)
    assert same_events(read_events(tmp_path / "p.h5").events, one_pass)


def test_cli_deflare_with_a_model(identity_weights, tmp_path, rng, capsys):
    from edeflare.cli import main
    from edeflare.io import read_events, write_events

    ev = random_events(rng, 1000, SIZE, t0=0, span_us=60_000)
    write_events(tmp_path / "in.h5", ev, SIZE)
    argv = [
        "deflare",
        str(tmp_path / "in.h5"),
        str(tmp_path / "out.h5"),
        "--model",
        str(identity_weights),
        "--decoder",
        "keep",
        "--batch-windows",
        "2",
    ]
    assert main(argv) == 0
    assert same_events(read_events(tmp_path / "out.h5").events, ev)
    assert "model: 1,000 events in, 1,000 out" in capsys.readouterr().out
    bad = [
        "deflare",
        str(tmp_path / "in.h5"),
        str(tmp_path / "x.h5"),
        "-m",
        "efr",
        "--decoder",
        "paper",
    ]
    assert main(bad) == 1
    assert "--decoder applies to --method model" in capsys.readouterr().err
    foreign = tmp_path / "foreign.safetensors"
    foreign.write_bytes(b"\x80\x04not a safetensors file")
    assert (
        main(["deflare", str(tmp_path / "in.h5"), str(tmp_path / "y.h5"), "--model", str(foreign)])
        == 1
    )
    assert "only loads safetensors" in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "y.h5").exists()


@pytest.fixture
def adding_weights(tmp_path):
    """A model that adds one ON event to every cell of every bin (final bias 1)."""
    model = create_model("unet2d.tiny")
    with torch.no_grad():
        model.final.bias.fill_(1.0)
    path = tmp_path / "add.safetensors"
    save_model(path, model, ModelCard(preset="unet2d.tiny"))
    return path


def test_no_event_is_synthesised_outside_the_recordings_span(adding_weights, tmp_path):
    size = (16, 12)
    # a recording from 27 ms to 52.5 ms: windows [20, 40) and [40, 60) ms are partial
    ev = make_events([27_000, 35_000, 52_499], [0, 1, 2], [0, 1, 2], [1, 0, 1])
    method = create_method("model", weights=adding_weights)
    out = method(ev, size)
    assert out["t"].min() >= 27_000 and out["t"].max() <= 52_499
    # bins of 2.5 ms: [20, 40) ms keeps bins 2..7 (bin 2 = [25, 27.5) ms partly), [40, 60)
    # ms keeps bins 0..5 (bin 5 = [52.5, 55) ms lies after the last event: dropped)
    per_bin = encode(out, size, 20_000, 40_000, bins=16) - encode(ev, size, 20_000, 40_000, 16)
    added = per_bin.sum(axis=(1, 2))
    assert (added[:2] == 0).all() and (added[13:] == 0).all()  # outside [27, 52.5) ms
    assert (added[3:13] == 192).all()  # one per pixel in every bin inside
    assert 0.1 < added[2] / 192 < 0.3  # the partial bin: the fifth drawn after 27 ms
    # streamed from a file (windows arrive one at a time): the same output
    src, dst = tmp_path / "in.npz", tmp_path / "out.npz"
    write_events(src, ev, size)
    deflare_file(src, dst, "model", params={"weights": adding_weights}, progress=False)
    assert same_events(read_events(dst).events, out)
    # without a span (interior windows) every bin gets its events
    deflarer = ModelDeflarer(adding_weights)
    ((_, inner),) = deflarer.windows([(20_000, ev[:2])], size)
    # +1 per cell: the OFF event's cell cancels to 0 (removed), all others gain one ON
    assert len(inner) == 8 * 192 and 35_000 not in inner["t"]


def test_the_model_method_takes_a_bundled_model_by_name(monkeypatch, identity_weights):
    from edeflare.models import infer

    assets = identity_weights.parent
    monkeypatch.setattr(infer, "_ASSETS", assets)
    (assets / "night.safetensors").write_bytes(identity_weights.read_bytes())
    method = create_method("model", weights="night")
    assert method.params["weights"] == str(assets / "night.safetensors")
    with pytest.raises(EdeflareError, match="no bundled model 'dusk'"):
        create_method("model", weights="dusk")


@pytest.mark.parametrize("model", ["night", "eflare"])
def test_warm_up_changes_no_output(model, rng):
    events = random_events(rng, 20_000, (64, 48), t0=5_000, span_us=90_000)
    windows = list(iter_time_windows(events, 20_000))
    # without the light-free shift, which keeps every event of these light-free windows
    cold = ModelDeflarer(bundled_weights(model), batch_windows=3, light_free_shift=0.0)
    warm = ModelDeflarer(bundled_weights(model), batch_windows=3, light_free_shift=0.0)
    warm.warm_up((64, 48))
    a = list(cold.windows(windows, (64, 48)))
    b = list(warm.windows(windows, (64, 48)))
    assert [s for s, _ in a] == [s for s, _ in b]
    assert all(same_events(x, y) for (_, x), (_, y) in zip(a, b, strict=True))
    assert 0 < sum(e.size for _, e in b) < events.size  # a real model, really deciding


def test_warm_up_windows_hold_a_light_then_none():
    # so the warm-up loads the rules of both kinds of window (lights, light-free)
    from edeflare.lights.cells import window_lights
    from edeflare.models.infer import _warm_up_windows

    for size in ((64, 48), (346, 260), (8, 6), (3, 3)):
        windows = _warm_up_windows(size, 20_000, 3)
        assert [s for s, _ in windows] == [0, 20_000, 40_000]
        assert windows[-1][1].size == 65_536  # the counts' int32 variant compiles too
        for start, ev in windows:
            assert ev.size and (np.diff(ev["t"]) >= 0).all()
            assert (ev["t"] >= start).all() and (ev["t"] < start + 20_000).all()
            assert (ev["x"] < size[0]).all() and (ev["y"] < size[1]).all()
            assert not ev["t"].flags.c_contiguous  # strided, as a real window's fields
        lit = [bool(window_lights(ev, size, 20_000).any()) for _, ev in windows]
        # a 3x3 sensor holds no light: thinner than MIN_LIGHT_RADIUS (the last window's
        # 65,536 events may fill a small sensor as a light does)
        assert lit[:2] == ([True, False] if size != (3, 3) else [False, False])


_COMPILED_AFTER_WARM_UP = r"""
import sys, numba, numpy as np
from edeflare.events import make_events
from edeflare.models.infer import ModelDeflarer, bundled_weights

def signatures():
    return {
        f"{name}.{attr}": len(f.signatures)
        for name, module in list(sys.modules.items()) if name.startswith("edeflare")
        for attr, f in vars(module).items() if isinstance(f, numba.core.registry.CPUDispatcher)
    }

rng = np.random.default_rng(0)
def window(n, t0):  # n events over 20 ms
    return make_events(t0 + np.sort(rng.integers(0, 20_000, n)), rng.integers(0, 64, n),
                       rng.integers(0, 48, n), rng.integers(0, 2, n))
d = ModelDeflarer(bundled_weights("night"))
streamer = d.streamer((64, 48))  # warms up
before = signatures()
streamer.process(window(4000, 0), 20_000)  # small windows, then one of 70 k events
streamer.process(window(4000, 20_000), 40_000)
streamer.process(window(70_000, 40_000), 60_000)
streamer.flush()
after = signatures()
print({k: (before.get(k, 0), v) for k, v in after.items() if v != before.get(k, 0)})
"""


def test_warm_up_compiles_every_kernel_a_real_window_needs():
    # a window's fields are strided views of the structured events; numba compiles a
    # separate kernel for contiguous ones (one event's): a warm-up on single events
    # left every kernel to compile inside the first real window (about 0.5 s)
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-c", _COMPILED_AFTER_WARM_UP], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "{}"


def test_cuda_networks_run_in_full_precision_and_restore_the_flags():
    # On an H200, cuDNN's defaults moved the default model's logits by up to 6e-3 from
    # the CPU's, and 2-16 events of a real recording changed side of the threshold
    # (docs/studies.md, "gpu-default"). The flags are process-wide: they must come back.
    cudnn = torch.backends.cudnn
    before = (cudnn.enabled, cudnn.benchmark, cudnn.deterministic, cudnn.allow_tf32)
    with _full_precision(torch.device("cuda")):
        assert (cudnn.deterministic, cudnn.allow_tf32, cudnn.benchmark) == (True, False, False)
        assert cudnn.enabled == before[0]
    assert (cudnn.enabled, cudnn.benchmark, cudnn.deterministic, cudnn.allow_tf32) == before
    with _full_precision(torch.device("cpu")):  # elsewhere: nothing changes
        assert (cudnn.enabled, cudnn.benchmark, cudnn.deterministic, cudnn.allow_tf32) == before
