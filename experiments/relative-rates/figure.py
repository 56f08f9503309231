"""figure.png: the Gen3 rotating light at 20-40 ms as recorded and with half its events
(each kept with probability 0.5, seed 0, as rate-thinning's ``thin_probe.py`` thins it):
the input, and what ``learned`` and a head of H's form keep of it.

Run: python experiments/relative-rates/figure.py WEIGHTS   (H's form: RUNS/H1/model.safetensors)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from edeflare import deflare
from edeflare.io import read_events
from edeflare.viz import event_frame, grid, save_image

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
FILE = "prophesee_gen3_rotating_light.raw"
CROP = (slice(40, 440), slice(120, 620))


def main(relative: str) -> None:
    r = read_events(REAL / FILE)
    t0 = int(r.events["t"][0])
    frames, captions = [], []
    for q in (1.0, 0.5):
        events = r.events[np.random.default_rng(0).random(r.events.size) < q]
        for label, weights in (("input", None), ("learned", "learned"), ("relative", relative)):
            out = (
                events
                if weights is None
                else deflare(events, r.sensor_size, "model", weights=weights, rng=0)
            )
            t = out["t"]
            part = out[(t >= t0 + 20_000) & (t < t0 + 40_000)]
            frames.append(event_frame(part, r.sensor_size)[CROP])
            captions.append(
                f"{label}, {'as recorded' if q == 1 else 'half the events'} ({part.size:,} events)"
            )
    save_image(
        Path(__file__).resolve().parent / "figure.png", grid(frames, ncols=3, captions=captions)
    )


if __name__ == "__main__":
    main(sys.argv[1])
