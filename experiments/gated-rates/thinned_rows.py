"""What thinning put in the training rows: flare where the light test finds no light.

Reads two runs' cached training rows (``features-train-*.npz`` as ``train-head`` writes
them, both with LF's 27 features in LF's order) and reports, for the flare rows (label 0),
how many lie in windows without a found light (``light_free`` on), and of those the
median ``free_support`` and the shares with the light-free rules' evidence on
(``crowded``, ``field``). The night recording's flare, for comparison (study light-test):
all of it without a found light, support 1.47, crowded 54 %, field 69 %.

Run: python experiments/gated-rates/thinned_rows.py OUT.json LABEL=ROWS.npz ...
(results/thinned_rows.json: LW's rows, not thinned, and LFT's)
"""

from __future__ import annotations

import json
import sys

import numpy as np

LIGHT_FREE, CROWDED, FIELD, FREE_SUPPORT = 2, 8, 9, 20  # columns of LF's feature order


def main() -> None:
    out = {}
    for arg in sys.argv[2:]:
        label, path = arg.split("=", 1)
        rows = np.load(path, allow_pickle=False)
        x, y = rows["x"], rows["y"]
        flare = y == 0
        free = flare & (x[:, LIGHT_FREE] > 0.5)
        crowded = x[:, CROWDED] > 0.5
        sparse = x[:, FREE_SUPPORT] < 2
        out[label] = {
            "rows": int(x.shape[0]),
            "flare rows": int(flare.sum()),
            "flare rows without a found light": int(free.sum()),
            "share of flare": round(float(free.sum() / flare.sum()), 4),
            "their support (median)": round(float(np.median(x[free, FREE_SUPPORT])), 2),
            "crowded on": round(float(crowded[free].mean()), 4),
            "field on": round(float((x[free, FIELD] > 0.5).mean()), 4),
            "crowded & sparse (support < 2)": int((free & crowded & sparse).sum()),
        }
        print(label, out[label], flush=True)
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
