"""python experiments/hybrid/cap.py SPLIT OUTDIR CAP...: the default's saved output
(``outputs.py``) with each pixel's events per polarity and 20 ms window capped at CAP,
everywhere or only inside the halo prior (``edeflare.models.halos``). A crude thinning:
dense flare fires many events in a pixel, a scene edge a few."""

import sys
from pathlib import Path

import numpy as np

from edeflare.eval.evaluate import evaluate_events
from edeflare.io import open_events

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "halo-prior"))
from sim_check import halo_prior as in_band

WIN_US = 20_000


def rank_in_pixel(ev: np.ndarray, w: int, h: int) -> np.ndarray:
    """Each event's rank (0 = first) among its pixel's events of its polarity and window."""
    key = (((ev["t"].astype(np.int64) // WIN_US) * h + ev["y"]) * w + ev["x"]) * 2 + ev["p"]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    gid = np.cumsum(first) - 1
    rank = np.empty(ev.size, dtype=np.int64)
    rank[order] = np.arange(ks.size) - np.flatnonzero(first)[gid]
    return rank


if __name__ == "__main__":
    split, outdir, caps = Path(sys.argv[1]), Path(sys.argv[2]), [int(c) for c in sys.argv[3:]]
    rows: dict[str, list] = {}
    for path in sorted(split.glob("*.h5")):
        src = open_events(path, group="input")
        inp, size = src.read(), src.sensor_size
        gt = open_events(path, group="gt").read()
        night = np.load(outdir / f"{path.stem}.night.npy")
        rank = rank_in_pixel(night, *size)
        band = in_band(night, size)
        outs = {"night": night}
        for c in caps:
            outs[f"cap {c}"] = night[rank < c]
            outs[f"cap {c} in band"] = night[(rank < c) | ~band]
        start = min(int(inp["t"][0]), int(gt["t"][0])) // WIN_US * WIN_US
        end = max(int(inp["t"][-1]), int(gt["t"][-1])) + 1
        for name, ev in outs.items():
            rows.setdefault(name, []).append(
                evaluate_events(gt, ev, size, start_us=start, end_us=end)
            )
    metrics = list(rows["night"][0].means)
    print("| method | " + " | ".join(metrics) + " |")
    for name, ss in rows.items():
        vals = [float(np.nanmean([s.means[m] for s in ss])) for m in metrics]
        print(f"| {name} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
