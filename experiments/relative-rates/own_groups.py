"""A run's keep decisions at its card's threshold on its own drawn test rows, by part and
by whether the light test found a light in the row's window: the share of the flare
removed and of the rest kept (groups.py does this on rate-thinning's subset's rows).

Run: python experiments/relative-rates/own_groups.py RUN OUT.json DATA_FOLDER...
(RUN: a train-head run folder; DATA_FOLDER: the data it was trained on, in its order)
"""

import json
import sys
from pathlib import Path

from _own_rows import own_test_rows

from edeflare.models.event_head import head_logits
from edeflare.models.head_training import context_columns
from edeflare.models.mask_kernels import keep_logit_threshold
from edeflare.models.weights import load_model

run, dst = Path(sys.argv[1]), Path(sys.argv[2])
data, groups = own_test_rows(run, sys.argv[3:])
net, card = load_model(run / "model.safetensors")[:2]
head = net.head
lit = data["x"][:, head.feature_names.index("light_free")] < 0.5
y = data["y"].astype(bool)
keep = head_logits(head.numpy_params(), context_columns(head, data)) > keep_logit_threshold(
    card.keep_threshold
)
out = {}
for g in sorted(set(groups)):
    for light, mask in (("light found", lit), ("no light found", ~lit)):
        m = (groups == g) & mask
        if (m & ~y).sum() < 20:
            continue
        out[f"{g}, {light}"] = {
            "flare removed": round(float(1 - keep[m & ~y].mean()), 3),
            "rest kept": round(float(keep[m & y].mean()), 3) if (m & y).any() else None,
            "flare rows": int((m & ~y).sum()),
        }
        print(f"{g}, {light}: {out[f'{g}, {light}']}", flush=True)
dst.write_text(json.dumps(out, indent=1) + "\n")
