"""Is the sparse flare without a found light lost in simulation too? Each head's keep
decisions, at its card's threshold, on the subset's test rows (rate-thinning's D's drawn
rows; a head reading other features gets its columns as ``columns.py`` derives them),
split by part and by whether the light test found a light in the row's window: the share
of the flare removed and of the rest kept.

Run: python experiments/relative-rates/groups.py RUNS OUT.json NAME=WEIGHTS ...
"""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "rate-thinning"))
from _rows import cache_path

from edeflare.io.sequence import list_sequences
from edeflare.models.event_features import (
    DEFAULT_FEATURES,
    RELATIVE_FEATURES,
    relative_features,
)
from edeflare.models.event_head import head_logits
from edeflare.models.head_training import HeadTrainingConfig, _group, context_columns
from edeflare.models.infer import bundled_weights, resolve_weights
from edeflare.models.mask_kernels import keep_logit_threshold
from edeflare.models.weights import load_model

runs, dst = Path(sys.argv[1]), Path(sys.argv[2])
config = HeadTrainingConfig(features=DEFAULT_FEATURES, context=8)
with np.load(cache_path(runs / "D", bundled_weights("night"), config, "test")) as z:
    data = {k: z[k] for k in z.files}
folders = sorted((runs / "s0").iterdir())
files = [str(f) for d in folders if (d / "test").is_dir() for f in list_sequences(d / "test")]
groups = np.array([_group(files, int(s)) for s in data["source"]])
lit = data["x"][:, DEFAULT_FEATURES.index("light_free")] < 0.5
y = data["y"].astype(bool)
cols = {n: data["x"][:, k] for k, n in enumerate(DEFAULT_FEATURES)}
cols.update(relative_features(cols, list(RELATIVE_FEATURES)))
out: dict[str, dict] = {}
for arg in sys.argv[3:]:
    name, weights = arg.split("=", 1)
    net, card = load_model(resolve_weights(weights))[:2]
    head = net.head
    x = np.stack([cols[f] for f in head.feature_names], 1).astype(np.float32)
    logits = head_logits(head.numpy_params(), context_columns(head, {**data, "x": x}))
    keep = logits > keep_logit_threshold(card.keep_threshold)
    rows = {}
    for g in sorted(set(groups)):
        for light, mask in (("light found", lit), ("no light found", ~lit)):
            m = (groups == g) & mask
            if (m & ~y).sum() < 20:
                continue
            rows[f"{g}, {light}"] = {
                "flare removed": round(float(1 - keep[m & ~y].mean()), 3),
                "rest kept": round(float(keep[m & y].mean()), 3) if (m & y).any() else None,
                "rows": int(m.sum()),
                "flare rows": int((m & ~y).sum()),
            }
    out[name] = rows
    for k, v in rows.items():
        print(f"{name:8s} {k:40s} {v}", flush=True)
dst.write_text(json.dumps(out, indent=1))
