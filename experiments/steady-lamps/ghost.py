"""The night recording's halo and ghost removed by each model, at four window phases.

Run: python experiments/steady-lamps/ghost.py FAERY_DATA OUT.json WEIGHTS...
(as benchmarks/night_recording.py scores its model rows; each model at its card's threshold)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from edeflare.eval.score import score_recording
from edeflare.lights import load_lights

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    faery, out, models = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3:]
    lights = load_lights(ROOT / "benchmarks" / "night_recording_lights.json", (1280, 720))
    rows = {}
    for weights in models:
        report = score_recording(faery / "evt3.raw", ["model"], lights=lights, phases=4,
                                 method_params={"model": {"weights": weights}})  # fmt: skip
        (r,) = report.rows
        rows[weights] = {k: round(float(getattr(r, k)), 4) for k in
                         ("halo_removed", "ghost_removed", "flare_removed", "light_kept",
                          "combined")}  # fmt: skip
        print(weights, rows[weights], flush=True)
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
