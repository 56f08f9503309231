"""Tests of the eflare-r-sim recipes (edeflare.sim.optics_scene, edeflare.data.eflare_r_sim).

Determinism (files are a pure function of recipe and index, whatever the order
or the workers), the physics of the paper's real-capture model (no star
streaks in the ground truth, the sources in both streams, the strobe's
frequency in the event rate), and the dataset contract (pairs, benchmark, CLI).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy import ndimage

from conftest import random_events, same_events
from edeflare.cli import main
from edeflare.data.generate import (
    RECIPES,
    generate_dataset,
    generate_sequence,
    sequence_path,
    write_sequence,
)
from edeflare.data.pairs import PairedWindows
from edeflare.errors import EdeflareError
from edeflare.eval.benchmark import benchmark
from edeflare.events import check_events
from edeflare.io import write_events
from edeflare.io.sequence import list_sequences, read_frames
from edeflare.sim.background import NightStreet
from edeflare.sim.optics import PSFConfig
from edeflare.sim.optics_scene import (
    LightSourceSpec,
    OpticsRenderer,
    OpticsScene,
    OpticsSceneConfig,
    draw_optics_scene,
    simulate_optics_pair,
)
from edeflare.sim.script import SensorSpec

# Small and quick: 20 ms (one window) on 64x48 with a coarse PSF grid.
TINY = dataclasses.replace(
    RECIPES["eflare-r-sim-mini"],
    name="tiny-r-sim",
    sequences=3,
    sensor_size=(64, 48),
    duration_us=20_000,
    config=OpticsSceneConfig(psf_grid=128),
)


def digests(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*.h5"))
    }


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """TINY generated once, in order, in this process."""
    out = tmp_path_factory.mktemp("r-sim")
    return out, generate_dataset(TINY, out, progress=False)


# ------------------------------------------------------------------------------ recipes


def test_recipes_are_test_sets_of_documented_sizes():
    full, mini = RECIPES["eflare-r-sim"], RECIPES["eflare-r-sim-mini"]
    assert (full.kind, full.sensor_size, full.sequences, full.duration_us) == (
        "optics",
        (640, 480),
        30,
        100_000,
    )
    assert full.windows_per_sequence * full.sequences == 150  # as E-Flare-R's 150 pairs
    assert (mini.sensor_size, mini.sequences) == ((346, 260), 20)
    for r in (full, mini):
        assert r.test_sequences == r.sequences and r.split_of(0) == "test"
    # From Python: a number of sequences and a seed; every sequence stays a test one.
    r = dataclasses.replace(full, sequences=7, seed=11)
    assert (r.test_sequences, r.split_of(0), r.seed) == (7, "test", 11)


def test_recipe_round_trips_and_flare_recipes_keep_their_digest():
    r = TINY.replace(optics=OpticsSceneConfig(psf_grid=64, sources=(2, 2)))
    again = type(r).from_dict(json.loads(json.dumps(r.to_dict())))
    assert again == r and again.sha256() == r.sha256()
    assert "optics" in r.identity() and "dsec" not in r.identity()
    mini = RECIPES["eflare-mini"]
    assert not {"kind", "optics", "dsec"} & set(mini.identity())


def test_scene_draws_are_pure_and_cover_filters_and_sources():
    scenes = [draw_optics_scene(rng=i) for i in range(40)]
    assert scenes[3] == draw_optics_scene(rng=3)
    assert {s.filter for s in scenes} == {"star", "random"}
    assert {src.kind for s in scenes for src in s.sources} == {"point", "lamp", "strobe"}
    for s in scenes:
        assert OpticsScene.from_json(s.to_json()) == s
        if s.filter == "star":
            assert s.psf.star_orientations == 3  # six-point star
        else:
            assert s.psf.random_phase_rms > 0 and s.psf.star_orientations == 0
        strobes = [src.frequency_hz for src in s.sources if src.kind == "strobe"]
        if strobes:  # enough frames per strobe period
            assert s.fps >= min(16 * max(strobes), 6000.0)


# --------------------------------------------------------------------------- determinism


def test_files_are_a_pure_function_of_recipe_and_index(reference, tmp_path):
    out, _ = reference
    for i in reversed(range(TINY.sequences)):  # another order, one file at a time
        write_sequence(sequence_path(tmp_path, TINY, i), generate_sequence(TINY, i), TINY)
    assert digests(tmp_path) == digests(out)
    shards = tmp_path / "shards"
    for shard in ("1/2", "0/2"):
        generate_dataset(TINY, shards, shard=shard, progress=False)
    assert digests(shards) == digests(out)
    other = dataclasses.replace(TINY, seed=TINY.seed + 1)
    a, b = generate_sequence(TINY, 0), generate_sequence(other, 0)
    assert not same_events(a.streams["input"], b.streams["input"])


@pytest.mark.slow
def test_two_workers_write_identical_bytes(reference, tmp_path):
    out, _ = reference
    generate_dataset(TINY, tmp_path, workers=2, progress=False)
    assert digests(tmp_path) == digests(out)


# ------------------------------------------------------------------------------- physics

SIZE = (96, 72)
STROBE = LightSourceSpec(
    kind="strobe", size_px=2.0, radiance=40 * 255.0, frequency_hz=200.0, depth=1.0, duty=0.3
)


def _scene(psf: PSFConfig) -> OpticsScene:
    filt = "star" if psf.star_orientations else "random"
    return OpticsScene(
        duration_us=50_000,
        fps=4000.0,
        filter=filt,
        psf=psf,
        sources=(STROBE,),
        sensor=SensorSpec(seed=7),
    )


@pytest.fixture(scope="module", params=["star", "random"])
def dark_pair(request):
    """A static strobe in the dark behind each filter: the flare is all there is."""
    if request.param == "star":
        psf = PSFConfig(grid=256, star_orientations=3, star_transmission=0.3)
    else:
        psf = PSFConfig(grid=256, random_phase_rms=0.8)
    scene = _scene(psf)
    return scene, simulate_optics_pair(scene, SIZE)


def _mask_count(events: np.ndarray, mask: np.ndarray) -> int:
    return int(mask[events["y"], events["x"]].sum())


def test_ground_truth_has_no_flare_outside_the_clean_psf(dark_pair):
    scene, pair = dark_pair
    check_events(pair.input, SIZE)
    check_events(pair.gt, SIZE)
    clean = OpticsRenderer(scene, SIZE).sources_frame(0, "gt")
    support = ndimage.binary_dilation(clean > 0.5, iterations=2)
    yy, xx = np.mgrid[: SIZE[1], : SIZE[0]]
    near = np.hypot(xx - SIZE[0] / 2, yy - SIZE[1] / 2) < 40
    outside = near & ~support
    n_ob, n_gt = _mask_count(pair.input, outside), _mask_count(pair.gt, outside)
    assert n_ob > 500 and n_gt <= 0.02 * n_ob
    assert pair.input.size > 1.2 * pair.gt.size


def test_light_source_events_are_in_both_streams(dark_pair):
    _, pair = dark_pair
    yy, xx = np.mgrid[: SIZE[1], : SIZE[0]]
    core = np.hypot(xx - SIZE[0] / 2, yy - SIZE[1] / 2) < 4
    n_ob, n_gt = _mask_count(pair.input, core), _mask_count(pair.gt, core)
    assert n_gt > 1000 and 0.5 < n_ob / n_gt < 2.0


def test_strobe_frequency_shows_in_the_event_rate(dark_pair):
    scene, pair = dark_pair
    yy, xx = np.mgrid[: SIZE[1], : SIZE[0]]
    core = np.hypot(xx - SIZE[0] / 2, yy - SIZE[1] / 2) < 4
    bin_us = 250
    n = scene.duration_us // bin_us
    freqs = np.fft.rfftfreq(n, d=bin_us * 1e-6)
    for events in (pair.input, pair.gt):
        on = events[core[events["y"], events["x"]] & (events["p"] == 1)]  # one burst per flash
        rate = np.bincount(on["t"] // bin_us, minlength=n)[:n].astype(float)
        spectrum = np.abs(np.fft.rfft(rate - rate.mean()))
        assert freqs[spectrum.argmax()] == pytest.approx(STROBE.frequency_hz, abs=20.0)
        assert spectrum.max() > 5 * np.median(spectrum)


def test_moving_sources_and_street_give_more_events_through_the_filter():
    scene = dataclasses.replace(
        _scene(PSFConfig(grid=128, star_orientations=3)),
        duration_us=20_000,
        sources=(
            dataclasses.replace(STROBE, travel_px=20.0, direction_deg=30.0),
            LightSourceSpec(kind="lamp", size_px=4.0, radiance=10 * 255.0, start=(0.3, 0.3)),
        ),
    )
    street = NightStreet((64, 48), rng=3)
    pair = simulate_optics_pair(scene, (64, 48), background=street, rng=0)
    assert pair.input.size > pair.gt.size > 0
    # Far from the sources both passes see the same street through one sensor draw.
    far = np.zeros((48, 64), bool)
    far[40:, 50:] = True
    assert _mask_count(pair.gt, far) > 0


def test_recorded_backgrounds_are_fused_by_pnl_es(tmp_path, rng):
    path = tmp_path / "drive.npz"
    write_events(path, random_events(rng, 20_000, (64, 48), span_us=200_000), (64, 48))
    recipe = dataclasses.replace(TINY, background="recorded", background_files=(str(path),))
    data = generate_sequence(recipe, 1)
    assert data.background["kind"] == "recorded"
    ob, gt = data.streams["input"], data.streams["gt"]
    check_events(ob, (64, 48))
    check_events(gt, (64, 48))
    assert ob.size > 0 and gt.size > 0
    assert np.array_equal(ob, generate_sequence(recipe, 1).streams["input"])


# ------------------------------------------------------------------------------ contract


def test_files_follow_the_dataset_contract(reference):
    out, report = reference
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest == report.manifest
    assert manifest["complete"] and manifest["splits"]["train"]["sequences"] == 0
    assert manifest["recipe"]["kind"] == "optics"
    for entry in manifest["files"]:
        assert entry["split"] == "test" and set(entry["events"]) == {"input", "gt"}
        with h5py.File(out / entry["file"]) as f:
            assert set(f) == {"input", "gt", "frames"}
            assert f.attrs["kind"] == "optics" and "variant" not in f.attrs
            assert (int(f.attrs["t_start_us"]), int(f.attrs["t_end_us"])) == (0, 20_000)
            scene = OpticsScene.from_json(f.attrs["script"])
        assert scene == generate_sequence(TINY, entry["index"]).script
        # the clean lens's images at the windows' ends: ground truth for reconstructions
        times, images = read_frames(out / entry["file"])
        assert times.tolist() == list(range(TINY.window_us, 20_001, TINY.window_us))
        assert images.shape == (times.size, 48, 64) and images.max() <= 255.0
        assert images.min() >= 0.0 and images.std() > 0
    windows = PairedWindows(list_sequences(out / "test"))
    x, y = windows[0]
    assert len(windows) == 3 and x.shape == y.shape == (1, 8, 48, 64)
    result = benchmark(out / "test", {"raw": "raw"}, progress=False)
    assert set(result.evaluation.methods) == {"raw"}


def test_cli(tmp_path, capsys):
    out = tmp_path / "cli"
    args = ["simulate", str(out), "--recipe", "eflare-r-sim-mini", "--sequences", "1"]
    args += ["--sensor-size", "48x32", "--duration-ms", "20", "--seed", "5", "--no-progress"]
    assert main(args) == 0
    assert [p.name for p in (out / "test").iterdir()] == ["seq_00000.h5"]
    assert "1 sequences made" in capsys.readouterr().out
    assert main([*args, "--test-sequences", "1"]) == 1
    assert "--test-sequences" in capsys.readouterr().err
    assert main([*args[:4], "--variant", "simple"]) == 1


def test_bad_scene_values_are_reported():
    with pytest.raises(EdeflareError, match="kind"):
        LightSourceSpec(kind="laser")
    with pytest.raises(EdeflareError, match="unknown key"):
        OpticsSceneConfig.from_dict({"sourcez": (1, 2)})
    with pytest.raises(EdeflareError, match="kind_weights"):
        OpticsSceneConfig(kind_weights=(1.0,))
