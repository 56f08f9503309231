"""python experiments/hybrid/thin.py SPLIT [WEIGHTS]: the mask model's keep
probabilities decoded two ways, on one windowing (the aligned 20 ms windows):

- ``threshold``: keep an event where p > 1/2 (what ``edeflare deflare`` does);
- ``thin``: in each cell (pixel, polarity, 2.5 ms bin) of n events, keep the
  round(sum of p) likeliest (the earliest among equals): p read as the share of the
  cell to keep, which is what the keep loss trains where a cell holds both flare and
  scene;
- ``thin-window``: the same with cells of (pixel, polarity, 20 ms window).
"""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.events import concat_events
from edeflare.io import open_events
from edeflare.models.infer import ModelDeflarer, resolve_weights

WIN_US, BIN_US = 20_000, 2_500


def thin(ev, p, w, h, bin_us=BIN_US):
    key = (((ev["t"].astype(np.int64) // bin_us) * h + ev["y"]) * w + ev["x"]) * 2 + ev["p"]
    order = np.lexsort((ev["t"], -p, key))  # in a cell, the likeliest first
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    gid = np.cumsum(first) - 1
    start = np.flatnonzero(first)
    rank = np.arange(ks.size) - start[gid]
    want = np.rint(np.bincount(gid, weights=p[order]))
    keep = np.zeros(ev.size, dtype=bool)
    keep[order] = rank < want[gid]
    return keep


def main() -> None:
    split = Path(sys.argv[1])
    weights = resolve_weights(sys.argv[2] if len(sys.argv) > 2 else "night")
    model = ModelDeflarer(weights, **dict(kv.split("=") for kv in sys.argv[3:]))

    rows: dict[str, list] = {}
    for path in sorted(split.glob("*.h5")):
        src = open_events(path, group="input")
        size = src.sensor_size
        gt = open_events(path, group="gt").read()
        wins = [(s, ev) for s, ev in src.windows(WIN_US) if ev.size]
        outs: dict[str, list] = {"threshold": [], "thin": [], "thin-window": []}
        for i in range(0, len(wins), 4):
            batch = wins[i : i + 4]
            for (_, ev), v in zip(batch, model.window_logits(batch, size), strict=True):
                p = 1.0 / (1.0 + np.exp(-(v + np.log(3.0))))
                outs["threshold"].append(ev[p > 0.5])
                outs["thin"].append(ev[thin(ev, p, *size)])
                outs["thin-window"].append(ev[thin(ev, p, *size, bin_us=WIN_US)])
        inp = src.read()
        start = min(int(inp["t"][0]), int(gt["t"][0])) // WIN_US * WIN_US
        end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
        for name, parts in outs.items():
            ev = concat_events(parts)
            rows.setdefault(name, []).append(
                evaluate_events(gt, ev, size, start_us=start, end_us=end)
            )
        print(path.stem, flush=True)
    metrics = list(rows["thin"][0].means)
    print("| decoding | " + " | ".join(metrics) + " |")
    for name, ss in rows.items():
        vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
        print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")


if __name__ == "__main__":
    main()
