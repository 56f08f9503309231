"""Where the night recording's flare differs from the simulated steady lamps' flare, as a
run's head reads them: each feature's median (and the head's keep logit's; the share of ON
events) over the night recording's annotated flare (halo and ghost), light and scene events
(one windowing), and over the run's own drawn test rows of a part in windows where no light
is found, flare and the rest. Measures only; nothing here is chosen.

Run: python experiments/relative-rates/gap.py RUN OUT.json FAERY_DATA PART DATA_FOLDER...
(RUN: a train-head run folder; PART: e.g. steady-640; DATA_FOLDER: RUN's data, in its order)
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _own_rows import own_test_rows, write_medians  # noqa: E402
from night_recording import HERE as BENCH  # noqa: E402
from night_recording import faery_file  # noqa: E402

from edeflare.io import read_events  # noqa: E402
from edeflare.lights import load_lights  # noqa: E402
from edeflare.models.event_head import head_logits  # noqa: E402
from edeflare.models.head_training import context_columns  # noqa: E402
from edeflare.models.head_tuning import recording_inputs, region_labels  # noqa: E402
from edeflare.models.infer import ModelDeflarer  # noqa: E402

run, dst, faery, part = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]), sys.argv[4]
d = ModelDeflarer(run / "model.safetensors", runtime="torch", batch_windows=8)
head = d.model.head
names = [
    *head.feature_names,
    *(f"context_{i}" for i in range(head.columns - len(head.feature_names))),
]
params = d.head_params


def medians(columns: np.ndarray) -> dict[str, float]:
    row = {n: float(np.median(columns[:, i])) for i, n in enumerate(names)}
    row["keep_logit"] = float(np.median(head_logits(params, columns)))
    row["on_share"] = float(np.mean(columns[:, names.index("polarity")]))  # a mean
    row["events"] = int(columns.shape[0])
    return {k: round(v, 3) for k, v in row.items()}


out: dict[str, dict[str, float]] = {}
recording = read_events(faery_file(faery / "evt3.raw"))  # only it, as fit.py reads it
events, size = recording.events, recording.sensor_size
lights = load_lights(BENCH / "night_recording_lights.json", size)
columns = recording_inputs(d, events, size, [0])[0]
code = region_labels(events, size, lights)
for label, c in (("flare", 2), ("light", 1), ("scene", 3)):
    if (code == c).any():  # the scene: only where the annotation scores it
        out[f"night recording: {label}"] = medians(columns[code == c])
data, groups = own_test_rows(run, sys.argv[5:])
rows = context_columns(head, data)
free = data["x"][:, head.feature_names.index("light_free")] > 0.5
y = data["y"].astype(bool)
for label, m in ((f"{part}, no light found: flare", ~y), (f"{part}, no light found: rest", y)):
    out[label] = medians(rows[(groups == part) & free & m])
write_medians(dst, out, "feature")
