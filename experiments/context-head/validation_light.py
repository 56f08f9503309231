"""The validation split's flare removed, scene kept and light kept, per keep threshold.

For heads over the same cached test features of a `train-head --light-weight` run (its
`features-test-*.npz` holds each row's light flag): the mean over the validation groups
of the flare removed and of the scene kept (the light's events left out), and the share
of the light's own events kept.

    python experiments/context-head/validation_light.py DATA RUN/features-test-*.npz \
        learned runs/lwA/model.safetensors
"""

from __future__ import annotations

import sys

import numpy as np

from edeflare.data.folders import dataset_folders
from edeflare.io.sequence import list_sequences
from edeflare.models.event_head import head_logits
from edeflare.models.head_training import (
    _group,
    _keep_probability,
    context_columns,
    load_teacher,
)
from edeflare.models.infer import bundled_weights, resolve_weights
from edeflare.models.weights import read_card


def main() -> None:
    data, cache, *models = sys.argv[1:]
    with np.load(cache) as z:
        val = {k: z[k] for k in z.files}
    files = [
        str(f) for d in dataset_folders(data) if (d / "test").is_dir()
        for f in list_sequences(d / "test")
    ]  # fmt: skip
    groups = np.array([_group(files, int(i)) for i in val["source"]])
    y, light = val["y"], val["light"]
    print(f"{y.size:,} validation rows, {light.sum():,} of the light's own events")
    for name in models:
        weights = resolve_weights(name)
        features = tuple(read_card(weights).head["features"])  # the head's own
        head = load_teacher(weights, bundled_weights("night"), features, context=True)
        p = _keep_probability(head_logits(head.numpy_params(), context_columns(head, val)))
        for thr in (0.4, 0.45, 0.5, 0.6, 0.7, 0.8):
            kept = p > thr
            removed = [1 - kept[(groups == g) & ~y].mean() for g in np.unique(groups)
                       if ((groups == g) & ~y).any()]  # fmt: skip
            scene = [kept[(groups == g) & y & ~light].mean() for g in np.unique(groups)
                     if ((groups == g) & y & ~light).any()]  # fmt: skip
            print(
                f"{name} at {thr}: flare removed {np.mean(removed):.3f}, scene kept "
                f"{np.mean(scene):.3f}, light kept {kept[light].mean():.3f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
