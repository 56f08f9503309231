"""python experiments/streaks/figure.py SPLIT SEQ OUT.png [T0_MS]: one 20 ms window of a
simulated sequence (default: 40 ms in) as the input, the default with its card before
(threshold 0.5, halo and ghost shifts 1, no spike prior), the default now, and the
ground truth; ON red, OFF blue on white (edeflare.viz.event_frame)."""

import sys
from pathlib import Path

from edeflare.deflare import deflare
from edeflare.events import slice_time
from edeflare.io import open_events
from edeflare.viz import event_frame, grid, save_image

BEFORE = {"keep_threshold": 0.5, "halo_shift": 1.0, "ghost_shift": 1.0, "streak_shift": 0.0}

split, seq, out = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
t0 = int(float(sys.argv[4]) * 1000) if len(sys.argv) > 4 else 40_000
src = open_events(split / f"{seq}.h5", group="input")
inp, size = src.read(), src.sensor_size
gt = open_events(split / f"{seq}.h5", group="gt").read()
streams = {
    "input": inp,
    "card before": deflare(inp, size, "model", **BEFORE),
    "default now": deflare(inp, size, "model"),
    "ground truth": gt,
}
frames = [event_frame(slice_time(ev, t0, t0 + 20_000), size) for ev in streams.values()]
save_image(out, grid(frames, captions=list(streams), ncols=2))
print(f"wrote {out}")
