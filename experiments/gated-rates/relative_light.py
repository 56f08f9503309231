"""Could a light test read rates relative to the window? Per 20 ms window of each real
recording: the window's mean rate m (events per pixel and ms), its busiest 8x8 cell's
rate over m, and whether today's (absolute) light test finds a light. It measures only.

Run: python experiments/gated-rates/relative_light.py OUT.json FAERY_DATA
"""

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "experiments" / "real-labels"))
from fit import real_recordings  # noqa: E402

from edeflare.lights.cells import _cell_event_counts, window_lights  # noqa: E402

W, CELL = 20_000, 8
out = {}
for name, ev, size, _ in real_recordings(Path(sys.argv[2])):
    width, height = size
    t = ev["t"].astype(np.int64)
    starts = np.arange(t[0] // W * W, t[-1] + 1, W)
    bounds = np.searchsorted(t, np.r_[starts, starts[-1] + W])
    rows = []
    for k in range(starts.size):
        e = ev[bounds[k] : bounds[k + 1]]
        if e.size < 100:
            continue
        m = e.size / (width * height) / (W / 1000)
        h, w = -(-height // CELL), -(-width // CELL)
        cells = _cell_event_counts(e["x"], e["y"], CELL, h, w) / CELL**2 / (W / 1000)
        top = float(cells.max())
        rows.append((m, top / m, top, bool(window_lights(e, size, W).any())))
    a = np.array(rows)
    out[name] = {
        "windows": len(rows),
        "mean_rate": float(np.median(a[:, 0])),
        "top_cell_over_mean_p5_p50_p95_max": np.percentile(a[:, 1], [5, 50, 95, 100])
        .round(1)
        .tolist(),
        "top_cell_rate_p5_p50_p95": np.percentile(a[:, 2], [5, 50, 95]).round(3).tolist(),
        "windows_with_a_light_found": float(a[:, 3].mean()),
    }
    print(name, out[name], flush=True)
json.dump(out, open(sys.argv[1], "w"), indent=1)
