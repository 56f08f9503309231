"""A weights file on eflare-forward with one windowing and with two (the default).

python experiments/context-head/forward_windowings.py RUN/model.safetensors out.json
"""

import json
import sys
import time

from evaluate import FORWARD

from edeflare.eval.benchmark import benchmark
from edeflare.io.sequence import list_sequences
from edeflare.methods import create_method

if __name__ == "__main__":
    weights, out_path = sys.argv[1], sys.argv[2]
    methods = {
        "raw": create_method("raw"),
        "one-view": create_method("model", weights=weights, phase_shift_us=0),
        "two-views": create_method("model", weights=weights),
    }
    t0 = time.time()
    result = benchmark(list_sequences(FORWARD), methods, progress=False)
    means = {m: s.means for m, s in result.evaluation.methods.items()}
    raw = means["raw"]["chamfer"]
    for m, v in means.items():
        print(m, {k: round(x, 3) for k, x in v.items()}, f"{1 - v['chamfer'] / raw:.1%} below raw")
    print(f"{time.time() - t0:.0f}s")
    with open(out_path, "w") as f:
        json.dump(means, f, indent=1)
