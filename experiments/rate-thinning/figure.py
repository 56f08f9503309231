"""figure.png: the Gen3 rotating light at 20-40 ms as recorded and with half its events
(each kept with probability 0.5, seed 0, as ``thin_probe.py`` thins it): the input, and
what ``night`` and ``learned`` keep of it.

Run: python experiments/rate-thinning/figure.py [OUT.png LABEL=WEIGHTS ...]   (other models)
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


def main(models: list[tuple[str, str]], dst: Path) -> None:
    r = read_events(REAL / FILE)
    t0 = int(r.events["t"][0])
    frames, captions = [], []
    for q in (1.0, 0.5):
        events = r.events[np.random.default_rng(0).random(r.events.size) < q]
        for label, weights in [("input", None), *models]:
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
    save_image(dst, grid(frames, ncols=1 + len(models), captions=captions))


if __name__ == "__main__":
    if len(sys.argv) > 1:
        pairs = [tuple(a.split("=", 1)) for a in sys.argv[2:]]
        main([(label, weights) for label, weights in pairs], Path(sys.argv[1]))
    else:
        main([("night", "night"), ("learned", "learned")], Path(__file__).parent / "figure.png")
