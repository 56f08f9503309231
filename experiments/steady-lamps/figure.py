"""figure.png: the night recording at 9.0-9.1 s and the DAVIS lamps at 40-60 ms, the input
and each model's output (`learned`, fit A, fit B).

Run: python experiments/steady-lamps/figure.py FAERY_DATA A.safetensors B.safetensors
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import REAL  # noqa: E402

from edeflare import deflare  # noqa: E402
from edeflare.io import read_events  # noqa: E402
from edeflare.viz import event_frame, grid, save_image  # noqa: E402

CASES = (  # file, de-flared from / to (µs after its start), drawn from / to, crop
    ("evt3.raw", 8_900_000, 9_100_000, 9_000_000, (slice(60, 620), slice(200, 960))),
    ("davis346_flicker_lamps.aedat4", 0, 130_000, 40_000, (slice(0, 260), slice(0, 346))),
)


def main() -> None:
    faery, a, b = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
    frames, captions = [], []
    for file, lo, hi, start, crop in CASES:
        events, size = read_events((faery if file == "evt3.raw" else REAL) / file)
        t0 = int(events["t"][0])
        events = events[(events["t"] >= t0 + lo) & (events["t"] < t0 + hi)]
        span = 100_000 if file == "evt3.raw" else 20_000
        for label, weights in (("input", None), ("learned", "learned"), ("fit A", a),
                               ("fit B (steady lamps)", b)):  # fmt: skip
            out = events if weights is None else deflare(events, size, "model", weights=weights)
            t = out["t"]
            part = out[(t >= t0 + start) & (t < t0 + start + span)]
            frames.append(event_frame(part, size)[crop])
            captions.append(f"{label}, {file.split('.')[0]}")
    save_image(
        Path(__file__).resolve().parent / "figure.png", grid(frames, ncols=4, captions=captions)
    )


if __name__ == "__main__":
    main()
