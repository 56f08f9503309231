"""Tests of edeflare.data.generate and ``edeflare simulate``: contract, determinism, resumption."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import alive, children, random_events, same_events, sigkill_main_process
from edeflare.cli import main
from edeflare.data.generate import (
    GROUPS,
    RECIPES,
    FlareConfig,
    Recipe,
    draw_inputs,
    generate_dataset,
    generate_sequence,
    list_recipes,
    sequence_path,
)
from edeflare.data.pairs import PairedWindows
from edeflare.errors import EdeflareError
from edeflare.events import check_events, merge_events
from edeflare.io import write_events
from edeflare.io.dsec import DsecReader
from edeflare.io.sequence import list_sequences
from edeflare.sim.background import SceneConfig
from edeflare.sim.compose import compose_pair
from edeflare.sim.script import FlareScript, ScriptConfig

# Small and quick: 40 ms sequences (2 windows) on 64x48, a coarse PSF grid, 1 kHz background.
TINY = Recipe(
    name="tiny",
    sequences=6,
    test_sequences=2,
    duration_us=40_000,
    sensor_size=(64, 48),
    scene=SceneConfig(fps=1000.0),
    config=FlareConfig(script=ScriptConfig(psf_grid=128)),
)


def digests(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*.h5"))
    }


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """TINY generated once, uninterrupted, in this process."""
    out = tmp_path_factory.mktemp("reference")
    report = generate_dataset(TINY, out, workers=1, progress=False)
    return out, report


# ------------------------------------------------------------------------------ recipes


def test_paper_recipe_has_the_papers_numbers():
    r = RECIPES["eflare-2.7k"]
    n_test = r.test_sequences
    n_train = r.sequences - n_test
    assert (r.sequences, n_train, n_test) == (544, 509, 35)
    assert r.sensor_size == (640, 480) and r.duration_us == 100_000 and r.window_us == 20_000
    assert r.windows_per_sequence * r.sequences == 2720
    assert (n_train * r.windows_per_sequence, n_test * r.windows_per_sequence) == (2545, 175)
    assert r.config.variant == "physical"
    assert {"eflare-2.7k", "eflare-mini"} <= set(list_recipes())


def test_recipe_round_trip_and_validation():
    r = dataclasses.replace(TINY, background="recorded", background_files=("a.h5",))
    assert Recipe.from_dict(json.loads(json.dumps(r.to_dict()))) == r
    assert r.sha256() != TINY.sha256()
    for bad, match in [
        ({"sequencs": 3}, "unknown recipe key"),
        ({"script": {"psf_gird": 3}}, "recipe 'script'"),
        ({"test_sequences": 700}, "exceeds sequences"),
        ({"window_us": 200_000}, "window_us <= duration_us"),
        ({"variant": "physics"}, "variant must be one of"),
        ({"background": "recorded"}, "needs background_files"),
        ({"variant": "forward", "background": "recorded", "background_files": ["a"]}, "video"),
        ({"weights": "count"}, "weights must be one of"),
        ({"sensor_size": [0, 4]}, "sensor_size"),
        ({"sequences": -1}, "int >= 0"),
    ]:
        with pytest.raises(EdeflareError, match=match):
            Recipe.from_dict(bad)


# -------------------------------------------------------------------------- sequences


def test_sequence_is_a_pure_function_of_recipe_and_index():
    a = generate_sequence(TINY, 3)
    generate_sequence(TINY, 1)  # other work in between changes nothing
    b = generate_sequence(TINY, 3)
    assert all(same_events(a.streams[k], b.streams[k]) for k in GROUPS)
    c = generate_sequence(dataclasses.replace(TINY, seed=1), 3)
    assert not same_events(a.streams["input"], c.streams["input"])
    for k in GROUPS:
        check_events(a.streams[k], TINY.sensor_size)
        assert a.streams[k].size == 0 or a.streams[k]["t"].max() < TINY.duration_us
    assert a.script.duration_us == TINY.duration_us
    with pytest.raises(EdeflareError, match=r"index must be in \[0, 6\)"):
        generate_sequence(TINY, 6)


def test_variants_build_the_pairs_they_promise():
    physical = generate_sequence(TINY, 2)
    simple = generate_sequence(TINY.replace(variant="simple"), 2)
    no_light = generate_sequence(TINY.replace(variant="no-light"), 2)
    s = simple.streams
    # Same script, background and flare: only the composition differs.
    for k in ("flare", "light", "background"):
        assert same_events(physical.streams[k], s[k]) and same_events(no_light.streams[k], s[k])
    assert same_events(s["input"], merge_events(s["background"], s["flare"]))
    assert same_events(s["gt"], merge_events(s["background"], s["light"]))
    assert same_events(no_light.streams["gt"], s["background"])
    assert physical.streams["input"].size < s["input"].size  # PNL-ES suppresses
    # The components and the composition seed rebuild the pair exactly.
    seed = draw_inputs(TINY, 2).compose_seed
    ob, gt = compose_pair(physical.components, "physical", rng=np.random.default_rng(seed))
    assert same_events(ob, physical.streams["input"]) and same_events(gt, physical.streams["gt"])


def test_forward_variant_and_counts_weights_run():
    fwd = generate_sequence(TINY.replace(variant="forward"), 0)
    phys = generate_sequence(TINY, 0)
    assert same_events(fwd.streams["flare"], phys.streams["flare"])
    assert fwd.streams["input"].size > 0 and not same_events(
        fwd.streams["input"], phys.streams["input"]
    )
    counts = generate_sequence(TINY.replace(weights="counts"), 0)
    assert same_events(counts.streams["flare"], phys.streams["flare"])
    assert counts.streams["input"].size > 0


def test_recorded_backgrounds_from_a_real_file(real_data, tmp_path):
    recipe = dataclasses.replace(
        TINY,
        sequences=2,
        test_sequences=1,
        sensor_size=(346, 260),
        background="recorded",
        background_files=(str(real_data / "davis346_street_cars.aedat4"),),
    )
    report = generate_dataset(recipe, tmp_path, progress=False)
    assert report.manifest["complete"]
    with h5py.File(tmp_path / "train" / "seq_00000.h5") as f:
        bg = json.loads(f.attrs["background"])
    assert bg["kind"] == "recorded" and bg["file"] == "davis346_street_cars.aedat4"
    assert bg["offset_xy"] == [0, 0]


def test_recorded_data_in_another_place_gives_identical_files(tmp_path, rng):
    """Manifests and files name background files relative to their common folder."""
    events = random_events(rng, 40_000, (80, 60), span_us=500_000)
    for place in ("a", "b"):
        for seq in ("zurich_00", "interlaken_00"):
            write_events(tmp_path / place / seq / "events.h5", events, (80, 60))
    made = {}
    for place in ("a", "b"):
        files = tuple(
            str(tmp_path / place / s / "events.h5") for s in ("zurich_00", "interlaken_00")
        )
        recipe = dataclasses.replace(
            TINY, sequences=2, test_sequences=1, background="recorded", background_files=files
        )
        report = generate_dataset(recipe, tmp_path / f"out_{place}", progress=False)
        made[place] = digests(tmp_path / f"out_{place}")
        names = report.manifest["recipe"]["background_files"]
        assert names == ["zurich_00/events.h5", "interlaken_00/events.h5"]
    assert made["a"] == made["b"]


# ---------------------------------------------------------------------------- datasets


def test_files_follow_the_dataset_contract(reference):
    out, report = reference
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest == report.manifest and manifest["complete"]
    assert manifest["recipe"] == TINY.to_dict() and manifest["edeflare_version"]
    assert manifest["splits"] == {
        "train": {"sequences": 4, "windows": 8},
        "test": {"sequences": 2, "windows": 4},
    }
    for entry in manifest["files"]:
        path = out / entry["file"]
        assert hashlib.sha256(path.read_bytes()).hexdigest() == entry["sha256"]
        assert entry["seed"] == [TINY.seed, entry["index"]]
        with h5py.File(path) as f:
            assert set(f) == set(GROUPS)
            assert f.attrs["sensor_size"].tolist() == [64, 48]
            assert (int(f.attrs["t_start_us"]), int(f.attrs["t_end_us"])) == (0, 40_000)
            script = FlareScript.from_json(f.attrs["script"])
            assert f.attrs["recipe_sha256"] == TINY.sha256()
        assert script == generate_sequence(TINY, entry["index"]).script
        for group in GROUPS:
            with DsecReader(path, group=f"{group}/events") as r:
                assert r.n_events == entry["events"][group]
    train = PairedWindows(list_sequences(out / "train"))
    test = PairedWindows(list_sequences(out / "test"))
    assert (len(train), len(test)) == (8, 4)
    x, y = train[0]
    assert x.shape == y.shape == (1, 8, 48, 64)


def test_no_sequence_is_in_both_splits(reference):
    out, _ = reference
    train = {p.name for p in (out / "train").glob("*.h5")}
    test = {p.name for p in (out / "test").glob("*.h5")}
    assert train and test and not train & test
    assert train | test == {f"seq_{i:05d}.h5" for i in range(TINY.sequences)}
    scripts = []
    for p in sorted(out.rglob("*.h5")):
        with h5py.File(p) as f:
            scripts.append(f.attrs["script"])
    assert len(set(scripts)) == len(scripts)  # every sequence is its own sample


def test_one_and_two_workers_write_identical_bytes(reference, tmp_path):
    out, report = reference
    two = generate_dataset(TINY, tmp_path, workers=2, progress=False)
    assert digests(tmp_path) == digests(out)
    assert (tmp_path / "manifest.json").read_bytes() == (out / "manifest.json").read_bytes()
    assert two.generated == TINY.sequences and set(two.stage_seconds) == set(report.stage_seconds)


def test_shards_assemble_the_same_dataset(reference, tmp_path):
    out, _ = reference
    first = generate_dataset(TINY, tmp_path, shard="0/2", progress=False)
    assert not first.manifest["complete"]
    assert first.manifest_path.name == "manifest.shard-0-of-2.json"
    assert [f["index"] for f in first.manifest["files"]] == [0, 2, 4]
    assert not (tmp_path / "manifest.json").exists()
    second = generate_dataset(TINY, tmp_path, shard=(1, 2), progress=False)
    assert second.manifest["complete"] and second.manifest_path.name == "manifest.json"
    assert (tmp_path / "manifest.json").read_bytes() == (out / "manifest.json").read_bytes()
    with pytest.raises(EdeflareError, match="shard i/n"):
        generate_dataset(TINY, tmp_path, shard="2/2")


def test_rerun_skips_and_a_changed_recipe_is_refused(reference, tmp_path):
    _, first = reference
    report = generate_dataset(TINY, tmp_path, progress=False)
    again = generate_dataset(TINY, tmp_path, progress=False)
    assert (again.generated, again.skipped) == (0, TINY.sequences)
    assert again.manifest == report.manifest == first.manifest
    with pytest.raises(EdeflareError, match="another recipe"):
        generate_dataset(dataclasses.replace(TINY, seed=9), tmp_path, progress=False)
    # A file of another recipe is refused too, even without a manifest.
    (tmp_path / "manifest.json").unlink()
    with pytest.raises(EdeflareError, match="made by another recipe"):
        generate_dataset(dataclasses.replace(TINY, seed=9), tmp_path, progress=False)


_KILLED_RUN = """
import json, sys
from edeflare.data.generate import Recipe, generate_dataset
recipe = Recipe.from_dict(json.loads(sys.argv[1]))
generate_dataset(recipe, sys.argv[2], workers=2, progress=False)
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_resume_after_sigkill_gives_the_uninterrupted_manifest(tmp_path):
    recipe = dataclasses.replace(TINY, sequences=24, test_sequences=4, duration_us=20_000)
    full = tmp_path / "full"
    generate_dataset(recipe, full, progress=False)
    out = tmp_path / "killed"
    log = tmp_path / "stderr.txt"
    status, workers = sigkill_main_process(
        [sys.executable, "-c", _KILLED_RUN, json.dumps(recipe.to_dict()), str(out)],
        log,
        lambda: len(list(out.rglob("seq_*.h5"))) >= 3,
        poll_s=0.02,
    )
    assert status == -signal.SIGKILL, log.read_text()
    # Its orphaned workers notice and stop: at most the sequences in flight are lost.
    assert workers and not any(alive(w) for w in workers)
    done = len(list(out.rglob("seq_*.h5")))
    assert 0 < done < recipe.sequences
    report = generate_dataset(recipe, out, workers=2, progress=False)
    assert report.skipped == done and report.generated == recipe.sequences - done
    assert (out / "manifest.json").read_bytes() == (full / "manifest.json").read_bytes()
    assert digests(out) == digests(full)
    assert not [p for p in out.rglob("*") if ".partial" in p.name]


_SMALL = ["--sequences", "6", "--test-sequences", "1", "--duration-ms", "40"]
_SMALL += ["--sensor-size", "64x48", "--seed", "5"]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_always_stops_simulate_and_a_rerun_completes(tmp_path):
    """Ctrl-C at a terminal (SIGINT to the process group) while files are being written."""
    recipe = RECIPES["eflare-mini"].replace(
        sequences=6, test_sequences=1, duration_us=40_000, sensor_size=(64, 48), seed=5
    )
    full = tmp_path / "full"
    generate_dataset(recipe, full, progress=False)
    out = tmp_path / "data"
    command = [sys.executable, "-m", "edeflare", "simulate", str(out), *_SMALL]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2] / "src"))
    made = 0
    for workers in ("1", "2", "1"):
        proc = subprocess.Popen(
            [*command, "--workers", workers],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,  # its own process group, as a shell's job
        )
        deadline = time.monotonic() + 120
        while len(list(out.rglob("seq_*.h5"))) <= made and time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read()  # still running: not done yet
            time.sleep(0.02)
        pool = children(proc.pid) if workers == "2" else []
        os.killpg(proc.pid, signal.SIGINT)  # while it writes the next files
        sent = time.monotonic()
        _, err = proc.communicate(timeout=30)
        assert time.monotonic() - sent < 10  # prompt, not at the end of the run
        assert (proc.returncode, err) == (130, "edeflare: interrupted; rerun to resume\n"), err
        deadline = time.monotonic() + 10
        while any(alive(w) for w in pool) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(alive(w) for w in pool)  # the workers stopped too
        now = len(list(out.rglob("seq_*.h5")))
        assert made < now < recipe.sequences  # stopped before the end
        made = now
    manifest = out / "manifest.json"  # kept current while running: never complete so far
    assert not manifest.exists() or json.loads(manifest.read_text())["complete"] is False
    rerun = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{recipe.sequences - made} sequences made, {made} already there" in rerun.stdout
    assert digests(out) == digests(full)  # every file once, whole, as an uninterrupted run's
    assert (out / "manifest.json").read_bytes() == (full / "manifest.json").read_bytes()
    assert not [p for p in out.rglob("*") if ".partial" in p.name]


def test_bad_files_are_reported(tmp_path):
    path = sequence_path(tmp_path, TINY, 0)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not hdf5")
    with pytest.raises(EdeflareError, match="not a readable sequence file"):
        generate_dataset(TINY, tmp_path, progress=False)
    (tmp_path / "manifest.json").write_text("{")
    with pytest.raises(EdeflareError, match="not a dataset manifest"):
        generate_dataset(TINY, tmp_path, progress=False)


# ------------------------------------------------------------------------------- CLI


def test_cli_simulate(tmp_path, capsys):
    out = tmp_path / "ds"
    argv = ["simulate", str(out), "--sequences", "2", "--test-sequences", "1"]
    argv += ["--sensor-size", "48x32", "--duration-ms", "20", "--seed", "3", "--no-progress"]
    assert main(argv) == 0
    assert "eflare-mini: 2 sequences made, 0 already there" in capsys.readouterr().out
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] and manifest["recipe"]["sensor_size"] == [48, 32]
    assert manifest["recipe"]["seed"] == 3 and manifest["recipe"]["name"] == "eflare-mini"
    assert main(argv) == 0
    assert "0 sequences made, 2 already there" in capsys.readouterr().out
    assert main(["simulate", str(tmp_path / "x"), "--recipe", "eflare-3k"]) == 1
    assert "unknown recipe 'eflare-3k'" in capsys.readouterr().err
    assert main(["simulate", str(out), "--seed", "4", "--no-progress"]) == 1
    assert "another recipe" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "y"), "--background", str(tmp_path / "no.h5")]) == 1
    assert "no such file" in capsys.readouterr().err


def test_generated_windows_decode_to_sensible_grids(reference):
    out, _ = reference
    ds = PairedWindows(list_sequences(out / "train"), crop=(32, 32), flip=True, seed=1)
    x, y = ds[1]
    assert x.shape == y.shape == (1, 8, 32, 32)
    assert np.isfinite(x).all() and np.abs(x).sum() > 0
