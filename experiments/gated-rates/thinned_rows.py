"""What thinning put in the training rows: flare where the light test finds no light.

Reads runs' cached training rows (``features-train-*.npz`` as ``train-head`` writes
them; the columns named by the run's ``head.json`` beside them) and reports, for the flare
rows (label 0), how many lie in windows without a found light (``light_free`` on), and of
those the median support (``free_support``, or ``support`` where the run reads it in every
window: the same value there) and the shares with the light-free rules' evidence on
(``crowded``, ``field``). The night recording's flare, for comparison (study light-test):
all of it without a found light, support 1.47, crowded 54 %, field 69 %.

Run: python experiments/gated-rates/thinned_rows.py OUT.json LABEL=ROWS.npz ...
(results/thinned_rows.json: LW's rows, not thinned, and LFT's)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def columns(rows_path: Path) -> tuple[int, ...]:
    """The columns of ``light_free``, ``crowded``, ``field`` and the support in the rows."""
    names = json.loads((rows_path.parent / "head.json").read_text())["config"]["features"]
    support = "free_support" if "free_support" in names else "support"
    return tuple(names.index(n) for n in ("light_free", "crowded", "field", support))


def main() -> None:
    out = {}
    for arg in sys.argv[2:]:
        label, path = arg.split("=", 1)
        light_free, crowded_at, field, support = columns(Path(path))
        rows = np.load(path, allow_pickle=False)
        x, y = rows["x"], rows["y"]
        flare = y == 0
        free = flare & (x[:, light_free] > 0.5)
        crowded = x[:, crowded_at] > 0.5
        sparse = x[:, support] < 2
        out[label] = {
            "rows": int(x.shape[0]),
            "flare rows": int(flare.sum()),
            "flare rows without a found light": int(free.sum()),
            "share of flare": round(float(free.sum() / flare.sum()), 4),
            "their support (median)": round(float(np.median(x[free, support])), 2),
            "crowded on": round(float(crowded[free].mean()), 4),
            "field on": round(float((x[free, field] > 0.5).mean()), 4),
            "crowded & sparse (support < 2)": int((free & crowded & sparse).sum()),
        }
        print(label, out[label], flush=True)
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
