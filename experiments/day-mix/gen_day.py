"""Training data with dense daytime-like streets under the night flare (experiment day-mix).

The eflare-night recipe (flare script, sparse sensing, hot pixels, keep-only targets)
with the synthetic street lit as by day: bright buildings, sky and road, strong
texture: 12-43 events per pixel and second (the Prophesee Gen4.1 daytime street:
27, 25 M events/s at 1280x720; the night recipe's streets: 1-5). Its events are all to
keep; the lights and their scattered flare are drawn as in eflare-night.

    python experiments/day-mix/gen_day.py OUT [SEQUENCES]
"""

import sys
import time

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES
from edeflare.sim.background import SceneConfig

DAY_SCENE = SceneConfig(
    sky_level=(80.0, 200.0),
    building_level=(60.0, 200.0),
    road_level=(50.0, 150.0),
    marking_level=(120.0, 230.0),
    window_level=(80.0, 230.0),
    texture_contrast=(0.1, 0.35),
    pan_px_per_s=(20.0, 200.0),
    zoom_per_s=(0.0, 0.8),
    lamps=(0, 2),
)

if __name__ == "__main__":
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 72
    recipe = RECIPES["eflare-night"].replace(
        name="eflare-day-mix", sequences=n, test_sequences=6, scene=DAY_SCENE, seed=101
    )
    t = time.time()
    generate_dataset(recipe, sys.argv[1], workers=2)
    print("took", round(time.time() - t), "s")
