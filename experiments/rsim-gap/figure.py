"""python experiments/rsim-gap/figure.py SPLIT SEQ OUT.png T0_MS BEFORE_DIR: one 20 ms
window of a simulated sequence as the input, the default's output saved before
(``BEFORE_DIR/<seq>.night.npy``, from ``experiments/hybrid/outputs.py`` at the commit
before), the default now, and the ground truth; ON red, OFF blue on white
(edeflare.viz.event_frame)."""

import sys
from pathlib import Path

import numpy as np

from edeflare.deflare import deflare
from edeflare.events import slice_time
from edeflare.io import open_events
from edeflare.viz import event_frame, grid, save_image

split, seq, out = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
t0, before = int(float(sys.argv[4]) * 1000), Path(sys.argv[5])
src = open_events(split / f"{seq}.h5", group="input")
inp, size = src.read(), src.sensor_size
gt = open_events(split / f"{seq}.h5", group="gt").read()
streams = {
    "input": inp,
    "default before (no arms)": np.load(before / f"{seq}.night.npy"),
    "default now": deflare(inp, size, "model"),
    "ground truth": gt,
}
frames = [event_frame(slice_time(ev, t0, t0 + 20_000), size) for ev in streams.values()]
save_image(out, grid(frames, captions=list(streams), ncols=2))
print(f"wrote {out}")
