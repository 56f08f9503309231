"""Background activity that a de-flarer must keep: python noise.py IN OUT LO HI.

Adds to each sequence's input (and to its keep-only gt) uniform random events at a rate
log-uniform in [LO, HI] events per pixel per second (seeded by the sequence index). Real
scenes hold scattered events far from any light (sensor noise, flicker on texture): without
them in training, a mask learns "scattered dot = flare" and deletes such scenes whole.
"""
import sys
from pathlib import Path

import h5py
import numpy as np

from edeflare.events import EVENT_DTYPE
from edeflare.io.dsec import read_dsec, write_dsec_groups

if __name__ == "__main__":
    src, dst = Path(sys.argv[1]), Path(sys.argv[2])
    lo, hi = float(sys.argv[3]), float(sys.argv[4])
    for split in ("train", "test"):
        (dst / split).mkdir(parents=True, exist_ok=True)
        for f in sorted((src / split).glob("*.h5")):
            out = dst / split / f.name
            if out.exists():
                continue
            with h5py.File(f, "r") as h:
                attrs = dict(h.attrs)
                groups = [g for g in ("input", "gt", "gt_full", "flare", "light") if g in h]
            streams = {}
            for g in groups:
                streams[g], size = read_dsec(f, g)
            rng = np.random.default_rng([777, int(attrs["index"])])
            rate = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
            t0, t1 = int(attrs["t_start_us"]), int(attrs["t_end_us"])
            n = rng.poisson(rate * size[0] * size[1] * (t1 - t0) / 1e6)
            noise = np.empty(n, EVENT_DTYPE)
            noise["t"] = np.sort(rng.integers(t0, t1, n))
            noise["x"] = rng.integers(0, size[0], n)
            noise["y"] = rng.integers(0, size[1], n)
            noise["p"] = rng.integers(0, 2, n)
            for g in ("input", "gt"):
                both = np.concatenate([streams[g], noise])
                streams[g] = both[np.argsort(both["t"], kind="stable")]
            attrs["noise_rate"] = rate
            attrs.pop("sensor_size", None)
            write_dsec_groups(out, streams, size, attrs)
            print(f.name, f"rate={rate:.2f}", n, flush=True)
