"""Collect the study's training and validation windows from eflare-mix (one windowing).

python experiments/context-head/collect.py /work/data/mix /work/runs-tmp/ctx
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from common import night_deflarer, window_inputs

from edeflare.data.folders import dataset_folders
from edeflare.io.sequence import list_sequences, read_sequence
from edeflare.models.head_training import _component, _draw, keep_labels

PER_CLASS, VAL_PER_WINDOW = 2_000, 20_000


def collect(files, d, balanced, out: Path, seed=0, lights=False):
    if out.exists():
        print("have", out)
        return
    rng = np.random.default_rng(seed)
    ctxs, xs, ys, wins, cells, srcs, sizes = [], [], [], [], [], [], []
    t0 = time.time()
    for k, path in enumerate(files):
        inp, gt, size, start, end = read_sequence(path)
        labels = keep_labels(inp, gt, 1_000)
        light = _component(path, "light")
        if light is not None:
            labels |= keep_labels(inp, light, 1_000)
        streams = [(inp, labels, k)]
        scene = _component(path, "background")
        if scene is not None:
            streams.append((scene, np.ones(scene.size, bool), -1 - k))
        for events, truth, source in streams:
            t = events["t"]
            for s in range(int(start), int(end), d.window_us):
                lo, hi = np.searchsorted(t, [s, s + d.window_us])
                if hi <= lo:
                    continue
                ev, y = events[lo:hi], truth[lo:hi]
                c, f, cell = window_inputs(d, ev, s, size, lights)
                if balanced:
                    take = np.concatenate(
                        [_draw(rng, np.flatnonzero(y == v), PER_CLASS) for v in (0, 1)]
                    )
                else:
                    take = _draw(rng, np.arange(ev.size), VAL_PER_WINDOW)
                wins.append(np.full(take.size, len(ctxs), np.int32))
                ctxs.append(c.astype(np.float16))
                xs.append(f[take])
                ys.append(y[take])
                cells.append(cell[take].astype(np.int32))
                srcs.append(np.full(take.size, source, np.int32))
                sizes.append(size)
        print(
            f"{k + 1}/{len(files)} {path.parent.parent.name}/{path.name} "
            f"{len(ctxs)} windows {time.time() - t0:.0f}s",
            flush=True,
        )
    arrays = {f"ctx_{i:05d}": c for i, c in enumerate(ctxs)}
    arrays.update(
        x=np.concatenate(xs),
        y=np.concatenate(ys),
        win=np.concatenate(wins),
        cell=np.concatenate(cells),
        source=np.concatenate(srcs),
        sizes=np.array(sizes, np.int32),
        files=np.array([str(f) for f in files]),
    )
    tmp = out.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.rename(out)


def main():
    data, run = Path(sys.argv[1]), Path(sys.argv[2])
    run.mkdir(parents=True, exist_ok=True)
    d = night_deflarer()
    folders = dataset_folders(data)
    for split, balanced in (("test", False), ("train", True)):
        files = [f for fo in folders if (fo / split).is_dir() for f in list_sequences(fo / split)]
        collect(files, d, balanced, run / f"{split}.npz", lights="--lights" in sys.argv)


if __name__ == "__main__":
    main()
