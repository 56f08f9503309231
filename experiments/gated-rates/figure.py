"""figure.png: 20 ms windows of the DAVIS346 lamps, the Prophesee Gen3 light, the Gen4.1
daytime street (its whole 8.8 ms) and the night recording (faery's ``evt3.raw``, at 9 s):
the input, and what ``night``, ``learned`` and each other model keep of each recording
de-flared whole; the Gen3 light, the street and the night recording cropped, the DAVIS
lamps drawn at twice their size. ON red, OFF blue.

Run: python experiments/gated-rates/figure.py OUT.png FAERY_DATA LABEL=WEIGHTS ...
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from edeflare.io import read_events
from edeflare.methods import deflare
from edeflare.viz import event_frame, grid, save_image

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT.parent / "shared" / "data" / "real"
WINDOW_US = 20_000


def main() -> None:
    out, faery = Path(sys.argv[1]), Path(sys.argv[2])
    models = [("night", "night"), ("learned", "learned")]
    models += [tuple(a.split("=", 1)) for a in sys.argv[3:]]  # type: ignore[misc]
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from night_recording import faery_file

    recordings = [
        # label, file, window start (us after the first event), crop (rows, columns), zoom
        ("DAVIS lamps", REAL / "davis346_flicker_lamps.aedat4", 40_000, (slice(None),) * 2, 2),
        ("Gen3 light", REAL / "prophesee_gen3_rotating_light.raw", 20_000,
         (slice(40, 440), slice(120, 620)), 1),
        ("Gen4.1 street", REAL / "prophesee_gen41_street.raw", 0,
         (slice(150, 670), slice(590, 1280)), 1),
        ("night recording", faery_file(faery / "evt3.raw"), 9_000_000,
         (slice(100, 620), slice(250, 940)), 1),
    ]  # fmt: skip
    cells, rows = [], []
    for label, path, offset, crop, zoom in recordings:
        rec = read_events(path)
        ev, size = rec.events, rec.sensor_size
        a = int(ev["t"][0]) + offset
        outs = [ev] + [deflare(ev, size, "model", weights=w) for _, w in models]
        for e in outs:
            frame = event_frame(e[(e["t"] >= a) & (e["t"] < a + WINDOW_US)], size)[crop]
            cells.append(np.repeat(np.repeat(frame, zoom, axis=0), zoom, axis=1))
        rows.append(label)
    labels = ["input", *(m for m, _ in models)]
    save_image(out, grid(cells, labels=labels, row_labels=rows, ncols=len(labels)))
    print("wrote", out)


if __name__ == "__main__":
    main()
