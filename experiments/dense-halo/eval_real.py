"""python experiments/dense-halo/eval_real.py WEIGHTS [THRESHOLD]: scores on the annotated lights + scene kept on flare-free recordings + uniform noise."""
import sys
import numpy as np
from edeflare.deflare import deflare
from edeflare.io import read_events
from edeflare.eval.score import bundled_lights, load_lights, score_events
from edeflare.events import make_events
REAL = str(__import__("pathlib").Path(__file__).resolve().parents[3] / "shared" / "data" / "real") + "/"
w = sys.argv[1]
kw = {"keep_threshold": float(sys.argv[2])} if len(sys.argv) > 2 else {}
line = [w.split("/")[-1]]
comb = []
for rec in ["prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4"]:
    r = read_events(REAL + rec)
    out = deflare(r.events, r.sensor_size, "model", weights=w, **kw)
    s = score_events(r.events, {"m": out}, load_lights(bundled_lights(rec), r.sensor_size), r.sensor_size)[0].to_dict()
    line.append(f"{rec[:5]} fl {s['flare_removed']:.3f} li {s['light_kept']:.3f} bg {s['background_kept']:.3f} C {s['combined']:.3f}")
for rec in ["davis346_street_cars.aedat4", "davis346_lowlight_cradle.aedat4", "prophesee_gen41_street.raw"]:
    r = read_events(REAL + rec)
    out = deflare(r.events, r.sensor_size, "model", weights=w, **kw)
    line.append(f"{rec[9:15] if rec.startswith('davis') else 'gen41'} {out.size / r.events.size:.3f}")
rng = np.random.default_rng(0)
for rate in (3.0, 20.0):
    n = int(rate * 346 * 260 * 0.5)
    ev = make_events(np.sort(rng.integers(0, 500_000, n)), rng.integers(0, 346, n), rng.integers(0, 260, n), rng.integers(0, 2, n))
    out = deflare(ev, (346, 260), "model", weights=w, **kw)
    line.append(f"noise{rate:g} {out.size / n:.3f}")
print(" | ".join(line), flush=True)
