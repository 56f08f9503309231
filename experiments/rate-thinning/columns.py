"""A run's drawn rows with only some feature columns, saved under the cache names that
``train-head --features NAMES`` over ``night`` looks for (the draws do not depend on which
features are computed, so these are the rows it would draw).

Run: python columns.py RUN_FROM RUN_TO NAMES   (NAMES comma-separated)
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np

from edeflare.io.sequence import list_sequences
from edeflare.models.event_features import DEFAULT_FEATURES
from edeflare.models.head_training import HeadTrainingConfig, _identity
from edeflare.models.infer import bundled_weights

src, dst, names = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3].split(",")
folders = sorted((src.parent / "s0").iterdir())  # as the shell's RUNS/s0/* lists them
keep = [DEFAULT_FEATURES.index(n) for n in names]
dst.mkdir(parents=True, exist_ok=True)
config = HeadTrainingConfig(features=DEFAULT_FEATURES, context=8)
for split in ("train", "test"):
    files = [f for d in folders if (d / split).is_dir() for f in list_sequences(d / split)]
    base = bundled_weights("night")
    with np.load(src / f"features-{split}-{_identity(files, base, config, split)}.npz") as z:
        rows = {k: z[k] for k in z.files}
    rows["x"] = np.ascontiguousarray(rows["x"][:, keep])
    sub = dataclasses.replace(config, features=tuple(names))
    out = dst / f"features-{split}-{_identity(files, base, sub, split)}.npz"
    with open(out, "wb") as f:
        np.savez(f, **rows)
    print(out.name, rows["x"].shape)
