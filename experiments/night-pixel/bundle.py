"""python bundle.py RUN/model.safetensors OUT.safetensors THRESHOLD '{"score": ...}':
the run's weights with the card that says how they were made, the keep threshold to
use, and the real-recording scores."""

import dataclasses
import json
import sys

from edeflare.models.weights import load_model, save_model

DATA = (
    "edeflare simulate DATA --recipe eflare-night --workers 2 (180 sequences of 100 ms at "
    "346x260, dataset seed 0: the simulator calibrated on real night recordings, sparse "
    "scattered light, background activity to keep, up to 8 hot pixels to remove, keep-only "
    "targets); started from the previous night model (mask.fast, experiments/night-mask/run_k4f)"
)

if __name__ == "__main__":
    run, out, threshold = sys.argv[1], sys.argv[2], float(sys.argv[3])
    model, card = load_model(run)
    scores = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
    card = dataclasses.replace(
        card,
        command=card.command.replace("/tmp/s17/eflare-night-hot", "DATA")
        .replace("/tmp/s17/runs/px3", "RUN")
        .replace("/tmp/s17/k4f.safetensors", "k4f.safetensors"),
        data=DATA,
        keep_threshold=threshold,
        metrics={**card.metrics, **scores},
        notes="the default model: sparse-flare mask for real recordings; see "
        "edeflare/assets/night.md",
    )
    save_model(out, model, card)
    print(card)
