"""python experiments/ghosts/figure.py FOLDER OUT.png WEIGHTS [SEQ...] [name=value...]: 20 ms
windows of eflare-night-sparse test sequences, input beside a model's output
(``name=value``: a parameter of the model method, e.g. ``ghost_shift=2``).

Grey: events to keep; red / blue: ON / OFF events to drop (scattered light, hot pixels);
green: events to drop inside a ghost's disc. Each row a sequence (40-60 ms).
"""

import json
import sys

import h5py
import numpy as np
from PIL import Image, ImageDraw

from edeflare.deflare import deflare
from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track


def panel(ev, drop, ghost, size):
    img = np.full((size[1], size[0], 3), 255, np.uint8)
    col = np.where(ev["p"][:, None] == 1, [220, 40, 40], [40, 60, 220]).astype(np.uint8)
    col[~drop] = [175, 175, 175]
    col[drop & ghost] = [0, 160, 0]
    order = np.argsort(drop, kind="stable")  # flare drawn last, on top
    img[ev["y"][order], ev["x"][order]] = col[order]
    return img


def main(folder, out, weights, names, params=None):
    params = params or {}
    rows = []
    for name in names:
        seq = f"{folder}/test/{name}.h5"
        inp, size = read_dsec(seq, "input")
        gt, _ = read_dsec(seq, "gt")
        light, _ = read_dsec(seq, "light")
        with h5py.File(seq) as f:
            ghosts = [GhostSpec(**g) for g in json.loads(f.attrs["script"])["ghosts"]]
        result = deflare(inp, size, "model", weights=weights, **params)
        kept = np.isin(event_keys(inp, size), event_keys(result, size))
        drop = ~np.isin(event_keys(inp, size), event_keys(gt, size))
        ghost = in_ghosts(inp, source_track(light), ghosts, size)
        w = (inp["t"] >= 40_000) & (inp["t"] < 60_000)
        left = panel(inp[w], drop[w], ghost[w], size)
        right = panel(inp[w & kept], drop[w & kept], ghost[w & kept], size)
        gap = np.full((size[1], 8, 3), 0, np.uint8)
        rows.append(np.concatenate([left, gap, right], 1))
    img = Image.fromarray(np.concatenate([np.vstack([r, np.zeros((8, r.shape[1], 3), np.uint8)])
                                          for r in rows]))  # fmt: skip
    d = ImageDraw.Draw(img)
    d.text((4, 2), "input (green: ghost events to drop)", fill=(0, 0, 0))
    label = " ".join([weights.rsplit("/", 1)[-1], *(f"{k}={v}" for k, v in params.items())])
    d.text((size[0] + 12, 2), f"after {label}", fill=(0, 0, 0))
    img.save(out)


if __name__ == "__main__":
    rest = sys.argv[4:]
    params = {k: float(v) for k, v in (a.split("=", 1) for a in rest if "=" in a)}
    main(sys.argv[1], sys.argv[2], sys.argv[3], [a for a in rest if "=" not in a], params)
