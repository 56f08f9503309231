"""A run's drawn training rows with light dropout: in a random half of the training windows
(seed 0) every light feature reads as in a window without a light (the values
``window_features`` gives there), saved under the same cache name in another run; the test
rows linked as they are.

Run: python drop_lights.py RUN_FROM RUN_TO   (the runs' rows: H's 20 features)
"""

import math
import os
import sys
from pathlib import Path

import numpy as np

from edeflare.models.event_features import NO_LIGHT_RADII

NO_LIGHT = {"light_free": 1.0, "light_distance": math.log1p(NO_LIGHT_RADII), "halo": 0.0,
            "ghost": 0.0, "spike": 0.0, "far": 1.0}  # fmt: skip
FEATURES = ("net_logit,polarity,light_free,light_distance,halo,ghost,spike,far,crowded,field,"
            "balance_pixel,balance_8,balance_32,centre_distance,rel_pixel,rel_8,rel_32,rel_128,"
            "rel_support,rel_since").split(",")  # fmt: skip

src, dst = Path(sys.argv[1]), Path(sys.argv[2])
dst.mkdir(parents=True, exist_ok=True)
(train,) = src.glob("features-train-*.npz")
(test,) = src.glob("features-test-*.npz")
with np.load(train) as z:
    rows = {k: z[k] for k in z.files}
windows = int(rows["window"].max()) + 1
dropped = np.random.default_rng(0).random(windows) < 0.5
hit = dropped[rows["window"]]
x = rows["x"]
for name, value in NO_LIGHT.items():
    x[hit, FEATURES.index(name)] = value
with open(dst / train.name, "wb") as f:
    np.savez(f, **rows)
if not (dst / test.name).exists():
    os.link(test, dst / test.name)
lit = x[:, FEATURES.index("light_free")] < 0.5
print(
    f"{dropped.sum()} of {windows} windows dropped; {hit.sum()} of {hit.size} rows; "
    f"rows with a light now {lit.mean():.3f}"
)
