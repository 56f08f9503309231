"""The annotated Gen3 light and DAVIS lamps thinned at random (each event kept with
probability q, seed 0), scored at one phase with a model at its card's threshold.

Run: python thin_probe.py WEIGHTS OUT.json [Q ...] [--rules-off]   (default q: 1, 0.5, 0.25;
--rules-off: every rule knob of the card at 0, the network's keep logits alone)
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from edeflare.eval.score import score_recording
from edeflare.io import read_events, write_events
from edeflare.lights import bundled_lights
from edeflare.models.infer import resolve_weights
from edeflare.models.weights import read_card

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
RECORDINGS = ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")

args = [a for a in sys.argv[1:] if a != "--rules-off"]
weights, dst = args[0], Path(args[1])
shares = [float(q) for q in args[2:]] or [1.0, 0.5, 0.25]
params = {"weights": weights}
if "--rules-off" in sys.argv:
    params.update({k: 0 for k in read_card(resolve_weights(weights)).rules})
out: dict[str, object] = {"weights": weights, "rules_off": "--rules-off" in sys.argv}
with tempfile.TemporaryDirectory() as tmp:
    for rec in RECORDINGS:
        r = read_events(REAL / rec)
        name = rec.split(".")[0]
        rows: dict[str, list[float]] = {}
        out[name] = rows
        for q in shares:
            ev = r.events[np.random.default_rng(0).random(r.events.size) < q]
            path = Path(tmp) / f"{name}_{q}.h5"
            write_events(path, ev, r.sensor_size)
            res = score_recording(
                path,
                ["model"],
                lights=bundled_lights(rec),
                phases=1,
                method_params={"model": params},
            )
            m = res.rows[0]
            row = [m.flare_removed, m.light_kept, m.background_kept, m.combined]
            rows[str(q)] = [round(float(v), 4) for v in row]
            print(name, q, rows[str(q)], flush=True)
dst.write_text(json.dumps(out, indent=1))
