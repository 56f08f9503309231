"""Sparse flare sensing: drop each flare-origin input event with prob 1-q (q per sequence).

python thin.py IN OUT [NEAR_PX] [KEEP_NEAR] [QLO] [QHI]: flare events within NEAR_PX (default 1) of
a light event of the same 10 ms are never thinned; with KEEP_NEAR=1 they are also labelled "keep"
(the dense glow around a source is what a real sensor records as the source). The survival q is
log-uniform in [QLO, QHI] (default 0.02, 0.6). With ALPHA > 0 (7th argument) it also falls with
the distance d from the source beyond 2 radii: q * (2 r / d) ** ALPHA (real scattered light falls
off faster than the simulator's glare: benchmarks/flare_stats.py).
"""
import sys, json
from pathlib import Path
import numpy as np, h5py
from edeflare.io.dsec import read_dsec
from edeflare.io.dsec import write_dsec_groups

def key(ev):
    return (ev["t"].astype(np.int64) << 24) ^ (ev["x"].astype(np.int64) << 12) ^ (ev["y"].astype(np.int64) << 1) ^ ev["p"].astype(np.int64)

src, dst = Path(sys.argv[1]), Path(sys.argv[2])
near_px = int(sys.argv[3]) if len(sys.argv) > 3 else 1
keep_near = len(sys.argv) > 4 and sys.argv[4] == "1"
qlo = float(sys.argv[5]) if len(sys.argv) > 5 else 0.02
qhi = float(sys.argv[6]) if len(sys.argv) > 6 else 0.6
alpha = float(sys.argv[7]) if len(sys.argv) > 7 else 0.0
for split in ("train", "test"):
    (dst / split).mkdir(parents=True, exist_ok=True)
    for f in sorted((src / split).glob("*.h5")):
        out = dst / split / f.name
        if out.exists():
            continue
        with h5py.File(f, "r") as h:
            attrs = dict(h.attrs)
            size = tuple(int(v) for v in h.attrs["sensor_size"]) if "sensor_size" in h.attrs else None
        streams = {g: read_dsec(f, g)[0] for g in ("input", "gt", "flare", "light")}
        light = streams.pop("light")
        idx = int(attrs["index"])
        rng = np.random.default_rng([4242, idx])
        q = float(np.exp(rng.uniform(np.log(qlo), np.log(qhi))))
        inp = streams["input"]
        isflare = np.isin(key(inp), key(streams["flare"]))
        # the source itself stays dense: flare events within 3 px of a light event of the
        # same 10 ms window are the source seen through the lens, not scattered light
        win = (inp["t"] - int(attrs["t_start_us"])) // 10_000
        lw = (light["t"] - int(attrs["t_start_us"])) // 10_000
        W, H = size
        near = np.zeros(inp.size, bool)
        from scipy import ndimage
        for k in np.unique(win):
            m = np.zeros((H, W), bool)
            sel = lw == k
            m[light["y"][sel], light["x"][sel]] = True
            m = ndimage.binary_dilation(m, iterations=near_px)
            ii = np.nonzero(win == k)[0]
            near[ii] = m[inp["y"][ii], inp["x"][ii]]
        survival = np.full(inp.size, q)
        if alpha > 0 and light.size:
            # the source per 10 ms window: centroid and the radius of a disc of its pixels
            cx = np.full(int(win.max()) + 1, np.nan)
            cy, rr = cx.copy(), cx.copy()
            for k in np.unique(lw):
                sel = light[lw == k]
                if k < 0 or k >= cx.size or sel.size < 20:
                    continue
                cx[k], cy[k] = sel["x"].mean(), sel["y"].mean()
                rr[k] = max(np.sqrt(np.unique(sel["y"].astype(np.int64) * W + sel["x"]).size / np.pi), 2.0)
            idx = np.arange(cx.size)
            ok = np.isfinite(cx)
            if ok.any():  # windows without the source take the nearest window's
                nearest = idx[ok][np.clip(np.searchsorted(idx[ok], idx), 0, ok.sum() - 1)]
                cx, cy, rr = cx[nearest], cy[nearest], rr[nearest]
                d = np.hypot(inp["x"] - cx[win], inp["y"] - cy[win])
                survival *= np.minimum(1.0, (2 * rr[win] / np.maximum(d, 1e-6)) ** alpha)
        drop = isflare & ~near & (rng.random(inp.size) >= survival)
        kept = inp[~drop]
        # a log photoreceptor does not clip: the source's own events are recorded even where
        # the 8-bit flare rendering saturates, so light events missing from the input return
        missing = light[~np.isin(key(light), key(kept))]
        merged = np.concatenate([kept, missing])
        merged = merged[np.argsort(merged["t"], kind="stable")]
        streams["input"] = merged
        # the target of a keep-only de-flarer: the input's true events (scene and source)
        streams["gt_full"] = streams["gt"]
        keep = np.concatenate([streams["gt"], light] + ([inp[isflare & near]] if keep_near else []))
        streams["gt"] = merged[np.isin(key(merged), key(keep))]
        attrs["flare_detection_q"] = q
        attrs.pop("sensor_size", None)
        streams["light"] = light  # the source alone, for statistics (benchmarks/flare_stats.py)
        write_dsec_groups(out, streams, size, attrs)
        print(f.name, f"q={q:.3f}", int(isflare.sum()), int(drop.sum()), missing.size, flush=True)
