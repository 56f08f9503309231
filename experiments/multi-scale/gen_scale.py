"""Training data at the larger sensor sizes (experiment multi-scale, issue 13 "every sensor size").

The eflare-night recipe at 640x480 and 1280x720, with its lights and their travel
scaled with the sensor: light radii of 4-45 px (640x480) and 6-60 px (1280x720),
against 3-28 px at 346x260, so halos (up to about 6 radii) reach 270-360 px; travel
up to 480 and 960 px. Seeds 505 and 506 (the scale check's test sequences: 4242).

    python experiments/multi-scale/gen_scale.py OUT640 640x480 [SEQUENCES]
    python experiments/multi-scale/gen_scale.py OUT1280 1280x720 [SEQUENCES]
"""

import sys
import time

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES

SIZES = {  # sensor -> (light radii px, travel px, seed)
    (640, 480): ((4.0, 45.0), (0.0, 480.0), 505),
    (1280, 720): ((6.0, 60.0), (0.0, 960.0), 506),
}

if __name__ == "__main__":
    out, size_text = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 20
    size = tuple(int(v) for v in size_text.split("x"))
    radii, travel, seed = SIZES[size]
    night = RECIPES["eflare-night"]
    script = night.config.script.__class__(
        **{**night.config.script.__dict__, "light_radius_px": radii, "travel_px": travel}
    )
    config = night.config.__class__(**{**night.config.__dict__, "script": script})
    recipe = night.replace(
        name=f"eflare-night-{size_text}",
        sequences=n,
        test_sequences=2,
        sensor_size=size,
        seed=seed,
        config=config,
    )
    t = time.time()
    generate_dataset(recipe, out, workers=2)
    print("took", round(time.time() - t), "s")
