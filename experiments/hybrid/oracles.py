"""python experiments/hybrid/oracles.py SPLIT: count oracles on a simulated split.

A count oracle deletes only: in each cell (pixel, polarity, a time bin of BIN us) it
keeps the input's first min(n_input, n_gt) events. It is what a deleting method could
reach if it knew how many of a cell's events are scene. Prints the eight metrics per
bin length, with the raw input's row.
"""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.io import open_events

BINS_US = (2_500, 5_000, 10_000, 20_000)


def cell_keys(ev: np.ndarray, w: int, h: int, bin_us: int) -> np.ndarray:
    return (((ev["t"].astype(np.int64) // bin_us) * h + ev["y"]) * w + ev["x"]) * 2 + ev["p"]


def count_oracle(inp: np.ndarray, gt: np.ndarray, w: int, h: int, bin_us: int) -> np.ndarray:
    k_in, k_gt = cell_keys(inp, w, h, bin_us), cell_keys(gt, w, h, bin_us)
    order = np.argsort(k_in, kind="stable")
    ks = k_in[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    gid = np.cumsum(first) - 1
    rank = np.arange(ks.size) - np.flatnonzero(first)[gid]
    uniq, n_gt = np.unique(k_gt, return_counts=True)
    i = np.minimum(np.searchsorted(uniq, ks), uniq.size - 1)
    allowed = np.where(uniq[i] == ks, n_gt[i], 0)
    keep = np.zeros(inp.size, dtype=bool)
    keep[order] = rank < allowed
    return inp[keep]


if __name__ == "__main__":
    rows: dict[str, list] = {}
    for path in sorted(Path(sys.argv[1]).glob("*.h5")):
        src = open_events(path, group="input")
        inp, size = src.read(), src.sensor_size
        gt = open_events(path, group="gt").read()
        start = min(int(inp["t"][0]), int(gt["t"][0])) // 20_000 * 20_000
        end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
        outs = {"raw": inp} | {
            f"count oracle, {b / 1000:g} ms": count_oracle(inp, gt, *size, b) for b in BINS_US
        }
        for name, ev in outs.items():
            s = evaluate_events(gt, ev, size, start_us=start, end_us=end)
            rows.setdefault(name, []).append(s)
    metrics = list(rows["raw"][0].means)
    print("| method | " + " | ".join(metrics) + " |")
    for name, ss in rows.items():  # each file weighs the same
        vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
        print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
