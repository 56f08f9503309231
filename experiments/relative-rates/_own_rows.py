"""A train-head run's own drawn test rows and each row's validation group (a part's name),
for own_groups.py and gap.py."""

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
