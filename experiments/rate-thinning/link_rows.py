"""Link a tune-head run's drawn rows (over ``learned``) under the cache names that
``train-head`` over ``night`` looks for: the two share one network (the same tensors), so
the rows are those train-head would draw.

Run: python link_rows.py TUNE_RUN TRAIN_RUN THIN   (THIN: the run's --thin, 1 for none)
"""

import os
import sys
from pathlib import Path

from _rows import cache_path

from edeflare.models.event_features import DEFAULT_FEATURES
from edeflare.models.head_training import HeadTrainingConfig
from edeflare.models.infer import bundled_weights

src, dst, thin = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
config = HeadTrainingConfig(features=DEFAULT_FEATURES, context=8, thin=thin)
dst.mkdir(parents=True, exist_ok=True)
for split in ("train", "test"):
    new = cache_path(dst, bundled_weights("night"), config, split)
    if not new.exists():
        os.link(cache_path(src, bundled_weights("learned"), config, split), new)
    print(new.name)
