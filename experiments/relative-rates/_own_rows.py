"""A train-head run's own drawn test rows and each row's validation group (a part's name),
for own_groups.py and gap.py; and the medians table that gap.py and gap_hot.py write."""

import json
from pathlib import Path

import numpy as np

from edeflare.data.folders import dataset_folders
from edeflare.io.sequence import list_sequences
from edeflare.models.head_training import _group


def own_test_rows(run: Path, data: list[str]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """RUN's cached test rows and their groups; ``data``: RUN's data folders, in its order
    (a mix stands for its parts in its manifest's order, as train-head reads them)."""
    (cache,) = run.glob("features-test-*.npz")
    with np.load(cache) as z:
        rows = {k: z[k] for k in z.files}
    folders = [f for arg in data for f in dataset_folders(arg)]
    files = [str(s) for d in folders if (d / "test").is_dir() for s in list_sequences(d / "test")]
    return rows, np.array([_group(files, int(s)) for s in rows["source"]])


def write_medians(dst: Path, out: dict[str, dict[str, float]], header: str) -> None:
    """``out`` (a column of medians per group) as JSON to ``dst``, and printed as a
    markdown table with one row per median (first column titled ``header``)."""
    dst.write_text(json.dumps(out, indent=1) + "\n")
    print(f"| {header} | " + " | ".join(out) + " |")
    print("|---|" + "---:|" * len(out))
    for k in next(iter(out.values())):
        print(f"| {k} | " + " | ".join(str(v[k]) for v in out.values()) + " |")
