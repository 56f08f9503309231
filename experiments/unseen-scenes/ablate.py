"""What makes `learned` delete the turning face: its head's inputs, a group at a time.

For each 20 ms window of the face's busiest quarter of 100 ms bins (as
benchmarks/unseen_scenes.py), `learned`'s head inputs (`ModelDeflarer.head_inputs`, one
windowing), and the share kept at its threshold as they are, with the light features set
to what they hold without a light, and with the context columns set to zero.

Run: python experiments/unseen-scenes/ablate.py DIR   (DIR as unseen_scenes.py's --folder)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from unseen_scenes import BIN_US, busy_bins, load_scene

from edeflare.models.event_features import DEFAULT_FEATURES
from edeflare.models.event_head import head_logits
from edeflare.models.infer import ModelDeflarer, bundled_weights

LIGHT = {"light_free": 1.0, "light_distance": float(np.log(65)), "halo": 0.0, "ghost": 0.0,
         "spike": 0.0, "far": 1.0}  # fmt: skip


def main() -> None:
    events, size = load_scene(Path(sys.argv[1]), "face")
    d = ModelDeflarer(bundled_weights("learned"), runtime="torch")
    threshold = float(np.log(d.card.keep_threshold / (1 - d.card.keep_threshold)))
    names = list(DEFAULT_FEATURES)
    assert tuple(d.card.head["features"]) == tuple(names), d.card.head["features"]
    _, kind = busy_bins(events)
    t0, t = int(events["t"][0]), events["t"]
    kept = {"as is": 0, "no-light features": 0, "context zero": 0}
    light_on = total = 0
    for b in np.flatnonzero(kind == 1):
        for k in range(BIN_US // d.window_us):
            a = t0 + b * BIN_US + k * d.window_us
            w = events[np.searchsorted(t, a) : np.searchsorted(t, a + d.window_us)]
            if not w.size:
                continue
            (x,) = d.head_inputs([(a, w)], size)
            total += w.size
            light_on += int(np.count_nonzero(x[:, names.index("light_free")] < 0.5))
            y = x.copy()
            for f, v in LIGHT.items():
                y[:, names.index(f)] = v
            z = x.copy()
            z[:, len(names) :] = 0.0
            for label, inputs in (("as is", x), ("no-light features", y), ("context zero", z)):
                kept[label] += int(np.count_nonzero(head_logits(d.head_params, inputs) > threshold))
    print(f"busiest quarter: {total:,} events; with a light in their window: {light_on:,}")
    for label, n in kept.items():
        print(f"{label}: {100 * n / total:.1f} % kept")


if __name__ == "__main__":
    main()
