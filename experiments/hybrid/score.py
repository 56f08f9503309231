"""python experiments/hybrid/score.py SPLIT OUTDIR: score hybrids of the mask default
(``night``) and a voxel network's output (``paper``) saved by ``outputs.py``.

Cells are (x, y, polarity, 2.5 ms bin). Variants:

- ``restore-cell``: night's events plus the network's events in cells where the
  input has none (the network only adds what flare suppressed);
- ``restore-pixel``: the same, for pixels with no input event in the window;
- ``paper-cut``: the network's events minus those in cells where the input had
  events and night kept none;
- ``cut+restore``: ``paper-cut`` plus night's events;
- ``keep-only oracle``: the input's events within 2 normalised units of a ground-truth
  event (as in ``benchmarks/flare_targets.py``);
- ``count oracle``: in each cell, the input's first min(n_input, n_gt) events.
"""

import json
import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.eval.metrics import keep_only_oracle
from edeflare.events import concat_events, empty_events
from edeflare.io import open_events

sys.path.insert(0, str(Path(__file__).parent))
from oracles import cell_keys, count_oracle

split, outdir = Path(sys.argv[1]), Path(sys.argv[2])
net = sys.argv[3] if len(sys.argv) > 3 else "paper"  # "none": the oracles only
BIN_US, WIN_US = 2_500, 20_000


def pick(ev, mask):
    return ev[mask] if ev.size else ev


def merge(*parts):
    parts = [p for p in parts if p.size]
    if not parts:
        return empty_events()
    ev = concat_events(parts)
    return ev[np.argsort(ev["t"], kind="stable")]


segs: dict[str, list] = {}
for path in sorted(split.glob("*.h5")):
    src = open_events(path, group="input")
    inp, size = src.read(), src.sensor_size
    gt = open_events(path, group="gt").read()
    w, h = size
    if net == "none":
        night = paper = empty_events()
    else:
        night = np.load(outdir / f"{path.stem}.night.npy")
        paper = np.load(outdir / f"{path.stem}.{net}.npy")
    k_in_cell = cell_keys(inp, w, h, BIN_US)
    k_in_pix = cell_keys(inp, w, h, WIN_US) // 2  # window-pixel
    k_night = cell_keys(night, w, h, BIN_US)
    p_cell = cell_keys(paper, w, h, BIN_US)
    p_pix = cell_keys(paper, w, h, WIN_US) // 2
    new_cell = ~np.isin(p_cell, k_in_cell)
    new_pix = ~np.isin(p_pix, k_in_pix)
    deleted_cells = np.setdiff1d(k_in_cell, k_night)
    cut = ~np.isin(p_cell, deleted_cells)
    variants = {
        "raw": inp,
        "night": night,
        net: paper,
        "restore-cell": merge(night, pick(paper, new_cell)),
        "restore-pixel": merge(night, pick(paper, new_pix)),
        f"{net}-cut": pick(paper, cut),
        "cut+restore": merge(night, pick(paper, cut & new_cell)),
        "keep-only oracle": inp[keep_only_oracle(inp, gt, size, max_distance=2.0)],
        "count oracle": count_oracle(inp, gt, w, h, BIN_US),
    }
    firsts = [int(e["t"][0]) for e in (inp, gt) if e.size]
    start = min(firsts) // WIN_US * WIN_US
    end = max(int(e["t"][-1]) + 1 for e in (inp, gt) if e.size)
    if net == "none":
        variants = {k: variants[k] for k in ("raw", "keep-only oracle", "count oracle")}
    for name, ev in variants.items():
        s = evaluate_events(gt, ev, size, start_us=start, end_us=end)
        segs.setdefault(name, []).append(s)
    print(path.stem, flush=True)

table = {}
for name, summaries in segs.items():
    # each file weighs the same, as in edeflare.eval.evaluate
    table[name] = {
        m: float(np.nanmean([s.means[m] for s in summaries])) for m in summaries[0].means
    }
metrics = list(next(iter(table.values())))
print("| method | " + " | ".join(metrics) + " |")
for name, row in table.items():
    print(f"| {name} | " + " | ".join(f"{row[m]:.4f}" for m in metrics) + " |")
(outdir / f"hybrid_scores_{net}.json").write_text(json.dumps(table, indent=2))
