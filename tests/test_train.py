"""Training: the loss falls, resume is exact, DDP (gloo) matches one process."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import torch

from conftest import random_events
from edeflare.errors import EdeflareError
from edeflare.events import merge_events
from edeflare.io.dsec import write_dsec_groups
from edeflare.models.weights import load_model
from edeflare.train import TrainConfig, train

SIZE = (16, 12)


@pytest.fixture
def dataset(tmp_path):
    """Six 60 ms sequences where the input is the ground truth plus a flickering blob."""
    rng = np.random.default_rng(5)
    for split, n in (("train", 6), ("test", 1)):
        (tmp_path / split).mkdir()
        for k in range(n):
            gt = random_events(rng, 300, SIZE, t0=0, span_us=60_000)
            blob = random_events(rng, 600, (4, 4), t0=0, span_us=60_000)
            blob["x"] += 10
            blob["y"] += 6
            streams = {"input": merge_events(gt, blob), "gt": gt}
            span = {"t_start_us": 0, "t_end_us": 60_000}
            write_dsec_groups(tmp_path / split / f"s{k}.h5", streams, SIZE, span)
    return tmp_path


def _config(**kw):
    base = TrainConfig(
        preset="unet2d.lite",
        iterations=12,
        batch_size=4,
        lr=3e-3,
        milestones=(),
        log_every=1,
        val_every=6,
        val_windows=2,
        checkpoint_every=4,
        seed=1,
    )
    return dataclasses.replace(base, **kw)


def _paths(root, split):
    return sorted((root / split).glob("*.h5"))


def _weights(path):
    return load_model(path)[0].state_dict()


def _log(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_training_lowers_the_loss_and_writes_everything(dataset, tmp_path):
    out = tmp_path / "run"
    final = train(
        _config(iterations=30),
        _paths(dataset, "train"),
        out,
        val_paths=_paths(dataset, "test"),
        progress=False,
    )
    rows = _log(out / "train_log.csv")
    assert [int(r["iteration"]) for r in rows] == list(range(1, 31))
    first = np.mean([float(r["loss"]) for r in rows[:5]])
    last = np.mean([float(r["loss"]) for r in rows[-5:]])
    assert last < 0.8 * first
    val = _log(out / "val_log.csv")
    assert [int(r["iteration"]) for r in val] == [6, 12, 18, 24, 30]
    assert float(val[-1]["val_mse"]) < float(val[-1]["input_mse"])  # beats the identity
    _, card = load_model(final)
    assert card.preset == "unet2d.lite" and card.metrics["iteration"] == 30
    assert (out / "best.safetensors").exists() and (out / "config.json").exists()


def test_keep_loss_teaches_a_mask_model_to_drop_the_blob_and_keep_the_rest(dataset, tmp_path):
    from edeflare.io.dsec import read_dsec
    from edeflare.models.infer import ModelDeflarer

    final = train(
        _config(preset="mask.lite", loss="keep", iterations=60, val_every=1000),
        _paths(dataset, "train"),
        tmp_path / "run",
        progress=False,
    )
    rows = _log(tmp_path / "run" / "train_log.csv")
    assert float(rows[0]["loss"]) == pytest.approx(-(np.log(0.75) + np.log(0.25)) / 2, abs=0.02)
    assert np.mean([float(r["loss"]) for r in rows[-10:]]) < 0.5  # well below the identity's
    test = _paths(dataset, "test")[0]
    inp, gt = read_dsec(test, "input")[0], read_dsec(test, "gt")[0]
    out = np.concatenate(
        [
            e
            for _, e in ModelDeflarer(final).windows(
                [(s, inp[(inp["t"] >= s) & (inp["t"] < s + 20_000)]) for s in (0, 20_000, 40_000)],
                SIZE,
            )
        ]
    )
    key = lambda ev: ev["t"].astype(np.int64) * 10_000 + ev["x"] * 100 + ev["y"]  # noqa: E731
    kept = np.isin(key(inp), key(out))
    is_gt = np.isin(key(inp), key(gt))
    far = (inp["x"] < 6) | (inp["y"] < 3)  # two pixels or more from the blob's cells
    assert kept[~is_gt].mean() < 0.3  # most of the blob goes
    assert kept[is_gt & far].mean() > 0.9  # the scene away from it stays


def test_keep_loss_needs_a_mask_preset_and_losses_are_checked(dataset, tmp_path):
    with pytest.raises(EdeflareError, match="loss 'keep' trains mask presets"):
        train(_config(loss="keep"), _paths(dataset, "train"), tmp_path / "a", progress=False)
    with pytest.raises(EdeflareError, match=r"unknown loss 'l1'; known: \['mse', 'keep'\]"):
        train(_config(loss="l1"), _paths(dataset, "train"), tmp_path / "b", progress=False)
    bad = _config(preset="mask.lite", loss="keep", keep_weight=1.0)
    with pytest.raises(EdeflareError, match=r"keep_weight must be in \(0, 1\), got 1.0"):
        train(bad, _paths(dataset, "train"), tmp_path / "c", progress=False)
    bad = _config(preset="mask.lite", loss="keep", keep_cells="pixel")
    with pytest.raises(EdeflareError, match="keep_cells must be 'bin' or 'window', got 'pixel'"):
        train(bad, _paths(dataset, "train"), tmp_path / "d", progress=False)


def test_init_starts_a_larger_preset_from_smaller_weights(dataset, tmp_path):
    from safetensors.torch import load_file

    from edeflare.models.weights import WeightsError

    fast = train(
        _config(preset="mask.fast", loss="keep", iterations=4, val_every=1000),
        _paths(dataset, "train"),
        tmp_path / "fast",
        progress=False,
    )
    # lr 0: the run's model is what it started from
    cfg = _config(preset="mask.pixel", loss="keep", iterations=2, val_every=1000, lr=0.0)
    final = train(
        dataclasses.replace(cfg, init=str(fast)),
        _paths(dataset, "train"),
        tmp_path / "pixel",
        progress=False,
    )
    before, after = load_file(str(fast)), load_file(str(final))
    assert set(after) - set(before) == {
        "pixel_gain", "pixel_in.bias", "pixel_in.weight", "pixel_out.bias", "pixel_out.weight"
    }  # fmt: skip
    assert all(torch.equal(before[k], after[k]) for k in before)
    assert not after["pixel_out.weight"].any()  # the new layers start fresh: the identity
    # freeze_init: only the new layers learn
    frozen = train(
        dataclasses.replace(cfg, init=str(fast), freeze_init=True, lr=3e-3, iterations=3),
        _paths(dataset, "train"),
        tmp_path / "frozen",
        progress=False,
    )
    tuned = load_file(str(frozen))
    assert all(torch.equal(before[k], tuned[k]) for k in before)
    assert tuned["pixel_out.weight"].any()
    with pytest.raises(EdeflareError, match="freeze_init needs init"):
        train(dataclasses.replace(cfg, freeze_init=True), _paths(dataset, "train"),
              tmp_path / "x", progress=False)  # fmt: skip
    lite = train(_config(iterations=1), _paths(dataset, "train"), tmp_path / "lite", progress=False)
    with pytest.raises(WeightsError, match="cannot start FlareMaskNet from these weights"):
        train(
            dataclasses.replace(cfg, init=str(lite)),
            _paths(dataset, "train"),
            tmp_path / "bad",
            progress=False,
        )


def test_resume_is_exact_and_logs_are_not_duplicated(dataset, tmp_path):
    cfg = _config()
    straight = train(cfg, _paths(dataset, "train"), tmp_path / "a", progress=False)
    # Stop after 8 iterations (a checkpoint at 8), then rerun to 12 in the same folder.
    train(
        dataclasses.replace(cfg, iterations=8),
        _paths(dataset, "train"),
        tmp_path / "b",
        progress=False,
    )
    # Simulate a kill after iteration 10: log rows beyond the checkpoint exist.
    with open(tmp_path / "b" / "train_log.csv", "a") as f:
        f.write("9,0,0.003,1.0,0\n10,0,0.003,1.0,0\n")
    resumed = train(cfg, _paths(dataset, "train"), tmp_path / "b", progress=False)
    a, b = _weights(straight), _weights(resumed)
    assert all(torch.equal(a[k], b[k]) for k in a)
    iterations = [int(r["iteration"]) for r in _log(tmp_path / "b" / "train_log.csv")]
    assert iterations == list(range(1, 13))


def test_a_time_limit_stops_checkpointed_and_a_rerun_ends_as_the_straight_run(
    dataset, tmp_path, capsys
):
    cfg = _config()
    straight = train(cfg, _paths(dataset, "train"), tmp_path / "a", progress=False)
    # A budget of zero minutes: the first iteration spends it, so the run stops after it.
    limited = train(
        dataclasses.replace(cfg, time_limit_min=0.0),
        _paths(dataset, "train"),
        tmp_path / "b",
        progress=False,
    )
    assert "time limit of 0 min reached at iteration 1 of 12" in capsys.readouterr().err
    assert load_model(limited)[1].metrics == {"iteration": 1}
    assert torch.load(tmp_path / "b" / "checkpoint.pt", weights_only=True)["iteration"] == 1
    resumed = train(cfg, _paths(dataset, "train"), tmp_path / "b", progress=False)
    a, b = _weights(straight), _weights(resumed)
    assert all(torch.equal(a[k], b[k]) for k in a)
    iterations = [int(r["iteration"]) for r in _log(tmp_path / "b" / "train_log.csv")]
    assert iterations == list(range(1, 13))


def test_the_cli_says_where_a_time_limit_stopped_it(dataset, tmp_path, capsys):
    from edeflare.cli import main

    args = ["train", str(dataset), "--preset", "unet2d.tiny", "--iterations", "12"]
    args += ["--batch-size", "2", "--crop", "8x8", "--out", str(tmp_path / "r")]
    assert main([*args, "--time-limit", "0"]) == 0
    assert "trained unet2d.tiny for 1 of 12 (time limit) iterations" in capsys.readouterr().out
    assert main(args) == 0  # the rerun resumes and finishes
    assert "trained unet2d.tiny for 12 iterations" in capsys.readouterr().out


def test_several_data_folders_train_as_one_folder_of_prefixed_links(dataset, tmp_path):
    """``edeflare train DAY NIGHT`` sees the windows in the order a MIX folder holding
    ``day_*`` and ``night_*`` links to their files gives (names sorted)."""
    from edeflare.cli import main

    folders = {"day": ["s0.h5", "s1.h5", "s2.h5"], "night": ["s3.h5", "s4.h5", "s5.h5"]}
    for name, files in folders.items():
        for split, kept in (("train", files), ("test", ["s0.h5"])):
            (tmp_path / name / split).mkdir(parents=True)
            (tmp_path / "mix" / split).mkdir(parents=True, exist_ok=True)
            for f in kept:
                (tmp_path / name / split / f).symlink_to(dataset / split / f)
                (tmp_path / "mix" / split / f"{name}_{f}").symlink_to(dataset / split / f)
    args = ["--preset", "unet2d.tiny", "--iterations", "6", "--batch-size", "2"]
    args += ["--crop", "8x8", "--val-every", "3", "--val-windows", "3", "--checkpoint-every", "3"]
    assert main(["train", str(tmp_path / "mix"), "--out", str(tmp_path / "a"), *args]) == 0
    day, night = str(tmp_path / "day"), str(tmp_path / "night")
    assert main(["train", day, night, "--out", str(tmp_path / "b"), *args]) == 0
    a = _weights(tmp_path / "a" / "model.safetensors")
    b = _weights(tmp_path / "b" / "model.safetensors")
    for (name, x), y in zip(a.items(), b.values(), strict=True):
        assert torch.equal(x, y), name
    val_a, val_b = _log(tmp_path / "a" / "val_log.csv"), _log(tmp_path / "b" / "val_log.csv")
    assert [r["val_mse"] for r in val_a] == [r["val_mse"] for r in val_b]
    assert json.loads((tmp_path / "b" / "config.json").read_text())["data"] == f"{day} {night}"
    # the other order is another sample order: another model
    assert main(["train", night, day, "--out", str(tmp_path / "c"), *args]) == 0
    c = _weights(tmp_path / "c" / "model.safetensors")
    assert not all(torch.equal(x, y) for x, y in zip(a.values(), c.values(), strict=True))


def test_a_data_folder_without_training_files_is_a_one_line_error(dataset, tmp_path, capsys):
    from edeflare.cli import main

    (tmp_path / "empty").mkdir()
    argv = ["train", str(dataset), str(tmp_path / "empty"), "--out", str(tmp_path / "r")]
    assert main(argv) == 1
    assert "empty/train: no such dataset folder" in capsys.readouterr().err


def test_resume_keeps_the_best_score_and_the_clock(dataset, tmp_path):
    cfg = _config(iterations=12)
    out = tmp_path / "r"
    val = _paths(dataset, "test")
    train(
        dataclasses.replace(cfg, iterations=6),
        _paths(dataset, "train"),
        out,
        val_paths=val,
        progress=False,
    )
    best_before = load_model(out / "best.safetensors")[1].metrics
    seconds_before = float(_log(out / "train_log.csv")[-1]["seconds"])
    state = torch.load(out / "checkpoint.pt", weights_only=True)
    assert state["best_val_mse"] == pytest.approx(best_before["val_mse"])
    train(cfg, _paths(dataset, "train"), out, val_paths=val, progress=False)
    rows = _log(out / "train_log.csv")
    seconds = [float(r["seconds"]) for r in rows]
    assert seconds == sorted(seconds) and seconds[6] >= seconds_before  # the clock goes on
    # best.safetensors holds the lowest validation MSE over both parts of the run
    scores = {int(r["iteration"]): float(r["val_mse"]) for r in _log(out / "val_log.csv")}
    best = load_model(out / "best.safetensors")[1].metrics
    assert best["val_mse"] == pytest.approx(min(scores.values()))
    assert best["iteration"] == min(scores, key=scores.get)


def test_resume_refuses_another_configuration(dataset, tmp_path):
    train(_config(iterations=4), _paths(dataset, "train"), tmp_path / "r", progress=False)
    with pytest.raises(EdeflareError, match=r"other values of \['lr'\]"):
        train(
            _config(iterations=8, lr=1e-4), _paths(dataset, "train"), tmp_path / "r", progress=False
        )


def test_data_loader_workers_and_precompute_give_the_same_model(dataset, tmp_path):
    a = train(_config(iterations=4), _paths(dataset, "train"), tmp_path / "a", progress=False)
    b = train(
        _config(iterations=4, num_workers=2),
        _paths(dataset, "train"),
        tmp_path / "b",
        progress=False,
    )
    c = train(
        _config(iterations=4, precompute=True),
        _paths(dataset, "train"),
        tmp_path / "c",
        progress=False,
    )
    wa, wb, wc = _weights(a), _weights(b), _weights(c)
    assert all(torch.equal(wa[k], wb[k]) and torch.equal(wa[k], wc[k]) for k in wa)


def test_sequences_of_several_sensor_sizes_train_with_a_crop(dataset, tmp_path):
    rng = np.random.default_rng(8)
    big = (24, 20)
    for k in range(2):  # two more training sequences on a larger sensor
        gt = random_events(rng, 300, big, t0=0, span_us=60_000)
        streams = {"input": merge_events(gt, random_events(rng, 100, big, 0, 60_000)), "gt": gt}
        span = {"t_start_us": 0, "t_end_us": 60_000}
        write_dsec_groups(dataset / "train" / f"big{k}.h5", streams, big, span)
    paths = _paths(dataset, "train")
    with pytest.raises(EdeflareError, match=r"several sensor sizes \(16x12, 24x20\): give a crop "
                       r"no larger than 12x16"):  # fmt: skip
        train(_config(), paths, tmp_path / "a", progress=False)
    final = train(_config(crop=(8, 12), iterations=4), paths, tmp_path / "b", progress=False)
    assert final.is_file() and len(_log(tmp_path / "b" / "train_log.csv")) == 4


def test_time_shift_is_a_recorded_option_that_changes_what_is_seen(dataset, tmp_path):
    paths = _paths(dataset, "train")
    plain = train(_config(iterations=4), paths, tmp_path / "a", progress=False)
    shifted = train(_config(iterations=4, time_shift=True), paths, tmp_path / "b", progress=False)
    assert json.loads((tmp_path / "b" / "config.json").read_text())["time_shift"] is True
    wa, wb = _weights(plain), _weights(shifted)
    assert any(not torch.equal(wa[k], wb[k]) for k in wa)
    with pytest.raises(EdeflareError, match=r"other values of \['time_shift'\]"):
        train(_config(iterations=8), paths, tmp_path / "b", progress=False)


def test_polarity_flip_is_a_recorded_option_that_changes_what_is_seen(dataset, tmp_path):
    paths = _paths(dataset, "train")
    plain = train(_config(iterations=4), paths, tmp_path / "a", progress=False)
    flipped = train(
        _config(iterations=4, polarity_flip=True), paths, tmp_path / "b", progress=False
    )
    assert json.loads((tmp_path / "b" / "config.json").read_text())["polarity_flip"] is True
    wa, wb = _weights(plain), _weights(flipped)
    assert any(not torch.equal(wa[k], wb[k]) for k in wa)
    with pytest.raises(EdeflareError, match=r"other values of \['polarity_flip'\]"):
        train(_config(iterations=8), paths, tmp_path / "b", progress=False)


def test_too_little_data_is_a_clear_error(dataset, tmp_path):
    with pytest.raises(EdeflareError, match="fewer than one global batch"):
        train(_config(batch_size=64), _paths(dataset, "train"), tmp_path / "x", progress=False)


@pytest.mark.slow
def test_ddp_with_two_gloo_processes_matches_one_process(dataset, tmp_path):
    common = [
        str(dataset),
        "--config",
        "cpu",
        "--preset",
        "unet2d.lite",
        "--iterations",
        "4",
        "--lr",
        "0.003",
        "--seed",
        "1",
        "--val-every",
        "100",
        "--checkpoint-every",
        "100",
    ]
    crop = ["--crop", "8x8"]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    subprocess.run(
        [
            sys.executable,
            "-m",
            "edeflare",
            "train",
            *common,
            *crop,
            "--batch-size",
            "4",
            "--out",
            str(tmp_path / "one"),
        ],
        check=True,
        env=env,
        capture_output=True,
    )
    subprocess.run(
        [
            sys.executable,
            "-m",
            "torch.distributed.run",
            "--standalone",
            "--nproc_per_node",
            "2",
            "-m",
            "edeflare",
            "train",
            *common,
            *crop,
            "--batch-size",
            "2",
            "--out",
            str(tmp_path / "two"),
        ],
        check=True,
        env=env,
        capture_output=True,
    )
    a = _weights(tmp_path / "one" / "model.safetensors")
    b = _weights(tmp_path / "two" / "model.safetensors")
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=1e-4, atol=1e-5)
    moved = any(not torch.equal(a[k], torch.zeros_like(a[k])) for k in a if "final" in k)
    assert moved  # training did change the zero-initialised last layer


def test_csv_append_drops_a_torn_last_line(tmp_path):
    from edeflare.train import _append_csv, _truncate_csv

    log = tmp_path / "train_log.csv"
    _append_csv(log, ["iteration", "loss"], [1, 0.5])
    _append_csv(log, ["iteration", "loss"], [2, 0.25])
    with open(log, "a") as f:
        f.write("3,0.1")  # killed in the middle of a row: no newline
    _append_csv(log, ["iteration", "loss"], [3, 0.125])
    assert log.read_text() == "iteration,loss\n1,0.5\n2,0.25\n3,0.125\n"
    with open(log, "a") as f:
        f.write("4,0.0")
    _truncate_csv(log, 10)  # a resume drops the torn row too
    assert log.read_text() == "iteration,loss\r\n1,0.5\r\n2,0.25\r\n3,0.125\r\n".replace("\r", "")


def test_checkpoint_holds_the_grad_scaler_state(tmp_path):
    """AMP's loss scale and growth tracker round-trip through the checkpoint (weights_only load)."""
    from edeflare.models import create_model
    from edeflare.train import _save_checkpoint

    model = create_model("unet2d.lite")
    opt = torch.optim.Adam(model.parameters())
    scaler = torch.amp.GradScaler("cpu", init_scale=512.0, growth_interval=7)
    scaler.scale(torch.ones(1))  # initialises the scale, as the first step does
    scaler.update(new_scale=128.0)
    path = tmp_path / "checkpoint.pt"
    _save_checkpoint(path, model, opt, 3, _config(), 0.5, 1.0, scaler)
    state = torch.load(path, weights_only=True)
    resumed = torch.amp.GradScaler("cpu", init_scale=65536.0, growth_interval=7)
    resumed.load_state_dict(state["scaler"])
    assert resumed.get_scale() == 128.0
    assert resumed.state_dict() == scaler.state_dict()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="AMP resume needs a CUDA device")
def test_amp_resume_continues_the_loss_scale_on_gpu(dataset, tmp_path):
    """Resumed at 8, a GPU run ends with the straight run's loss scale, not a reset one."""
    config = _config(amp=True, device="cuda")
    paths = _paths(dataset, "train")
    train(config, paths, tmp_path / "once", progress=False)
    part = tmp_path / "twice"
    train(dataclasses.replace(config, iterations=8), paths, part, progress=False)
    assert torch.load(part / "checkpoint.pt", weights_only=True)["scaler"]["scale"] > 0
    train(config, paths, part, progress=False)
    once = torch.load(tmp_path / "once" / "checkpoint.pt", weights_only=True)["scaler"]
    twice = torch.load(part / "checkpoint.pt", weights_only=True)["scaler"]
    assert once == twice


@pytest.mark.slow
def test_a_run_killed_with_sigkill_resumes_to_the_straight_runs_model(dataset, tmp_path):
    import signal
    import time

    args = ["train", str(dataset), "--preset", "unet2d.tiny", "--iterations", "200"]
    args += ["--batch-size", "2", "--crop", "8x8", "--checkpoint-every", "5", "--seed", "3"]
    straight = subprocess.run(
        [sys.executable, "-m", "edeflare", *args, "--out", str(tmp_path / "a")],
        capture_output=True,
        text=True,
    )
    assert straight.returncode == 0, straight.stderr
    run = tmp_path / "b"
    child = subprocess.Popen(
        [sys.executable, "-m", "edeflare", *args, "--out", str(run)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while not (run / "checkpoint.pt").exists() and time.monotonic() < deadline:
        time.sleep(0.005)
    os.kill(child.pid, signal.SIGKILL)  # just after a checkpoint, or while writing the next
    child.wait()
    assert child.returncode == -signal.SIGKILL
    assert not (run / "model.safetensors").exists()  # it was killed before the end
    resumed = subprocess.run(
        [sys.executable, "-m", "edeflare", *args, "--out", str(run)], capture_output=True, text=True
    )
    assert resumed.returncode == 0, resumed.stderr
    a, b = _weights(tmp_path / "a" / "model.safetensors"), _weights(run / "model.safetensors")
    assert all(torch.equal(a[k], b[k]) for k in a)
    rows = _log(run / "train_log.csv")
    assert [int(r["iteration"]) for r in rows] == list(range(10, 201, 10))  # no row twice
