"""python experiments/ghosts/prior_shift.py FOLDER: the default's keep logits lowered by B
inside the ghost prior of ``prior_check.py``: what it drops of ghosts, other flare, scene.

Aligned 20 ms windows only (one windowing), each B on the same logits.
"""

import json
import sys

import h5py
import numpy as np
from scipy import ndimage

from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.models.flaremask import keep_logit_threshold
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track

K = [-0.5, -1, -1.5, -2, -2.5, -3, -3.5, -4, -4.5, -5, 0.4, 0.6]
S = 8
B = [0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 10.0]


def prior_cells(ev, size, dense=300):
    W, H = size
    h, w = -(-H // S), -(-W // S)
    cnt = np.zeros((h, w))
    np.add.at(cnt, (ev["y"] // S, ev["x"] // S), 1)
    bright = cnt > dense
    yy, xx = np.mgrid[0:h, 0:w]
    cy, cx = (H - 1) / 2 / S, (W - 1) / 2 / S
    prior = np.zeros((h, w), bool)
    for k in K:
        sy = np.round(cy + (yy + 0.5 - cy) / k).astype(int)
        sx = np.round(cx + (xx + 0.5 - cx) / k).astype(int)
        ok = (sy >= 0) & (sy < h) & (sx >= 0) & (sx < w)
        prior[ok] |= bright[sy[ok], sx[ok]]
    return ndimage.binary_dilation(prior, iterations=2) & ~ndimage.binary_dilation(
        bright, iterations=1
    )


if __name__ == "__main__":
    d = ModelDeflarer(bundled_weights())
    cut = keep_logit_threshold(d.keep_threshold)
    per = {b: {"ghost": [], "other": [], "keep": []} for b in B}
    for seq in list_sequences(sys.argv[1] + "/test"):
        inp, size = read_dsec(seq, "input")
        gt, _ = read_dsec(seq, "gt")
        light, _ = read_dsec(seq, "light")
        with h5py.File(seq) as f:
            ghosts = [GhostSpec(**g) for g in json.loads(f.attrs["script"])["ghosts"]]
        keep = np.isin(event_keys(inp, size), event_keys(gt, size))
        ghost = in_ghosts(inp, source_track(light), ghosts, size)
        logit = np.empty(len(inp))
        inprior = np.zeros(len(inp), bool)
        t0 = int(inp["t"][0])
        for s in range(t0, int(inp["t"][-1]) + 1, 20000):
            sel = (inp["t"] >= s) & (inp["t"] < s + 20000)
            ev = inp[sel]
            logit[sel] = d.window_logits([(s, ev)], size)[0]
            inprior[sel] = prior_cells(ev, size)[ev["y"] // S, ev["x"] // S]
        for b in B:
            kept = logit - b * inprior > cut
            for name, m, hit in (("ghost", ~keep & ghost, ~kept), ("other", ~keep & ~ghost, ~kept),
                                 ("keep", keep, kept)):
                if m.sum() >= 100:
                    per[b][name].append((m & hit).sum() / m.sum())
    for b in B:
        v = {k: round(float(np.mean(x)), 3) for k, x in per[b].items()}
        hm = 3 / sum(1 / x for x in v.values())
        print(f"B={b}: ghost dropped {v['ghost']} other dropped {v['other']} kept {v['keep']} hm {hm:.3f}", flush=True)
