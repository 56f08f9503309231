"""Training data with dense halos next to the lights (experiment dense-halo, issue 13).

The eflare-night recipe with the sparse-sensing stage letting far more of the
scattered light through: survival log-uniform in [0.1, 1] per sequence (eflare-night:
[0.003, 0.2]), falloff 1 (eflare-night: 2). The halo and glare next to a light then
come out dense (meant to resemble the optics test set's blurred discs), labelled to
drop; the source, its 2 px glow, the street and the background
activity are labelled to keep, as in eflare-night.

    python experiments/dense-halo/gen_dense.py OUT [SEQUENCES]            # d3's data
    python experiments/dense-halo/gen_dense.py OUT [SEQUENCES] --solid    # d4's data

``--solid``: survival log-uniform in [0.3, 1] at every distance (falloff 0) and a star
filter in every sequence, seed 303: solid star arms like the optics test set's.
"""

import sys
import time

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES

if __name__ == "__main__":
    solid = "--solid" in sys.argv
    args = [a for a in sys.argv[1:] if a != "--solid"]
    n = int(args[1]) if len(args) > 1 else 72
    night = RECIPES["eflare-night"]
    survival, falloff = ((0.3, 1.0), 0.0) if solid else ((0.1, 1.0), 1.0)
    sensing = night.config.sensing.__class__(
        **{**night.config.sensing.__dict__, "survival": survival, "falloff": falloff}
    )
    script = night.config.script
    if solid:
        script = script.__class__(**{**script.__dict__, "star_probability": 1.0})
    config = night.config.__class__(
        **{**night.config.__dict__, "sensing": sensing, "script": script}
    )
    recipe = night.replace(
        name="eflare-dense-halo-solid" if solid else "eflare-dense-halo",
        sequences=n,
        test_sequences=6,
        seed=303 if solid else 202,
        config=config,
    )
    t = time.time()
    generate_dataset(recipe, args[0], workers=2)
    print("took", round(time.time() - t), "s")
