"""Weights files through the package's deflarer (two windowings, the default) on the real
recordings: the annotated lights scored as `evaluate.py` scores them, the light-free
recordings by the fraction of events kept.

    python experiments/context-head/real_recordings.py NAME=RUN/model.safetensors ... --out r.json
"""

from __future__ import annotations

import argparse
import json
import time

from evaluate import score_real

from edeflare.methods import create_method


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("weights", nargs="+", help="NAME=PATH (a bundled name is a path too)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    methods = {
        name: create_method("model", weights=path)
        for name, path in (w.split("=", 1) for w in a.weights)
    }
    out: dict[str, dict] = {"real": {}, "no_light": {}}
    t0 = time.time()
    score_real(methods, out)
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1, default=float)
    print(f"done {time.time() - t0:.0f}s")


if __name__ == "__main__":
    main()
