"""python experiments/streaks/score.py SPLIT LABEL=PATTERN ... [--pix]: the eight metrics
of saved outputs on a simulated split (PATTERN: a path with SEQ for the sequence's name,
as ``experiments/hybrid/outputs.py`` writes them), with the raw input's row.

``--pix`` adds, per output, its events in the pixels where the ground truth has an event
in the same 20 ms window (what the output would score if it also deleted every
flare-only pixel, and nothing else), and that oracle applied to the raw input.
"""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.events import event_keys
from edeflare.io import open_events

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "hybrid"))
from oracles import cell_keys

WIN_US = 20_000

split = Path(sys.argv[1])
specs = [a.split("=", 1) for a in sys.argv[2:] if "=" in a]
pix_rows = "--pix" in sys.argv
rows: dict[str, list] = {}
for path in sorted(split.glob("*.h5")):
    src = open_events(path, group="input")
    inp, size = src.read(), src.sensor_size
    gt = open_events(path, group="gt").read()
    scene = np.isin(cell_keys(inp, *size, WIN_US) // 2, cell_keys(gt, *size, WIN_US) // 2)
    outs = {"raw": inp} | ({"pixel oracle": inp[scene]} if pix_rows else {})
    for label, pattern in specs:
        ev = np.load(pattern.replace("SEQ", path.stem))
        outs[label] = ev
        if pix_rows:
            kept = np.isin(event_keys(inp, size), event_keys(ev, size))
            outs[f"{label} & pixel oracle"] = inp[scene & kept]
    start = min(int(inp["t"][0]), int(gt["t"][0])) // WIN_US * WIN_US
    end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
    for name, ev in outs.items():
        rows.setdefault(name, []).append(evaluate_events(gt, ev, size, start_us=start, end_us=end))
metrics = list(rows["raw"][0].means)
print("| method | " + " | ".join(metrics) + " |")
for name, ss in rows.items():  # each file weighs the same, as in edeflare.eval.evaluate
    vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
    print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
