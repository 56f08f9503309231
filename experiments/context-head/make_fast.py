"""Study data: eflare-mix's dense-640 with lights as large and fast as the Gen3 light's
(radius up to 40 px, up to 1,200 px of travel in a sequence), the scene alone stored.

    python experiments/context-head/make_fast.py OUT
"""

import dataclasses
import sys

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES

if __name__ == "__main__":
    dense = RECIPES["eflare-mix"].part("dense-640")
    script = dataclasses.replace(
        dense.config.script, light_radius_px=(2.0, 40.0), travel_px=(0.0, 1200.0)
    )
    recipe = dense.replace(
        name="study.fast-640",
        sequences=18,
        test_sequences=2,
        seed=212,
        config=dataclasses.replace(dense.config, script=script, components=True),
    )
    generate_dataset(recipe, sys.argv[1], workers=2, progress=False)
