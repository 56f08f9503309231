"""python experiments/gpu-paper/eval_r_sim.py WEIGHTS OUT.json [SPLIT]: the GPU-trained
``unet3d.paper`` on ``eflare-r-sim`` (640x480, never trained on) against the raw input,
with the reconstruction scores (bundled ``firenet``), on this CPU.

One window per network call (the 3D network needs about 2.7 GiB per 640x480 window on
CPU). Prints the metric means and the downstream scores and writes them to OUT.json.
"""

import json
import sys

from edeflare.deflare import create_method
from edeflare.eval.benchmark import benchmark

weights, out = sys.argv[1], sys.argv[2]
split = sys.argv[3] if len(sys.argv) > 3 else "benchmarks/.data/eflare-r-sim/test"
methods = {"raw": "raw", "paper": create_method("model", weights=weights, batch_windows=1)}
result = benchmark(split, methods, downstream=True, progress=False)
means = {m: s.means for m, s in result.evaluation.methods.items()}
speed = {m: s.windows_per_s for m, s in result.speed.items()}
data = {"weights": weights, "split": split, "means": means, "downstream": result.downstream,
        "windows_per_s": speed}
with open(out, "w") as f:
    json.dump(data, f, indent=2)
print(json.dumps(data, indent=2))
