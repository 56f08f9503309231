"""python experiments/ghosts/davis_prior_picture.py OUT.png: the DAVIS346 lamps, first two 100 ms,
what the default keeps (grey), what --ghost-shift 2 drops of it besides (red), and the
prior of the first 20 ms of each (green lines: cells)."""
import sys
import numpy as np
from PIL import Image
from edeflare.deflare import create_method
from edeflare.io import read_events
from edeflare.models.ghosts import ghost_cells
rec = read_events("../shared/data/real/davis346_flicker_lamps.aedat4")
ev, size = rec.events, rec.sensor_size
a = create_method("model")(ev, size, rng=0)
b = create_method("model", ghost_shift=2.0)(ev, size, rng=0)
lost = a[~np.isin(a, b)]
W, H = size
t0 = int(ev["t"][0])
imgs = []
for k in range(3):
    s = t0 + k * 100000
    sel = lambda e: e[(e["t"] >= s) & (e["t"] < s + 100000)]
    img = np.full((H, W, 3), 255, np.uint8)
    e = sel(a); img[e["y"], e["x"]] = (150, 150, 150)
    e = sel(lost); img[e["y"], e["x"]] = (220, 0, 0)
    c = ghost_cells(ev[(ev["t"] >= s) & (ev["t"] < s + 20000)], size, 20000)
    cy, cx = np.nonzero(c)
    for y, x in zip(cy, cx):
        img[y*8:y*8+8:7, x*8:x*8+8] = (0, 160, 0)
    imgs.append(img)
    print(k, len(sel(a)), len(sel(lost)))
Image.fromarray(np.concatenate(imgs, 1)).resize((3 * W * 2, H * 2), Image.NEAREST).save(sys.argv[1])
print(len(ev), len(a), len(b))
