"""`train-head` with the kept events near a light weighed more in the loss.

(`edeflare train-head --light-weight` now weighs the light's own events, flagged by the
pair's `light` stream; this script keeps the study's proxy to reproduce its runs.)

The real targets ask more of the light (>= 95 % kept) than of the flare (>= 85 % removed).
This fits heads as `edeflare train-head` does, on the same cached events, with one change:
each kept training event within one radius of a light's centre (its `light_distance`
feature, the rules' light detector) weighs WEIGHT times its class weight.

    python experiments/context-head/fit_light_weight.py DATA RUN --weight 4 \
        --hidden 8 --context 8 --members 3 [--scene-weight 4]

``--scene-weight``: the events of each pair's scene alone (a recording without a light,
every event kept; the real targets ask 95 % of such scenes) weigh that many times theirs.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import torch

from edeflare.cli.train_head import _widths  # the CLI's parsing of --hidden
from edeflare.models import head_training
from edeflare.models.event_features import FEATURES
from edeflare.models.head_training import HeadTrainingConfig, train_head
from edeflare.models.infer import bundled_weights


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("run")
    ap.add_argument("--weight", type=float, default=4.0)
    ap.add_argument(
        "--scene-weight",
        type=float,
        default=1.0,
        help="weight of the events of the scene alone (windows without a light, all kept)",
    )
    ap.add_argument("--hidden", type=_widths, default=(8,), help="as train-head's")
    ap.add_argument("--context", type=int, default=8)
    ap.add_argument("--members", type=int, default=3)
    ap.add_argument("--epochs", type=int, default=12)
    a = ap.parse_args()
    base = head_training.loss_weights
    column = list(FEATURES).index("light_distance")
    near: dict[str, np.ndarray] = {}

    def cached(path, make):  # remember which training rows lie near a light
        data = original_cached(path, make)
        if "train" in path.name:
            near["rows"] = data["x"][:, column] <= math.log1p(1.0)
            near["alone"] = data["source"] < 0  # the scene without its light
        return data

    original_cached = head_training._cached
    head_training._cached = cached

    def class_weights(y: np.ndarray, config: HeadTrainingConfig, **_: object) -> torch.Tensor:
        w = base(y, config)  # the class weights alone
        rows = near["rows"]
        if rows.size == y.size:  # the training set (the validation set is not weighed)
            boost = np.where(rows & y, a.weight, 1.0)
            boost = torch.from_numpy(np.where(near["alone"], a.scene_weight, boost))
            w = w * boost.to(w.dtype)
        return w

    head_training.loss_weights = class_weights
    config = HeadTrainingConfig(
        hidden=a.hidden,
        context=a.context,
        members=a.members,
        epochs=a.epochs,
    )
    summary = train_head(
        [a.data],
        bundled_weights("night"),
        a.run,
        config,
        progress=False,
        command=(
            f"fit_light_weight.py {a.data} {a.run} --weight {a.weight} "
            f"--scene-weight {a.scene_weight} --hidden {','.join(map(str, a.hidden))} "
            f"--context {a.context} "
            f"--members {a.members} --epochs {a.epochs}"
        ),
    )
    print(
        f"keep threshold {summary['keep_threshold']:.2f}, "
        f"validation {max(r['score'] for r in summary['threshold_table']):.3f}"
    )


if __name__ == "__main__":
    main()
