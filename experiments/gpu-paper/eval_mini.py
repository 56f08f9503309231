"""python experiments/gpu-paper/eval_mini.py WEIGHTS OUT.json [SPLIT]: the GPU-trained
``unet3d.paper`` on the ``eflare-mini`` test split of ``benchmarks/flare_targets.py``
(20 sequences at 346x260, seed 9999) against the raw input and ``eflare`` (issue 13's
third target: no worse than ``eflare`` on any metric), on this CPU.
"""

import json
import sys

from edeflare.deflare import create_method
from edeflare.eval.benchmark import benchmark

weights, out = sys.argv[1], sys.argv[2]
split = sys.argv[3] if len(sys.argv) > 3 else "benchmarks/.data/eflare-mini-test/test"
methods = {
    "raw": "raw",
    "paper": create_method("model", weights=weights, batch_windows=1),
    "eflare": create_method("model", weights="eflare"),
}
result = benchmark(split, methods, progress=False)
means = {m: s.means for m, s in result.evaluation.methods.items()}
speed = {m: s.windows_per_s for m, s in result.speed.items()}
data = {"weights": weights, "split": split, "means": means, "windows_per_s": speed}
with open(out, "w") as f:
    json.dump(data, f, indent=2)
print(json.dumps(data, indent=2))
