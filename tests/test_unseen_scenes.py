"""benchmarks/unseen_scenes.py: its shares by hand, its readers and its file checks."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import load_benchmark
from edeflare.events import make_events


@pytest.fixture
def unseen(monkeypatch):
    return load_benchmark(monkeypatch, "unseen_scenes")


def _events(counts):
    """``counts[k]`` events in the k-th 100 ms bin, at x = their index."""
    t = np.repeat(100_000 * np.arange(len(counts)), counts)
    return make_events(t, np.arange(t.size), np.zeros(t.size), np.ones(t.size))


def test_the_busiest_quarter_and_the_quietest_half_of_the_bins(unseen):
    events = _events([10, 1, 4, 2, 8, 3, 6, 5])  # busiest quarter: 10, 8; quietest half: 1-4
    _, kind = unseen.busy_bins(events)
    assert kind.tolist() == [1, -1, -1, -1, 1, -1, 0, 0]
    # keep bin 0 whole, half of bin 4, bin 1 and none of bins 2, 3, 5 (quietest: 1 of 10)
    starts = np.cumsum([0, 10, 1, 4, 2, 8, 3, 6])
    kept = np.concatenate([np.arange(10), starts[4] + np.arange(4), [starts[1]]])
    shares = unseen.shares(events, events[np.sort(kept)])
    assert shares == {"kept": round(100 * 15 / 39, 1), "dense": round(100 * 14 / 18, 1),
                      "sparse": 10.0}  # fmt: skip


def test_the_face_reader_takes_seconds_and_bool_polarity_without_pickles(unseen, tmp_path):
    a = np.zeros(3, [("t", "<f8"), ("x", "<u2"), ("y", "<u2"), ("p", "?")])
    a["t"], a["x"], a["y"], a["p"] = (
        [0.004484, 0.0045, 1.25],
        [280, 999, 500],
        [0, 719, 3],
        [True, False, True],
    )
    np.save(tmp_path / "face.npy", a)
    events, size = unseen._read_face(tmp_path / "face.npy")
    assert size == (1280, 720)
    assert events["t"].tolist() == [4484, 4500, 1_250_000]
    assert events["p"].tolist() == [1, 0, 1] and events["x"].tolist() == [280, 999, 500]
    objects = np.array([{"t": 1}], dtype=object)
    np.save(tmp_path / "objects.npy", objects, allow_pickle=True)
    with pytest.raises(ValueError, match="pickle"):
        unseen._read_face(tmp_path / "objects.npy")


def test_a_missing_or_different_file_is_refused_by_name(unseen, tmp_path):
    with pytest.raises(SystemExit, match="no such file"):
        unseen.load_scene(tmp_path, "face")
    member = tmp_path / unseen.SCENES["face"][0]
    member.parent.mkdir(parents=True)
    member.write_bytes(b"not the face")
    with pytest.raises(SystemExit, match="sha256 differs"):
        unseen.load_scene(tmp_path, "face")
