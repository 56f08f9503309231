"""Tests of the dsec-flare recipe (edeflare.data.dsec_flare) on a small DSEC tree written here.

The files follow DSEC's own layout (``events/{p,t,x,y}``, ``ms_to_idx`` and
``t_offset`` at the root, no sensor size, Blosc compression) in the three
folder layouts of a download; the windows cut from them must be exactly the
source events of their time span, and files without ground truth must be
refused clearly by the paired-data consumers and accepted by the others.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import h5py
import hdf5plugin
import numpy as np
import pytest

from edeflare.cli import main
from edeflare.data.dsec_flare import (
    DEFAULT_WINDOWS,
    DSEC_FLARE_SEQUENCES,
    DsecFlareConfig,
    DsecFlareError,
    WindowSpec,
    parse_window,
)
from edeflare.data.generate import RECIPES, Recipe, generate_dataset
from edeflare.data.pairs import PairedWindows
from edeflare.errors import EdeflareError, EventFileError
from edeflare.io import read_events
from edeflare.io.dsec import DsecReader
from edeflare.io.sequence import list_sequences

T_OFFSET = 49_599_300_523  # a DSEC-like absolute time of the first event
SPAN_US = 27_000_000  # long enough for the window around 26 s of 09_c
LAYOUTS = {  # where each sequence sits in the test tree (all layouts of a download)
    "zurich_city_03_a": "{seq}/events/left/events.h5",
    "zurich_city_10_b": "train/{seq}/events/left/events.h5",
    "zurich_city_12_a": "test/{seq}/events/left/events.h5",
    "zurich_city_09_c": "{seq}/events_left/events.h5",
    "zurich_city_09_d": "train/{seq}/events/left/events.h5",
}


def _events(seed: int) -> dict[str, np.ndarray]:
    """One event every 250 µs on average over the span, on a 640x480 sensor."""
    gen = np.random.default_rng(seed)
    n = SPAN_US // 250
    t = np.sort(gen.integers(0, SPAN_US, n)).astype(np.uint32)
    return {
        "t": t,
        "x": gen.integers(0, 640, n).astype(np.uint16),
        "y": gen.integers(0, 480, n).astype(np.uint16),
        "p": gen.integers(0, 2, n).astype(np.uint8),
    }


def write_dsec_like(path: Path, ev: dict[str, np.ndarray]) -> None:
    """An ``events.h5`` as DSEC ships it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    comp = hdf5plugin.Blosc(cname="zstd", clevel=1)
    ms = np.searchsorted(ev["t"], np.arange(int(ev["t"][-1]) // 1000 + 1) * 1000)
    with h5py.File(path, "w") as f:
        for k in ("p", "t", "x", "y"):
            f.create_dataset(f"events/{k}", data=ev[k], **comp)
        f.create_dataset("ms_to_idx", data=ms.astype(np.uint64))
        f.create_dataset("t_offset", data=np.int64(T_OFFSET))


@pytest.fixture(scope="module")
def dsec_root(tmp_path_factory) -> tuple[Path, dict[str, dict[str, np.ndarray]]]:
    root = tmp_path_factory.mktemp("dsec")
    source = {}
    for i, (seq, layout) in enumerate(LAYOUTS.items()):
        source[seq] = _events(i)
        write_dsec_like(root / layout.format(seq=seq), source[seq])
    # A rectification map beside 03_a: one pixel to the right (the last column leaves).
    yy, xx = np.mgrid[:480, :640].astype(np.float32)
    with h5py.File(root / "zurich_city_03_a/events/left/rectify_map.h5", "w") as f:
        f.create_dataset("rectify_map", data=np.stack([xx + 1.0, yy], axis=-1))
    return root, source


def recipe(root: Path, **changes) -> Recipe:
    dsec = DsecFlareConfig(root=str(root), **changes)
    return RECIPES["dsec-flare"].replace(dsec=dsec)


@pytest.fixture(scope="module")
def dataset(dsec_root, tmp_path_factory):
    root, _ = dsec_root
    out = tmp_path_factory.mktemp("dsec-flare")
    return out, generate_dataset(recipe(root), out, progress=False)


def _source_window(ev: dict[str, np.ndarray], start_us: int, duration_us: int) -> np.ndarray:
    t = ev["t"].astype(np.int64)
    keep = (t >= start_us) & (t < start_us + duration_us)
    return np.stack([t[keep] - start_us, ev["x"][keep], ev["y"][keep], ev["p"][keep]])


# ------------------------------------------------------------------------------ recipe


def test_recipe_holds_the_papers_sequences_and_windows():
    r = RECIPES["dsec-flare"]
    assert r.kind == "dsec" and r.sensor_size == (640, 480) and r.duration_us == 100_000
    assert set(r.config.sequences) == set(DSEC_FLARE_SEQUENCES)
    assert r.sequences == r.test_sequences == 15
    centres = {w.sequence: w.center_s for w in DEFAULT_WINDOWS}
    assert centres["zurich_city_03_a"] == 7.6 and centres["zurich_city_09_c"] == 26.0
    r2 = r.replace(dsec=DsecFlareConfig(windows=(WindowSpec("x", 1.0, 4),)))
    assert r2.sequences == r2.test_sequences == 4
    assert parse_window("zurich_city_09_d:3.25:2") == WindowSpec("zurich_city_09_d", 3.25, 2)
    for bad in ("", "a:b", "a:1:x", "a:1:2:3", "a:-1"):
        with pytest.raises(EdeflareError):
            parse_window(bad)


def test_windows_are_the_source_events_of_their_span(dsec_root, dataset):
    _, source = dsec_root
    out, report = dataset
    manifest = report.manifest
    assert manifest["complete"] and len(manifest["files"]) == 15
    assert manifest["splits"]["train"]["sequences"] == 0
    assert manifest["recipe"]["dsec"]["root"] is None  # the folder's place does not matter
    starts: dict[str, list[int]] = {}
    for entry in manifest["files"]:
        assert entry["split"] == "test" and set(entry["events"]) == {"input"}
        path = out / entry["file"]
        with h5py.File(path) as f:
            assert set(f) == {"input"} and f.attrs["kind"] == "dsec"
            assert (int(f.attrs["t_start_us"]), int(f.attrs["t_end_us"])) == (0, 100_000)
            window = json.loads(f.attrs["script"])
        seq = window["sequence"]
        assert window["file"] == LAYOUTS[seq].format(seq=seq)
        assert window["t_offset_us"] == T_OFFSET and not window["rectified"]
        assert window["category"] == DSEC_FLARE_SEQUENCES[seq]
        starts.setdefault(seq, []).append(window["start_us"])
        with DsecReader(path, group="input/events") as reader:
            ev = reader.read()
        got = np.stack([ev["t"], ev["x"], ev["y"], ev["p"]])
        assert np.array_equal(got, _source_window(source[seq], window["start_us"], 100_000))
        assert ev.size > 300
    assert starts["zurich_city_03_a"] == [7_450_000, 7_550_000, 7_650_000]  # around 7.6 s
    assert starts["zurich_city_09_c"] == [25_850_000, 25_950_000, 26_050_000]  # around 26 s
    mid = SPAN_US // 2  # the others: the middle of the recording
    for seq in ("zurich_city_10_b", "zurich_city_12_a", "zurich_city_09_d"):
        assert abs(starts[seq][1] + 50_000 - mid) < 2_000


def test_rerun_skips_and_the_same_data_elsewhere_gives_the_same_files(dsec_root, dataset):
    root, _ = dsec_root
    out, first = dataset
    again = generate_dataset(recipe(root), out, progress=False)
    assert (again.generated, again.skipped) == (0, 15)
    assert again.manifest == first.manifest


def test_rectification_uses_the_map(dsec_root, tmp_path):
    root, source = dsec_root
    r = recipe(root, windows=(WindowSpec("zurich_city_03_a", 7.6, 1),), rectify=True)
    report = generate_dataset(r, tmp_path, progress=False)
    ev = read_events(tmp_path / report.manifest["files"][0]["file"]).events
    raw = _source_window(source["zurich_city_03_a"], 7_550_000, 100_000)
    inside = raw[1] < 639  # x + 1 stays on the sensor
    assert np.array_equal(ev["x"], raw[1][inside] + 1)
    assert np.array_equal(ev["t"], raw[0][inside])
    bad = recipe(root, windows=(WindowSpec("zurich_city_10_b", 1.0, 1),), rectify=True)
    with pytest.raises(EventFileError, match="rectify_map"):
        generate_dataset(bad, tmp_path / "bad", progress=False)


# ------------------------------------------------------------------------------- errors


def test_missing_sequences_are_listed(dsec_root, tmp_path, capsys):
    _, source = dsec_root
    partial = tmp_path / "partial"
    for seq in ("zurich_city_03_a", "zurich_city_09_c"):
        write_dsec_like(partial / "train" / seq / "events/left/events.h5", source[seq])
    with pytest.raises(DsecFlareError) as err:
        generate_dataset(recipe(partial), tmp_path / "out", progress=False)
    message = str(err.value)
    assert "found 2 of the 5" in message
    assert "found: zurich_city_03_a, zurich_city_09_c" in message
    assert "missing: zurich_city_10_b, zurich_city_12_a, zurich_city_09_d" in message
    assert not (tmp_path / "out" / "test").exists()
    # The CLI says the same in one line, and the sequences one has are enough with windows.
    base = ["simulate", str(tmp_path / "cli"), "--recipe", "dsec-flare", "--no-progress"]
    assert main([*base, "--dsec-root", str(partial)]) == 1
    assert "missing: zurich_city_10_b" in capsys.readouterr().err
    assert (
        main([*base, "--dsec-root", str(partial), "--dsec-window", "zurich_city_03_a:7.6:2"]) == 0
    )
    assert len(list((tmp_path / "cli" / "test").glob("*.h5"))) == 2


def test_bad_roots_windows_and_options_are_reported(dsec_root, tmp_path, capsys):
    root, _ = dsec_root
    with pytest.raises(DsecFlareError, match="--dsec-root"):
        generate_dataset(RECIPES["dsec-flare"], tmp_path / "a", progress=False)
    with pytest.raises(EventFileError, match="no such folder"):
        generate_dataset(recipe(tmp_path / "nowhere"), tmp_path / "b", progress=False)
    late = recipe(root, windows=(WindowSpec("zurich_city_03_a", 60.0, 1),))
    with pytest.raises(DsecFlareError, match="outside its recording"):
        generate_dataset(late, tmp_path / "c", progress=False)
    one = recipe(root, windows=(WindowSpec("zurich_city_03_a", 7.6, 1),))
    small = dataclasses.replace(one, sensor_size=(320, 240))
    with pytest.raises(EventFileError, match="beyond the sensor 320x240"):
        generate_dataset(small, tmp_path / "d", progress=False)
    base = ["simulate", str(tmp_path / "e"), "--recipe", "dsec-flare", "--dsec-root", str(root)]
    assert main([*base, "--sequences", "3"]) == 1
    assert "--sequences" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "f"), "--dsec-root", str(root)]) == 1


# ---------------------------------------------------------------------------- consumers


def test_paired_consumers_refuse_and_the_others_accept(dataset, tmp_path, capsys):
    out, _ = dataset
    files = list_sequences(out / "test")
    with pytest.raises(EventFileError, match="no ground truth"):
        PairedWindows(files)
    assert main(["benchmark", str(out / "test"), "--methods", "raw"]) == 1
    assert "no ground truth" in capsys.readouterr().err
    # One event group: deflare, view and info read the input directly.
    assert main(["deflare", str(files[0]), str(tmp_path / "clean.h5"), "-m", "raw"]) == 0
    assert read_events(tmp_path / "clean.h5").events.size == read_events(files[0]).events.size
    assert main(["view", str(files[0]), "-o", str(tmp_path / "v.png"), "--count", "2"]) == 0
    assert (tmp_path / "v.png").stat().st_size > 0
