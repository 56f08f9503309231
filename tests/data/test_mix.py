"""Mixes: each part a dataset of its own, one manifest over them; resume, shards, training."""

from __future__ import annotations

import csv
import dataclasses
import json
import signal
import sys
from pathlib import Path

import h5py
import pytest
import torch
from test_generate import TINY, digests

from conftest import alive, sigkill_main_process
from edeflare.cli import main
from edeflare.data.folders import dataset_files, dataset_folders, sequence_files
from edeflare.data.generate import RECIPES, Mix, Recipe, generate_dataset
from edeflare.errors import EdeflareError
from edeflare.io.sequence import file_sha256
from edeflare.models.weights import load_model
from edeflare.train import TRAIN_PRESETS, train

# eflare-mix's five parts as they are, two sequences of 20 ms each at 48x36.
TINY_MIX = RECIPES["eflare-mix"].replace(
    sequences=2, test_sequences=1, sensor_size=(48, 36), duration_us=20_000
)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """TINY_MIX generated once, uninterrupted, in this process."""
    out = tmp_path_factory.mktemp("mix")
    return out, generate_dataset(TINY_MIX, out, progress=False)


def test_each_part_is_the_dataset_its_recipe_makes(reference, tmp_path):
    out, report = reference
    m = report.manifest
    assert (report.generated, report.skipped) == (10, 0) and m["complete"]
    assert report.manifest_path == out / "manifest.json"
    assert m["format"] == "edeflare-mix/1" and m["mix_sha256"] == TINY_MIX.sha256()
    assert [p["folder"] for p in m["parts"]] == list(TINY_MIX.part_names)
    assert m["splits"] == {"train": {"sequences": 5, "windows": 5},
                           "test": {"sequences": 5, "windows": 5}}  # fmt: skip
    for part in m["parts"]:
        recipe = TINY_MIX.part(part["name"])
        assert part["recipe"] == recipe.name == f"eflare-mix.{part['name']}"
        assert part["recipe_sha256"] == recipe.sha256()
        assert part["manifest_sha256"] == file_sha256(out / part["folder"] / "manifest.json")
        assert sorted(p.relative_to(out / part["folder"]).as_posix()
                      for p in (out / part["folder"]).rglob("*.h5")) == [
            "test/seq_00001.h5", "train/seq_00000.h5"]  # fmt: skip
    # byte for byte what generating the part alone writes (here: one 640x480 forward part)
    alone = generate_dataset(TINY_MIX.part("dense-640"), tmp_path, progress=False)
    assert digests(tmp_path) == digests(out / "dense-640")
    assert alone.manifest_path.read_bytes() == (out / "dense-640" / "manifest.json").read_bytes()
    with h5py.File(out / "dense-640" / "train" / "seq_00000.h5") as f:
        assert f.attrs["variant"] == "forward" and set(f) == {"input", "gt"}
    with h5py.File(out / "night-346" / "train" / "seq_00000.h5") as f:
        assert {"input", "gt", "gt_full", "flare"} <= set(f)  # eflare-night's own layout


def test_the_gaps_mix_stores_the_scene_alone_beside_dense_and_dim_flare(tmp_path):
    # eflare-gaps exists for what eflare-mix's files lack: the scene without the light
    # (a "background" stream) under dense forward-model flare, and dim sparse streets
    gaps = RECIPES["eflare-gaps"].replace(
        sequences=1, test_sequences=0, sensor_size=(48, 36), duration_us=20_000
    )
    assert gaps.part_names == ("dense-640", "sparse-346")
    assert RECIPES["eflare-gaps"].part("dense-640").sensor_size == (640, 480)
    assert gaps.part("sparse-346").scene == RECIPES["eflare-night-sparse"].scene
    generate_dataset(gaps, tmp_path, progress=False)
    with h5py.File(tmp_path / "dense-640" / "train" / "seq_00000.h5") as f:
        assert f.attrs["variant"] == "forward" and {"input", "gt", "background"} <= set(f)
    with h5py.File(tmp_path / "sparse-346" / "train" / "seq_00000.h5") as f:
        assert {"input", "gt", "background"} <= set(f)
    # seeds no other recipe uses: its sequences are not eflare-mix's or a test set's
    seeds = {r.seed for r in _other_recipes("eflare-gaps")}
    assert not {r.seed for _, r in RECIPES["eflare-gaps"].parts} & seeds


def test_the_day_mix_stores_day_streets_at_the_larger_sensors(tmp_path):
    # eflare-day: day streets at 640x480 and 1280x720 (eflare-mix's are night streets
    # there), under eflare-night's weak lights and the forward model's strong sources,
    # the scene alone stored in every part
    full = RECIPES["eflare-day"]
    assert full.part_names == ("day-640", "day-1280", "dense-day-640", "dense-day-1280",
                               "drive-640", "drive-1280")  # fmt: skip
    assert [full.part(n).sensor_size for n in full.part_names] == [
        (640, 480), (1280, 720), (640, 480), (1280, 720), (640, 480), (1280, 720)]  # fmt: skip
    day_scene = RECIPES["eflare-day-street"].scene
    assert full.part("day-640").scene == day_scene
    assert full.part("day-1280").scene.sky_level == day_scene.sky_level
    assert full.part("day-1280").scene.pan_px_per_s == (30.0, 300.0)  # x1.5 at 1280x720
    assert full.part("dense-day-640").config.variant == "forward"
    # driving: the same street expanding faster than any other street
    assert full.part("drive-640").scene.zoom_per_s == (1.0, 3.0)
    assert full.part("drive-640").scene.sky_level == day_scene.sky_level
    assert full.part("drive-1280").scene.pan_px_per_s == (0.0, 120.0)
    assert max(r.scene.zoom_per_s[1] for r in _other_recipes("eflare-day")) <= 0.8
    assert full.part("drive-640").config.variant == "forward"
    assert full.part("drive-1280").config.variant != "forward"
    small = full.replace(sequences=1, test_sequences=0, sensor_size=(48, 36), duration_us=20_000)
    generate_dataset(small, tmp_path, progress=False)
    for part in full.part_names:
        with h5py.File(tmp_path / part / "train" / "seq_00000.h5") as f:
            assert {"input", "gt", "background"} <= set(f), part
    assert not {r.seed for _, r in full.parts} & {r.seed for r in _other_recipes("eflare-day")}


def test_the_training_mix_holds_every_part_of_the_mixes_and_fast_lights(tmp_path):
    # eflare-train: eflare-mix's and eflare-day's parts (the same recipes: the same
    # files), then fast-640, eflare-mix's dense-640 with large, fast lights
    train, mix, day = RECIPES["eflare-train"], RECIPES["eflare-mix"], RECIPES["eflare-day"]
    assert train.part_names == (*mix.part_names, *day.part_names, "fast-640")
    assert [r for _, r in train.parts][:-1] == [r for _, r in (*mix.parts, *day.parts)]
    assert train.sequences == mix.sequences + day.sequences + 18
    fast, dense = train.part("fast-640"), mix.part("dense-640")
    assert (fast.sensor_size, fast.scene, fast.config.variant) == (
        dense.sensor_size, dense.scene, "forward")  # fmt: skip
    assert fast.config.script.light_radius_px == (2.0, 40.0)  # eflare-mix's: 2-10 px
    assert fast.config.script.travel_px == (0.0, 1200.0)
    assert dense.config.script.light_radius_px == (2.0, 10.0)
    others = {r.seed for r in _other_recipes("eflare-train")}
    assert fast.seed not in others
    small = train.replace(sequences=1, test_sequences=0, sensor_size=(48, 36), duration_us=20_000)
    generate_dataset(small.part("fast-640"), tmp_path, progress=False)
    with h5py.File(tmp_path / "train" / "seq_00000.h5") as f:
        assert {"input", "gt", "background"} <= set(f)  # the scene alone stored


def _other_recipes(name: str) -> list:
    """The registered recipes and mix parts outside ``name`` that are not its parts too."""

    def parts(entry):
        return [r for _, r in entry.parts] if isinstance(entry, Mix) else [entry]

    own = parts(RECIPES[name])
    return [r for other in RECIPES.names() if other != name
            for r in parts(RECIPES[other]) if r not in own]  # fmt: skip


def test_shards_assemble_the_same_bytes(reference, tmp_path):
    out, _ = reference
    # shard i/3 makes the items at positions i, i + 3, ... of the mix's order
    # (night-346 0-1, day-346 2-3, dense-640 4-5, dense-1280 6-7, sparse-1280 8-9)
    first = generate_dataset(TINY_MIX, tmp_path / "sh", shard="0/3", progress=False)
    made = sorted(p.relative_to(tmp_path / "sh").as_posix()
                  for p in (tmp_path / "sh").rglob("seq_*.h5"))  # fmt: skip
    assert made == sorted(
        f"{part}/{TINY_MIX.part(part).split_of(i)}/seq_{i:05d}.h5"
        for part in TINY_MIX.part_names
        for i in range(2)
        if (TINY_MIX.offset(part) + i) % 3 == 0
    )
    assert len(made) == 4 and first.generated == 4 and not first.manifest["complete"]
    assert first.manifest_path.name == "manifest.shard-0-of-3.json"
    assert not (tmp_path / "sh" / "manifest.json").exists()
    assert dataset_folders(tmp_path / "sh") == [tmp_path / "sh" / p for p in TINY_MIX.part_names]
    generate_dataset(TINY_MIX, tmp_path / "sh", shard=(2, 3), progress=False)
    last = generate_dataset(TINY_MIX, tmp_path / "sh", shard="1/3", progress=False)
    assert last.manifest["complete"] and last.manifest_path.name == "manifest.json"
    assert digests(tmp_path / "sh") == digests(out)
    assert (tmp_path / "sh" / "manifest.json").read_bytes() == (out / "manifest.json").read_bytes()
    for part in TINY_MIX.part_names:
        assert (tmp_path / "sh" / part / "manifest.json").read_bytes() == (
            out / part / "manifest.json"
        ).read_bytes()


def test_rerun_skips_and_another_mix_or_dataset_is_refused(reference, tmp_path):
    _, first = reference
    generate_dataset(TINY_MIX, tmp_path, progress=False)
    again = generate_dataset(TINY_MIX, tmp_path, progress=False)
    assert (again.generated, again.skipped) == (0, 10) and again.manifest == first.manifest
    with pytest.raises(EdeflareError, match="holds another mix"):
        generate_dataset(TINY_MIX.replace(seed=9), tmp_path, progress=False)
    with pytest.raises(EdeflareError, match="holds a mix"):
        generate_dataset(TINY, tmp_path, progress=False)
    generate_dataset(TINY, tmp_path / "plain", progress=False)
    with pytest.raises(EdeflareError, match="holds a dataset, not a mix"):
        generate_dataset(TINY_MIX, tmp_path / "plain", progress=False)
    # a part's folder of another recipe is refused by the part's own check
    (tmp_path / "manifest.json").unlink()
    renamed = Mix("eflare-mix", ((TINY_MIX.part_names[0], TINY),))
    with pytest.raises(EdeflareError, match="another recipe"):
        generate_dataset(renamed, tmp_path, progress=False)


def test_mixes_check_their_parts():
    r = Recipe(sequences=3, test_sequences=1)
    with pytest.raises(EdeflareError, match="part name 'train' must be a folder name"):
        Mix("m", (("train", r),))
    with pytest.raises(EdeflareError, match="part 'a' must be a Recipe"):
        Mix("m", (("a", TINY_MIX),))
    with pytest.raises(EdeflareError, match="at least one part"):
        Mix("m", ())
    with pytest.raises(EdeflareError, match="has no part 'c'; parts: a"):
        Mix("m", (("a", r),)).part("c")
    mix = Mix("m", (("a", r), ("b", r.replace(seed=1)), ("c", r.replace(seed=2))))
    assert [mix.offset(p) for p in "abc"] == [0, 3, 6]
    # shard i/n of the mix is the part's (i - offset) % n: the positions i, i + n, ...
    for i in range(4):
        for part in "abc":
            j, n = mix.shard_of(part, (i, 4))
            assert [k for k in range(3) if k % n == j] == [
                k for k in range(3) if (mix.offset(part) + k) % 4 == i
            ]


_KILLED_RUN = """
import json, sys
from edeflare.data.generate import Mix, Recipe, generate_dataset
parts = tuple((name, Recipe.from_dict(d)) for name, d in json.loads(sys.argv[1]))
generate_dataset(Mix("killed", parts), sys.argv[2], workers=2, progress=False)
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_resume_after_sigkill_gives_the_uninterrupted_bytes(tmp_path):
    small = TINY.replace(sequences=8, test_sequences=2, duration_us=20_000)
    mix = Mix("killed", (("a", small), ("b", small.replace(seed=2, sensor_size=(40, 30)))))
    full = tmp_path / "full"
    generate_dataset(mix, full, workers=1, progress=False)
    out = tmp_path / "killed"
    parts = json.dumps([(name, recipe.to_dict()) for name, recipe in mix.parts])
    status, workers = sigkill_main_process(
        [sys.executable, "-c", _KILLED_RUN, parts, str(out)],
        tmp_path / "stderr.txt",
        lambda: len(list(out.rglob("seq_*.h5"))) >= 3,
        poll_s=0.02,
    )
    assert status == -signal.SIGKILL, (tmp_path / "stderr.txt").read_text()
    assert workers and not any(alive(w) for w in workers)
    done = len(list(out.rglob("seq_*.h5")))
    assert 0 < done < mix.sequences
    killed = json.loads((out / "manifest.json").read_text())  # written as the run started
    assert not killed["complete"] and killed["mix_sha256"] == mix.sha256()
    report = generate_dataset(mix, out, workers=2, progress=False)
    assert report.skipped == done and report.generated == mix.sequences - done
    assert digests(out) == digests(full)  # and two workers wrote what one did
    assert (out / "manifest.json").read_bytes() == (full / "manifest.json").read_bytes()
    for part in mix.part_names:
        assert (out / part / "manifest.json").read_bytes() == (
            full / part / "manifest.json"
        ).read_bytes()
    assert not [p for p in out.rglob("*") if ".partial" in p.name]


def test_cli_simulates_a_registered_mix(tmp_path, capsys):
    RECIPES.register("tiny-mix", Mix("tiny-mix", (("a", TINY), ("b", TINY.replace(seed=4)))))
    try:
        argv = ["simulate", str(tmp_path / "m"), "--recipe", "tiny-mix", "--no-progress"]
        assert main([*argv, "--shard", "1/2"]) == 0
        text = capsys.readouterr().out
        assert "tiny-mix: 6 sequences made, 0 already there" in text
        assert "mix 6/12 sequences so far (parts a, b)" in text
        assert main([*argv, "--workers", "2"]) == 0
        assert "6 sequences made, 6 already there" in capsys.readouterr().out
        assert main(argv) == 0
        assert "0 sequences made, 12 already there" in capsys.readouterr().out
        assert main([*argv, "--seed", "0", "--sensor-size", "8x8"]) == 1
        err = capsys.readouterr().err
        assert "--sensor-size, --seed do not apply to the mix tiny-mix" in err
    finally:
        RECIPES.unregister("tiny-mix")
    manifest = json.loads((tmp_path / "m" / "manifest.json").read_text())
    assert manifest["complete"] and manifest["name"] == "tiny-mix"
    for part, seed in (("a", TINY.seed), ("b", 4)):
        files = sorted((tmp_path / "m" / part).rglob("seq_*.h5"))
        assert len(files) == TINY.sequences
        with h5py.File(files[0]) as f:
            assert json.loads(f.attrs["seed"])[0] == seed


def test_a_mix_folder_trains_as_its_parts(reference, tmp_path):
    """``edeflare train MIX`` and ``train(..., [MIX])`` equal ``edeflare train MIX/a MIX/b ...``."""
    out, _ = reference
    parts = [out / p for p in TINY_MIX.part_names]
    assert dataset_folders(out) == parts and dataset_folders(parts[0]) == [parts[0]]
    train_files, val_files = dataset_files([out])
    assert (train_files, val_files) == dataset_files(parts)
    assert [p.relative_to(out).parts[0] for p in train_files] == list(TINY_MIX.part_names)
    assert all(p.parent.name == "test" for p in val_files) and len(val_files) == 5
    assert sequence_files([out]) == train_files and sequence_files([out], "test") == val_files
    assert sequence_files([parts[0] / "test", train_files[0]]) == [val_files[0], train_files[0]]
    args = ["--preset", "unet2d.tiny", "--iterations", "4", "--batch-size", "2", "--crop", "16x16"]
    args += ["--val-every", "2", "--val-windows", "2", "--checkpoint-every", "2"]
    assert main(["train", str(out), "--out", str(tmp_path / "a"), *args]) == 0
    assert main(["train", *map(str, parts), "--out", str(tmp_path / "b"), *args]) == 0
    config = dataclasses.replace(
        TRAIN_PRESETS["cpu"], preset="unet2d.tiny", iterations=4, batch_size=2, crop=(16, 16),
        val_every=2, val_windows=2, checkpoint_every=2,
    )  # fmt: skip
    train(config, [out], tmp_path / "c", val_paths=[out], progress=False)
    a, b, c = (load_model(tmp_path / r / "model.safetensors")[0].state_dict() for r in "abc")
    for name, x in a.items():
        assert torch.equal(x, b[name]) and torch.equal(x, c[name]), name
    logs = [_column(tmp_path / r / "val_log.csv", "val_mse") for r in "abc"]
    assert logs[0] == logs[1] == logs[2] and len(logs[0]) == 2


def _column(path, name):
    with open(path, newline="") as f:
        return [row[name] for row in csv.DictReader(f)]
