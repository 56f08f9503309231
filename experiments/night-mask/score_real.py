"""Score models against dv-fastdecay on the annotated real recordings (edeflare score's numbers).

python score_real.py NAME=W.safetensors [NAME=W2.safetensors ...]
"""
import sys

from edeflare.eval.score import bundled_lights, score_recording
from edeflare.deflare import deflare
from edeflare.io import read_events
from edeflare.eval.score import load_lights, score_events

REAL = "../shared/data/real/"
RECS = ["prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4"]
if __name__ == "__main__":
    models = dict(a.split("=", 1) for a in sys.argv[1:])
    for rec in RECS:
        r = read_events(REAL + rec)
        ev, size = r.events, r.sensor_size
        outs = {"dv-fastdecay": deflare(ev, size, "dv-fastdecay"), "dv-bafilter": deflare(ev, size, "dv-bafilter")}
        for name, w in models.items():
            outs[name] = deflare(ev, size, "model", weights=w)
        lights = load_lights(bundled_lights(rec), size)
        print(rec)
        for s in score_events(ev, outs, lights, size):
            d = s.to_dict()
            print(f"  {d['method']:>14}: flare removed {d['flare_removed']:.3f} light kept {d['light_kept']:.3f} "
                  f"bg kept {d['background_kept']:.3f} combined {d['combined']:.3f}")
