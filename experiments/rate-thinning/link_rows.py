"""Link a tune-head run's drawn rows (over ``learned``) under the cache names that
``train-head`` over ``night`` looks for: the two share one network (the same tensors), so
the rows are those train-head would draw.

Run: python link_rows.py TUNE_RUN TRAIN_RUN THIN   (THIN: the run's --thin, 1 for none)
"""

import os
import sys
from pathlib import Path

from edeflare.io.sequence import list_sequences
from edeflare.models.event_features import DEFAULT_FEATURES
from edeflare.models.head_training import HeadTrainingConfig, _identity
from edeflare.models.infer import bundled_weights

src, dst, thin = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
folders = sorted((src.parent / "s0").iterdir())  # as the shell's RUNS/s0/* lists them
config = HeadTrainingConfig(features=DEFAULT_FEATURES, context=8, thin=thin)
dst.mkdir(parents=True, exist_ok=True)
for split in ("train", "test"):
    files = [f for d in folders if (d / split).is_dir() for f in list_sequences(d / split)]
    old = _identity(files, bundled_weights("learned"), config, split)
    new = dst / f"features-{split}-{_identity(files, bundled_weights('night'), config, split)}.npz"
    if not new.exists():
        os.link(src / f"features-{split}-{old}.npz", new)
    print(new.name)
