"""python experiments/ghosts/prior_check.py FOLDER: would a ghost prior tell ghosts from the scene?

Per 20 ms window of each ``FOLDER/test`` sequence (``eflare-night-sparse``): the cells
(8x8 px) with more than 300 events are the lights; the prior marks the cells whose
reflection through the image centre at a factor k (``c + (q - c) / k``, k in ``K``, the
recipe's ghost factors) is a light, widened by 2 cells, minus the lights themselves.
Printed: of the ghost events to drop, the other events to drop and the events to keep,
how many there are and the share inside the prior. No learning: a parameter-free
input a network could be given.
"""

import json
import sys

import h5py
import numpy as np
from scipy import ndimage

from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track

K = [-0.5, -1, -1.5, -2, -2.5, -3, -3.5, -4, -4.5, -5, 0.4, 0.6]
S = 8
tot = {"ghost": [0, 0], "keep": [0, 0], "other": [0, 0]}
for seq in list_sequences(sys.argv[1] + "/test"):
    inp, size = read_dsec(seq, "input")
    gt, _ = read_dsec(seq, "gt")
    light, _ = read_dsec(seq, "light")
    with h5py.File(seq) as f:
        ghosts = [GhostSpec(**g) for g in json.loads(f.attrs["script"])["ghosts"]]
    W, H = size
    h, w = -(-H // S), -(-W // S)
    keep = np.isin(event_keys(inp, size), event_keys(gt, size))
    ghost = in_ghosts(inp, source_track(light), ghosts, size)
    for t0 in range(0, 100000, 20000):
        sel = (inp["t"] >= t0) & (inp["t"] < t0 + 20000)
        ev = inp[sel]
        cnt = np.zeros((h, w))
        np.add.at(cnt, (ev["y"] // S, ev["x"] // S), 1)
        bright = cnt > 300
        yy, xx = np.mgrid[0:h, 0:w]
        cy, cx = (H - 1) / 2 / S, (W - 1) / 2 / S
        prior = np.zeros((h, w), bool)
        for k in K:
            sy = np.round(cy + (yy + 0.5 - cy) / k).astype(int)
            sx = np.round(cx + (xx + 0.5 - cx) / k).astype(int)
            ok = (sy >= 0) & (sy < h) & (sx >= 0) & (sx < w)
            prior[ok] |= bright[sy[ok], sx[ok]]
        prior = ndimage.binary_dilation(prior, iterations=2) & ~ndimage.binary_dilation(
            bright, iterations=1
        )
        inprior = prior[ev["y"] // S, ev["x"] // S]
        for name, m in (
            ("ghost", ~keep[sel] & ghost[sel]),
            ("keep", keep[sel]),
            ("other", ~keep[sel] & ~ghost[sel]),
        ):
            tot[name][0] += m.sum()
            tot[name][1] += (m & inprior).sum()
print({k: (v[0], round(v[1] / max(v[0], 1), 3)) for k, v in tot.items()})
