"""Where does `learned` read the rate? The Gen3 light with half its events (each kept with
probability 0.5, seed 0), scored at one phase as ``thin_probe.py`` scores it, with some of
the head's per-event features given the values twice the rate would give them (each is
log(1 + x): the counts behind the rates and the support doubled, the time since the pixel's
last event halved): if the light comes back, those features carry the rate; if not, the
context maps (or the rest) do.

Run: python experiments/rate-thinning/rate_columns.py OUT.json
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from _half import score_half, write_half

import edeflare.models.infer as infer

RATES = ("rate_pixel", "rate_8", "rate_32", "rate_128", "rate_window", "support")
ARMS = {"as thinned": {}, "counts x 2": dict.fromkeys(RATES, 2.0),
        "counts x 2, since / 2": {**dict.fromkeys(RATES, 2.0), "since_pixel": 0.5},
        "since / 2": {"since_pixel": 0.5}}  # fmt: skip
original = infer.window_features


def run(scales: dict[str, float], path: Path) -> list[float]:
    def scaled(ctx, logits, names, **kwargs):  # type: ignore[no-untyped-def]
        f = original(ctx, logits, names, **kwargs)
        for i, name in enumerate(names):
            if name in scales:  # log(1 + x) -> log(1 + scale x)
                f[:, i] = np.log1p(scales[name] * np.expm1(f[:, i]))
        return f

    infer.window_features = scaled
    try:
        return score_half(path, {"weights": "learned"})
    finally:
        infer.window_features = original


out = {}
with tempfile.TemporaryDirectory() as tmp:
    path = write_half(tmp)
    for arm, scales in ARMS.items():
        out[arm] = run(scales, path)
        print(arm, out[arm], flush=True)
Path(sys.argv[1]).write_text(json.dumps(out, indent=1))
