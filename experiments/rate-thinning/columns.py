"""A run's drawn rows with only some feature columns, saved under the cache names that
``train-head --features NAMES`` over ``night`` looks for (the draws do not depend on which
features are computed, so these are the rows it would draw). A rate-relative feature
(``rel_*``) is computed from the run's absolute columns (``relative_features``).

Run: python columns.py RUN_FROM RUN_TO NAMES   (NAMES comma-separated)
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np
from _rows import cache_path

from edeflare.models.event_features import (
    DEFAULT_FEATURES,
    RELATIVE_FEATURES,
    relative_features,
)
from edeflare.models.head_training import HeadTrainingConfig
from edeflare.models.infer import bundled_weights

src, dst, names = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3].split(",")
dst.mkdir(parents=True, exist_ok=True)
config = HeadTrainingConfig(features=DEFAULT_FEATURES, context=8)
sub = dataclasses.replace(config, features=tuple(names))
base = bundled_weights("night")
for split in ("train", "test"):
    with np.load(cache_path(src, base, config, split)) as z:
        rows = {k: z[k] for k in z.files}
    cols = {n: rows["x"][:, k] for k, n in enumerate(DEFAULT_FEATURES)}
    cols.update(relative_features(cols, [n for n in names if n in RELATIVE_FEATURES]))
    rows["x"] = np.stack([cols[n] for n in names], 1).astype(np.float32)
    out = cache_path(dst, base, sub, split)
    with open(out, "wb") as f:
        np.savez(f, **rows)
    print(out.name, rows["x"].shape)
