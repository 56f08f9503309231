"""python bundle.py RUN/model.safetensors OUT.safetensors THRESHOLD: the run's weights with the
card that says how they were made, the keep threshold to use, and the real-recording scores."""
import dataclasses
import json
import sys

from edeflare.models.weights import load_model, save_model

DATA = (
    "experiments/night-mask (2026-11-25): gen.py night2.json (112 train sequences) + mixed.json "
    "(56), 346x260, 100 ms; thin.py NEAR=2 KEEP_NEAR=1 q in [0.003, 0.2] falloff 2; noise.py "
    "0.3-20 events/px/s; keep-only targets (the eflare-night recipe does the same in the package)"
)

if __name__ == "__main__":
    run, out, threshold = sys.argv[1], sys.argv[2], float(sys.argv[3])
    model, card = load_model(run)
    scores = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
    card = dataclasses.replace(
        card,
        command=card.command.replace("/tmp/edata_train4", "DATA").replace("/tmp/exp/run_k4f", "RUN"),
        data=DATA,
        keep_threshold=threshold,
        metrics={**card.metrics, **scores},
        notes="sparse-flare mask for real night recordings; see edeflare/assets/night.md",
    )
    save_model(out, model, card)
    print(card)
