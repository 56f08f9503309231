"""Heads of two `train-head --members` ensembles over one network, recombined.

- ``union A B RUN OUT``: one ensemble of every member of A and B (their mean logit), the
  keep threshold chosen as `train-head` chooses it, on RUN's cached test-split rows;
- ``member W I RUN OUT``: member I of W alone, its threshold chosen the same way;
- ``validate W RUN``: the threshold and validation score W's head gets on RUN's rows.

Run: python experiments/seed-spread/seeds.py union learned RUN/model.safetensors RUN OUT
"""

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from edeflare.data.folders import dataset_folders
from edeflare.models.event_head import EventHeadEnsemble, head_logits
from edeflare.models.head_training import (
    HeadTrainingConfig,
    _group,
    choose_threshold,
    collect_sets,
    context_columns,
)
from edeflare.models.infer import bundled_weights
from edeflare.models.weights import load_model, save_model

DATA = ["/work/data/train"]  # eflare-train, as `learned` was trained


def _path(w: str) -> Path:
    return Path(w) if w.endswith(".safetensors") else bundled_weights(w)


def _threshold(head, run: Path) -> tuple[float, float]:
    summary = json.loads((run / "head.json").read_text())
    config = HeadTrainingConfig(
        **{k: tuple(v) if isinstance(v, list) else v for k, v in summary["config"].items()}
    )
    folders = [p for d in DATA for p in dataset_folders(d)]
    base = Path(summary["base_weights"])
    sets, files, _ = collect_sets(folders, base, run, config, progress=False)
    val = sets["test"]
    groups = np.array([_group(files["test"], int(i)) for i in val["source"]])
    logits = head_logits(head.numpy_params(), context_columns(head, val))
    threshold, table = choose_threshold(logits, val["y"], groups)
    return threshold, max(r["score"] for r in table)


def _save(net, card, head, threshold: float, score: float, out: Path, note: str) -> None:
    net.head = head
    card = dataclasses.replace(
        card,
        head=head.spec(),
        keep_threshold=threshold,
        metrics={"head_validation_score": score},
        notes=note,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    save_model(out, net, card)
    print(f"{out}: threshold {threshold:.2f}, validation {score:.4f}")


def main() -> None:
    kind = sys.argv[1]
    if kind == "union":
        a, b, run, out = sys.argv[2:6]
        net, card = load_model(_path(a), "cpu")
        net_b, _ = load_model(_path(b), "cpu")
        head = EventHeadEnsemble([*net.head.members, *net_b.head.members])
        threshold, score = _threshold(head, Path(run))
        _save(net, card, head, threshold, score, Path(out), f"members of {a} and {b}")
    elif kind == "member":
        w, i, run, out = sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5]
        net, card = load_model(_path(w), "cpu")
        head = net.head.members[i]
        threshold, score = _threshold(head, Path(run))
        _save(net, card, head, threshold, score, Path(out), f"member {i} of {w}")
    elif kind == "validate":
        w, run = sys.argv[2], sys.argv[3]
        net, _ = load_model(_path(w), "cpu")
        threshold, score = _threshold(net.head, Path(run))
        print(f"{w}: threshold {threshold:.2f}, validation {score:.4f} on {run}'s test rows")
    else:
        raise SystemExit(__doc__)


if __name__ == "__main__":
    main()
