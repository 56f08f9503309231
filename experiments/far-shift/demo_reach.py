"""python experiments/far-shift/demo_reach.py [name=value,...]: how far from its light the
demo's flare lies, and where the flare is that a parameter set keeps and the card's
default drops (distances from the light stream's median position, in pixels).

Default parameters: the far shift measured by the sensor's width alone
(``radii=0``: patches ``far_from_lights``' default) with far shift 4."""

import sys

import numpy as np

import edeflare.models.halos as halos
from edeflare.data.generate import RECIPES, generate_sequence
from edeflare.deflare import deflare
from edeflare.demo import DEMO_INDEX, DEMO_SEED
from edeflare.events import event_keys

arg = sys.argv[1] if len(sys.argv) > 1 else "radii=0,far_shift=4"
params = {k: float(v) for k, v in (kv.split("=") for kv in arg.split(","))}
radii = params.pop("radii", None)
recipe = RECIPES["eflare-night"].replace(seed=DEMO_SEED)
seq = generate_sequence(recipe, DEMO_INDEX % recipe.sequences)
size, inp, gt, light = (seq.sensor_size, *(seq.streams[k] for k in ("input", "gt", "light")))
keys = event_keys(inp, size)
flare = ~np.isin(keys, event_keys(gt, size))
base = np.isin(keys, event_keys(deflare(inp, size, "model", far_shift=0.0), size))
if radii is not None:
    halos.far_from_lights.__kwdefaults__["radii"] = radii
other = np.isin(keys, event_keys(deflare(inp, size, "model", **params), size))
cx, cy = np.median(light["x"]), np.median(light["y"])
d = np.hypot(inp["x"] - cx, inp["y"] - cy)
pct = [5, 25, 50, 75, 95]
print(f"light at ({cx:.0f}, {cy:.0f}); {flare.sum()} flare events")
print("flare's distance, percentiles", pct, np.round(np.percentile(d[flare], pct)).tolist())
extra = flare & other & ~base
print(f"{arg}: keeps {extra.sum()} flare events more than without the far shift, at",
      np.round(np.percentile(d[extra], pct)).tolist() if extra.any() else "-")  # fmt: skip
