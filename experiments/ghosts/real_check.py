"""python experiments/ghosts/real_check.py [WEIGHTS...] [name=value...]: a model on the real
recordings (``name=value``: a parameter of the model method for every run, e.g.
``ghost_shift=2``).

Per weights file (default: the bundled default): on the two annotated recordings the
score of ``edeflare score --phases 4`` (the recording delayed by 0, 5, 10, 15 ms; means
and the worst phase's combined score), then the share of events kept on the real
recordings without a bright light (DAVIS346 street and cradle, Gen4.1 street).
"""

import sys

import numpy as np

from edeflare.deflare import deflare
from edeflare.eval.score import load_lights, score_events
from edeflare.io import read_events

REAL = "../shared/data/real/"
LIGHTS = "src/edeflare/assets/lights/"
SCORED = ("prophesee_gen3_rotating_light", "davis346_flicker_lamps")
SCENES = ("davis346_street_cars.aedat4", "davis346_lowlight_cradle.aedat4",
          "prophesee_gen41_street.raw")  # fmt: skip
EXT = {"prophesee_gen3_rotating_light": ".raw", "davis346_flicker_lamps": ".aedat4"}


def main(weights, params):
    kw = {**params, **({} if weights is None else {"weights": weights})}
    line = [str(weights or "bundled") + "".join(f" {k}={v}" for k, v in params.items())]
    for name in SCORED:
        ev0, size = read_events(REAL + name + EXT[name])
        lights = load_lights(LIGHTS + name + ".json", size)
        rows = []
        for shift in (0, 5000, 10000, 15000):
            ev = ev0.copy()
            ev["t"] += shift
            out = deflare(ev, size, "model", **kw)
            out["t"] -= shift
            s = score_events(ev0, {"m": out}, lights, size)[0]
            rows.append((s.flare_removed, s.light_kept, s.background_kept, s.combined))
        a = np.array(rows, dtype=float)
        m = np.nanmean(a, axis=0)
        line.append(f"{name.split('_')[0]}: {100 * m[0]:.1f} / {100 * m[1]:.1f} / "
                    f"{100 * m[2]:.1f} / {m[3]:.3f} ({a[:, 3].min():.3f})")  # fmt: skip
    for name in SCENES:
        rec = read_events(REAL + name)
        kept = deflare(rec.events, rec.sensor_size, "model", **kw).size / rec.events.size
        line.append(f"{name.split('.')[0]} {100 * kept:.1f} %")
    print("; ".join(line), flush=True)


if __name__ == "__main__":
    params = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
    params = {k: float(v) for k, v in params.items()}
    for w in [a for a in sys.argv[1:] if "=" not in a] or [None]:
        main(w, params)
