"""python experiments/hybrid/real_thin.py WEIGHTS [KEY=VALUE ...]: the annotated real
recordings (one windowing, phase 0) and the scenes without lights, with the mask's keep
probabilities decoded by threshold and by window thinning (``thin.py``)."""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.score import bundled_lights, load_lights, score_events
from edeflare.io import read_events
from edeflare.models.infer import ModelDeflarer, resolve_weights

sys.path.insert(0, str(Path(__file__).parent))
from thin import WIN_US, thin

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
model = ModelDeflarer(resolve_weights(sys.argv[1]), **dict(kv.split("=") for kv in sys.argv[2:]))


def outputs(events, size):
    t = events["t"].astype(np.int64)
    starts = np.unique(t // WIN_US) * WIN_US
    wins = [(int(s), events[(t >= s) & (t < s + WIN_US)]) for s in starts]
    kept = {"threshold": [], "thin": []}
    for i in range(0, len(wins), 4):
        batch = wins[i : i + 4]
        for (_, ev), v in zip(batch, model.window_logits(batch, size), strict=True):
            p = 1.0 / (1.0 + np.exp(-(v + np.log(3.0))))
            kept["threshold"].append(ev[p > 0.5])
            kept["thin"].append(ev[thin(ev, p, *size, bin_us=WIN_US)])
    return {k: np.concatenate(v) for k, v in kept.items()}


for rec in ["prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4"]:
    r = read_events(REAL / rec)
    preds = outputs(r.events, r.sensor_size)
    lights = load_lights(bundled_lights(rec), r.sensor_size)
    for s in score_events(r.events, preds, lights, r.sensor_size):
        d = s.to_dict()
        print(
            f"{rec[:10]} {d['method']:9s} flare {d['flare_removed']:.3f} light "
            f"{d['light_kept']:.3f} bg {d['background_kept']:.3f} combined {d['combined']:.3f}"
        )
for rec in [
    "davis346_street_cars.aedat4",
    "davis346_lowlight_cradle.aedat4",
    "prophesee_gen41_street.raw",
]:
    r = read_events(REAL / rec)
    preds = outputs(r.events, r.sensor_size)
    print(rec[:16], " ".join(f"{k} {v.size / r.events.size:.3f}" for k, v in preds.items()))
