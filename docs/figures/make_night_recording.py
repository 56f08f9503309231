"""The real night recording (faery 0.7.1's ``tests/data/evt3.raw``) de-flared.

    python docs/figures/make_night_recording.py faery-0.7.1/tests/data/evt3.raw \
        docs/figures/night_recording.png

Its first 2 s are de-flared by ``night``, ``general`` and ``learned`` (and dv-fastdecay);
two 100 ms windows (at 0.2 s, the light's early bloom, and 1.5 s) are drawn as the input
and each output, cropped to the light, its streaks and the ghost ring. ON red, OFF blue.
The recording held out for every model: ``benchmarks/night_recording.py``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from edeflare.io import read_events
from edeflare.methods import deflare
from edeflare.viz import event_frame, grid, save_image

SPAN_US = 2_000_000
WINDOWS_US = (200_000, 1_500_000)
WINDOW_US = 100_000
CROP = (slice(60, 620), slice(200, 960))  # rows, columns: the light, streaks, ghost ring
METHODS = (
    ("night", "model", {"weights": "night"}),
    ("general", "model", {"weights": "general"}),
    ("learned", "model", {"weights": "learned"}),
    ("dv-fastdecay", "dv-fastdecay", {}),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    events, size = read_events(args.recording)
    t0 = int(events["t"][0])
    events = events[events["t"] < t0 + SPAN_US]
    streams = {"input": events}
    for label, method, params in METHODS:
        streams[label] = deflare(events, size, method, rng=0, **params)
    frames, captions = [], []
    for start in WINDOWS_US:
        for label, ev in streams.items():
            t = ev["t"]
            part = ev[np.searchsorted(t, t0 + start) : np.searchsorted(t, t0 + start + WINDOW_US)]
            frames.append(event_frame(part, size)[CROP])
            captions.append(f"{label}, [{start / 1e6:g}, {(start + WINDOW_US) / 1e6:g}) s")
    save_image(args.out, grid(frames, ncols=len(streams), captions=captions))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
