"""python experiments/demo-scene/variants.py [name=value ...]...: the demo's scene
(``edeflare demo``'s sequence) de-flared by the default with other parameters.

Each argument is one variant: comma-separated ``name=value`` parameters of the model
method (``-`` for the default; ``weights=PATH`` for other weights). Per variant: the
flare removed and the true events kept (:func:`edeflare.eval.metrics.deletion_shares`),
then the true events split into the scene's (the ground truth's events in the
sequence's ``background``) and the light's.
"""

import sys

import numpy as np

from edeflare.data.generate import RECIPES, generate_sequence
from edeflare.deflare import deflare
from edeflare.demo import DEMO_INDEX, DEMO_SEED
from edeflare.eval.metrics import deletion_shares
from edeflare.events import event_keys

recipe = RECIPES["eflare-night"].replace(seed=DEMO_SEED)
seq = generate_sequence(recipe, DEMO_INDEX % recipe.sequences)
size, inp, gt = seq.sensor_size, seq.streams["input"], seq.streams["gt"]


# the street, not the light
scene = np.isin(event_keys(gt, size), event_keys(seq.streams["background"], size))
print(f"{inp.size} input events, {gt.size} to keep ({scene.sum()} of the scene)", flush=True)
for arg in sys.argv[1:] or ["-"]:
    params = {} if arg == "-" else {
        k: v if k == "weights" else float(v) for k, v in (kv.split("=") for kv in arg.split(","))
    }  # fmt: skip
    out = deflare(inp, size, "model", **params)
    removed, kept = deletion_shares(inp, gt, out, size)
    kept_gt = np.isin(event_keys(gt, size), event_keys(out, size))
    street, light = 100 * kept_gt[scene].mean(), 100 * kept_gt[~scene].mean()
    print(
        f"{arg}: flare removed {100 * removed:.1f} %, true kept {100 * kept:.1f} %, "
        f"scene kept {street:.1f} %, light kept {light:.1f} %",
        flush=True,
    )
