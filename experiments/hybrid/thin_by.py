"""python experiments/hybrid/thin_by.py SPLIT OUTDIR NET [N]: thin the input by another
method's per-cell counts. In each cell (pixel, polarity, a time bin) keep the input's
first min(n_input, n_NET) events, with NET's saved output (``outputs.py``) standing
in for the ground truth of the count oracle. Prints the eight metrics for bins of
2.5, 5, 10 and 20 ms, with the raw input's and NET's own rows (the first N sequences).
"""

import sys
from pathlib import Path

import numpy as np
from oracles import count_oracle

from edeflare.eval.evaluate import evaluate_events
from edeflare.io import open_events

split, outdir, net = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
n = int(sys.argv[4]) if len(sys.argv) > 4 else None
rows: dict[str, list] = {}
for path in sorted(split.glob("*.h5"))[:n]:
    src = open_events(path, group="input")
    inp, size = src.read(), src.sensor_size
    gt = open_events(path, group="gt").read()
    pred = np.load(outdir / f"{path.stem}.{net}.npy")
    start = min(int(inp["t"][0]), int(gt["t"][0])) // 20_000 * 20_000
    end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
    outs = {"raw": inp, net: pred}
    for b in (2_500, 5_000, 10_000, 20_000):
        outs[f"thinned by {net}, {b / 1000:g} ms"] = count_oracle(inp, pred, *size, b)
    for name, ev in outs.items():
        rows.setdefault(name, []).append(evaluate_events(gt, ev, size, start_us=start, end_us=end))
metrics = list(rows["raw"][0].means)
print("| method | " + " | ".join(metrics) + " |")
for name, ss in rows.items():  # each file weighs the same
    vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
    print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
