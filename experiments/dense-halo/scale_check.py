"""python experiments/dense-halo/scale_check.py WEIGHTS FOLDER...: the de-flarer on eflare-night
test sequences simulated at other sensor sizes (issue 13, "every sensor size").

Each FOLDER holds ``test/*.h5`` of the eflare-night recipe (keep-only targets: ``gt`` is
the subset of ``input`` to keep). Per folder: the share of the events to drop that are
dropped, of the events to keep that are kept, and their harmonic mean (events pooled
over the sequences).
"""
import sys

import numpy as np

from edeflare.deflare import deflare
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences


def keys(ev):
    return (ev["t"].astype(np.int64) << 24) | (ev["x"].astype(np.int64) << 12) | (ev["y"].astype(np.int64) << 1) | ev["p"].astype(np.int64)


w = sys.argv[1]
for folder in sys.argv[2:]:
    drop_n = drop_removed = keep_n = keep_kept = 0
    for seq in list_sequences(folder + "/test"):
        inp, size = read_dsec(seq, "input")
        gt, _ = read_dsec(seq, "gt")
        out = deflare(inp, size, "model", weights=w)
        k_in, k_gt, k_out = keys(inp), keys(gt), keys(out)
        to_keep = np.isin(k_in, k_gt)
        kept = np.isin(k_in, k_out)
        drop_n += int((~to_keep).sum()); drop_removed += int((~to_keep & ~kept).sum())
        keep_n += int(to_keep.sum()); keep_kept += int((to_keep & kept).sum())
    r, k = drop_removed / max(drop_n, 1), keep_kept / max(keep_n, 1)
    print(f"{folder} {size[0]}x{size[1]}: to drop {drop_n}, dropped {r:.3f}; to keep {keep_n}, kept {k:.3f}; harmonic {2 * r * k / (r + k):.3f}", flush=True)
