"""Weights files through the package's deflarer (two windowings, the default) on the real
recordings: the annotated lights scored as `edeflare score` does, the light-free recordings
by the fraction of events kept.

    python experiments/context-head/real_recordings.py NAME=RUN/model.safetensors ... --out r.json
"""

from __future__ import annotations

import argparse
import json
import time

from evaluate import LIGHTS, NO_LIGHT, REAL

from edeflare.eval.score import score_recording
from edeflare.io import read_events
from edeflare.lights import bundled_lights
from edeflare.methods import create_method
from edeflare.methods.base import METHODS


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("weights", nargs="+", help="NAME=PATH (a bundled name is a path too)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    named = dict(w.split("=", 1) for w in a.weights)
    for name, path in named.items():
        key = f"study-{name}"
        if key not in METHODS:
            METHODS.register(key, lambda path=path: create_method("model", weights=path))
    out: dict[str, dict] = {"real": {}, "no_light": {}}
    t0 = time.time()
    for rec in LIGHTS:
        r = score_recording(REAL / rec, [f"study-{n}" for n in named], lights=bundled_lights(rec))
        for row in r.rows:
            out["real"].setdefault(rec, {})[row.method] = {
                "flare removed": row.flare_removed,
                "light kept": row.light_kept,
                "background kept": row.background_kept,
                "combined": row.combined,
            }
            print(
                f"{rec[:24]:24s} {row.method:18s} flare {row.flare_removed:.3f} light "
                f"{row.light_kept:.3f} bg {row.background_kept:.3f} comb {row.combined:.3f}",
                flush=True,
            )
    for rec in NO_LIGHT:
        r = read_events(REAL / rec)
        for name in named:
            kept = create_method(f"study-{name}")(r.events, r.sensor_size).size / r.events.size
            out["no_light"].setdefault(rec, {})[name] = kept
            print(f"{rec[:24]:24s} {name:18s} kept {kept:.3f}", flush=True)
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1, default=float)
    print(f"done {time.time() - t0:.0f}s")


if __name__ == "__main__":
    main()
