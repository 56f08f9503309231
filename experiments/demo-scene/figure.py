"""python experiments/demo-scene/figure.py OUT.png: the demo scene's street (the ground
truth's events that are not the light's) kept and dropped by the default, with the
halo prior's reach uncapped (as before 2026-11-27) and capped at a fifth of the
sensor's width (``edeflare.models.halos.HALO_MAX_REACH``); three 20 ms windows each.
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import edeflare.models.halos as halos
from edeflare.data.generate import RECIPES, generate_sequence
from edeflare.deflare import deflare
from edeflare.demo import DEMO_INDEX, DEMO_SEED
from edeflare.events import event_keys

recipe = RECIPES["eflare-night"].replace(seed=DEMO_SEED)
seq = generate_sequence(recipe, DEMO_INDEX % recipe.sequences)
size, inp, gt = seq.sensor_size, seq.streams["input"], seq.streams["gt"]
scene = np.isin(event_keys(gt, size), event_keys(seq.streams["background"], size))
cap = halos.HALO_MAX_REACH
fig, axes = plt.subplots(2, 3, figsize=(15, 8.4), constrained_layout=True)
variants = (("halo reach uncapped", 1e9), ("capped at 0.2 x width", cap))
for row, (label, reach) in enumerate(variants):
    halos.HALO_MAX_REACH = reach
    kept = np.isin(event_keys(gt, size), event_keys(deflare(inp, size, "model"), size))
    share = kept[scene].mean()
    for col in range(3):
        a = int(gt["t"][0]) + 20_000 * col
        sel = scene & (gt["t"] >= a) & (gt["t"] < a + 20_000)
        ax = axes[row, col]
        ax.scatter(gt["x"][sel & ~kept], gt["y"][sel & ~kept], s=0.4, c="tab:red", lw=0)
        ax.scatter(gt["x"][sel & kept], gt["y"][sel & kept], s=0.4, c="tab:green", lw=0)
        ax.set_xlim(0, size[0])
        ax.set_ylim(size[1], 0)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"{label}: {20 * col}-{20 * col + 20} ms", fontsize=10)
    axes[row, 0].set_ylabel(f"street kept {100 * share:.1f} %")
halos.HALO_MAX_REACH = cap
fig.suptitle(
    "The demo's street (ground truth without the light): kept by the default (green), dropped (red)"
)
fig.savefig(sys.argv[1], dpi=90)
