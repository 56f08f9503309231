"""python experiments/dense-halo/chamfer_sources.py RSIM_TEST_FOLDER [N]: where the raw input's Chamfer mass on eflare-r-sim comes from."""
import sys
import numpy as np, h5py
from scipy.spatial import cKDTree
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.eval.metrics import nearest_distances
from edeflare.sim.optics_scene import OpticsScene
acc = np.zeros(4); n = 0; mass = np.zeros(4); tot = 0.0
for seq in list_sequences(sys.argv[1])[: int(sys.argv[2]) if len(sys.argv) > 2 else 10]:
    inp, size = read_dsec(seq, "input"); gt, _ = read_dsec(seq, "gt")
    scene = OpticsScene.from_json(h5py.File(seq)["/"].attrs["script"])
    for s in range(0, 100_000, 20_000):
        ev = inp[(inp["t"] >= s) & (inp["t"] < s + 20_000)]
        g = gt[(gt["t"] >= s) & (gt["t"] < s + 20_000)]
        d = nearest_distances(g, ev, size, s, 20_000)
        r = np.full(ev.size, np.inf)
        for src in scene.sources:
            x, y = src.position_px(ev["t"], scene.duration_us, size)
            r = np.minimum(r, np.hypot(ev["x"] - x, ev["y"] - y) / max(src.size_px, 1))
        far = (d > 2) & (r >= 10)
        # spatial distance (px) to the nearest same-polarity gt event in the window
        sp = np.full(ev.size, np.inf)
        for p in (0, 1):
            gp = g[g["p"] == p]
            m = far & (ev["p"] == p)
            if gp.size and m.any():
                sp[m] = cKDTree(np.c_[gp["x"], gp["y"]]).query(np.c_[ev["x"][m], ev["y"][m]])[0]
        b = np.digitize(sp[far], [0.5, 1.5, 5.0])
        acc += np.bincount(b, minlength=4); mass += np.bincount(b, weights=d[far], minlength=4)
        tot += d.sum()
print("far events at >=10 radii by spatial distance to a same-polarity gt event [0, <=1px, <=5px, >5px]:", acc.astype(int))
print("their share of the total chamfer mass:", np.round(mass / tot, 3))
