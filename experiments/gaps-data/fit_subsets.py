"""Fit keep heads on parts of a train-head run's cached training rows; score each on the
run's whole validation split, beside the bundled `general`.

    python experiments/gaps-data/fit_subsets.py RUN DATA [DATA ...]

RUN is `edeflare train-head DATA ... --out RUN`'s folder (its feature caches); DATA are
the same folders in the same order. The rows of the first folder's files come first in
the cache and are drawn before any other's, so "mix only" is exactly the rows a run on
`eflare-mix` alone draws (its fit reproduces `general`'s validation score).
"""

from __future__ import annotations

import glob
import sys
from pathlib import Path

import numpy as np

from edeflare.data.folders import dataset_folders
from edeflare.io.sequence import list_sequences
from edeflare.models.event_head import head_logits
from edeflare.models.head_training import HeadTrainingConfig, _group, choose_threshold, fit_head
from edeflare.models.infer import bundled_weights
from edeflare.models.weights import load_model


def _score(logits: np.ndarray, y: np.ndarray, groups: np.ndarray) -> str:
    thr, table = choose_threshold(logits, y, groups)
    kept = 1.0 / (1.0 + np.exp(-(logits + np.log(3.0)))) > thr
    parts = []
    for g in np.unique(groups):
        s = groups == g
        flare, scene = s & ~y, s & y
        removed = f"{1 - kept[flare].mean():.3f}" if flare.any() else "-"
        parts.append(f"{g}: {removed} / {kept[scene].mean():.3f}")
    best = max(r["score"] for r in table)
    return f"validation {best:.4f} at {thr}; flare removed / scene kept: " + ", ".join(parts)


def main() -> None:
    run, data = Path(sys.argv[1]), sys.argv[2:]
    folders = [p for d in data for p in dataset_folders(d)]
    train_files = [
        f for d in folders if (d / "train").is_dir() for f in list_sequences(d / "train")
    ]
    val_files = [
        str(f) for d in folders if (d / "test").is_dir() for f in list_sequences(d / "test")
    ]
    tr = dict(np.load(glob.glob(str(run / "features-train-*.npz"))[0]))
    va = dict(np.load(glob.glob(str(run / "features-test-*.npz"))[0]))
    groups = np.array([_group(val_files, int(i)) for i in va["source"]])
    src = tr["source"]
    file_of = np.where(src >= 0, src, -1 - src)  # the scene alone's rows: -1 - file
    names = [f"{f.parent.parent.parent.name}/{f.parent.parent.name}" for f in train_files]
    part = np.array(names)[file_of]
    first = Path(data[0]).name
    general, _ = load_model(bundled_weights("general"), "cpu")
    print(
        "general (bundled):",
        _score(head_logits(general.head.numpy_params(), va["x"]), va["y"], groups),
    )
    subsets = {f"{first} only": np.char.startswith(part, f"{first}/")}
    for p in sorted(set(names)):
        if not p.startswith(f"{first}/"):
            subsets[f"{first} + {p}"] = subsets[f"{first} only"] | (part == p)
    subsets["all"] = np.ones(part.size, bool)
    config = HeadTrainingConfig(hidden=(64, 32), epochs=16)
    for name, sel in subsets.items():
        head = fit_head(tr["x"][sel], tr["y"][sel], config, progress=False)
        logits = head_logits(head.numpy_params(), va["x"])
        print(f"{name} ({int(sel.sum()):,} rows):", _score(logits, va["y"], groups), flush=True)


if __name__ == "__main__":
    main()
