"""The annotated Gen3 light and DAVIS lamps thinned at random (each event kept with
probability q, seed 0), scored at one phase with a model at its card's threshold.

Run: python thin_probe.py WEIGHTS OUT.json [Q ...]   (default q: 1, 0.5, 0.25)
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from edeflare.eval.score import score_recording
from edeflare.io import read_events, write_events
from edeflare.lights import bundled_lights

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
RECORDINGS = ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")

weights, dst = sys.argv[1], Path(sys.argv[2])
shares = [float(q) for q in sys.argv[3:]] or [1.0, 0.5, 0.25]
out: dict[str, dict[str, list[float]]] = {"weights": weights}  # type: ignore[dict-item]
with tempfile.TemporaryDirectory() as tmp:
    for rec in RECORDINGS:
        r = read_events(REAL / rec)
        name = rec.split(".")[0]
        out[name] = {}
        for q in shares:
            ev = r.events[np.random.default_rng(0).random(r.events.size) < q]
            path = Path(tmp) / f"{name}_{q}.h5"
            write_events(path, ev, r.sensor_size)
            res = score_recording(path, ["model"], lights=bundled_lights(rec), phases=1,
                                  method_params={"model": {"weights": weights}})
            m = res.rows[0]
            row = [m.flare_removed, m.light_kept, m.background_kept, m.combined]
            out[name][str(q)] = [round(float(v), 4) for v in row]
            print(name, q, out[name][str(q)], flush=True)
dst.write_text(json.dumps(out, indent=1))
