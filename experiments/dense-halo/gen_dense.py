"""Training data with dense halos next to the lights (experiment dense-halo, issue 13).

The eflare-night recipe with the sparse-sensing stage letting far more of the
scattered light through: survival log-uniform in [0.1, 1] per sequence (eflare-night:
[0.003, 0.2]), falloff 1 (eflare-night: 2). The halo and glare next to a light then
come out as dense as the optics test set's blurred discs and the Gen3 recording's
arc, labelled to drop; the source, its 2 px glow, the street and the background
activity are labelled to keep, as in eflare-night.

    python experiments/dense-halo/gen_dense.py OUT [SEQUENCES]
"""

import sys
import time

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES

if __name__ == "__main__":
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 72
    night = RECIPES["eflare-night"]
    sensing = night.config.sensing.__class__(
        **{**night.config.sensing.__dict__, "survival": (0.1, 1.0), "falloff": 1.0}
    )
    recipe = night.replace(
        name="eflare-dense-halo",
        sequences=n,
        test_sequences=6,
        seed=202,
        config=night.config.__class__(**{**night.config.__dict__, "sensing": sensing}),
    )
    t = time.time()
    generate_dataset(recipe, sys.argv[1], workers=2)
    print("took", round(time.time() - t), "s")
