"""python experiments/halo-prior/picture.py OUT.png: the default with and without the halo
prior on the two annotated real recordings (three windows each: 10 ms of the Gen3
rotating light, cropped to where it moves, 20 ms of the DAVIS346 lamps), with what the
prior removes on its own and the prior's pixels (grey) with the window's lights (black)
in the last column. ON red, OFF blue."""

import sys
from pathlib import Path

import numpy as np

from edeflare.deflare import deflare
from edeflare.io import read_events
from edeflare.models.ghosts import light_cells
from edeflare.models.halos import halo_pixels
from edeflare.viz import event_frame, grid, save_image

REAL = Path("../shared/data/real")
RECORDINGS = (  # name, window, windows shown, crop (x0, x1, y0, y1)
    ("prophesee_gen3_rotating_light.raw", 10_000, (1, 2, 4), (150, 490, 40, 360)),
    ("davis346_flicker_lamps.aedat4", 20_000, (1, 2, 3), (0, 346, 0, 260)),
)


def prior_frame(ev, size, window_us):
    width, height = size
    img = np.full((height, width, 3), 255, np.uint8)
    img[halo_pixels(ev, size, window_us)] = 200
    cells = light_cells(ev, size, window_us)
    img[np.repeat(np.repeat(cells, 8, 0), 8, 1)[:height, :width]] = 0
    return img


if __name__ == "__main__":
    out = Path(sys.argv[1])
    labels = ["input", "default, no prior", "default, halo shift 1", "removed by the prior",
              "prior (grey), lights (black)"]  # fmt: skip
    cells, rows = [], []
    for name, window, picks, (x0, x1, y0, y1) in RECORDINGS:
        ev, size = read_events(REAL / name)
        plain = deflare(ev, size, "model", halo_shift=0.0)
        halo = deflare(ev, size, "model", halo_shift=1.0)
        lost = plain[~np.isin(plain, halo)]
        t0 = int(ev["t"][0]) // window * window  # the model's aligned windows
        for k in picks:
            a, b = t0 + k * window, t0 + (k + 1) * window
            cut = [e[(e["t"] >= a) & (e["t"] < b)] for e in (ev, plain, halo, lost)]
            imgs = [event_frame(c, size) for c in cut] + [prior_frame(cut[0], size, window)]
            cells += [i[y0:y1, x0:x1] for i in imgs]
            rows.append(f"{name.split('_')[0]} {(a - t0) // 1000}-{(b - t0) // 1000} ms")
    save_image(out, grid(cells, labels=labels, row_labels=rows, ncols=len(labels)))
    print("wrote", out)
