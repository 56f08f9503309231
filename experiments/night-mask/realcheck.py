"""Pictures + crude numbers: input, model(s), dv FastDecay on real recordings with lights."""
import sys, time
import numpy as np
import dv_processing as dv
from edeflare.io import read_events
from edeflare.deflare import deflare
from edeflare.viz import event_frame, grid, save_image

def fastdecay(ev, size):
    f = dv.noise.FastDecayNoiseFilter(size)
    s = dv.EventStore()
    for t, x, y, p in zip(ev["t"].tolist(), ev["x"].tolist(), ev["y"].tolist(), ev["p"].tolist()):
        s.push_back(t, x, y, bool(p))
    f.accept(s); out = f.generateEvents()
    keep = np.zeros(len(ev), bool)
    a = out.numpy()
    # match by (t, x, y)
    k_all = (ev["t"].astype(np.int64) << 22) + (ev["x"].astype(np.int64) << 11) + ev["y"]
    k_out = (a["timestamp"].astype(np.int64) << 22) + (a["x"].astype(np.int64) << 11) + a["y"]
    return ev[np.isin(k_all, k_out)]

models = sys.argv[2:]
out = sys.argv[1]
recs = [("../shared/data/real/prophesee_gen3_rotating_light.raw", 10_000, 4),
        ("../shared/data/real/davis346_flicker_lamps.aedat4", 20_000, 4)]
rows = []
labels = None
for path, win, n in recs:
    r = read_events(path)
    ev, size = r.events, r.sensor_size
    res = {"input": ev}
    t = time.time(); res["dv-fastdecay"] = fastdecay(ev, size); print(path, "fastdecay", round(time.time()-t, 2), len(res["dv-fastdecay"]) / len(ev))
    for m in models:
        t = time.time(); res[m] = deflare(ev, size, "model", weights=m); print(path, m, round(time.time()-t, 2), len(res[m]) / len(ev))
    t0 = int(ev["t"][0])
    for k in range(n):
        a, b = t0 + k * win, t0 + (k + 1) * win
        row = []
        for name, e in res.items():
            sel = e[(e["t"] >= a) & (e["t"] < b)]
            row.append(event_frame(sel, size))
        rows.append(row)
        labels = list(res)
# pad to same size per column
H = max(im.shape[0] for r in rows for im in r); W = max(im.shape[1] for r in rows for im in r)
def pad(im):
    o = np.full((H, W, 3), 255, np.uint8); o[: im.shape[0], : im.shape[1]] = im; return o
imgs = [pad(im) for r in rows for im in r]
save_image(out, grid(imgs, labels=[l.split("/")[-2] if "/" in l else l for l in labels], ncols=len(labels)))
