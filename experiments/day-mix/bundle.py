"""python bundle.py RUN/model.safetensors OUT.safetensors THRESHOLD '{"score": ...}':
the run's weights with the card that says how they were made, the keep threshold to
use, and the real-recording scores."""

import dataclasses
import json
import sys

from edeflare.models.weights import load_model, save_model

DATA = (
    "MIX = the training files of NIGHT (edeflare simulate NIGHT --recipe eflare-night "
    "--workers 2: 168 sequences of 100 ms at 346x260, seed 0) and of DAY (python "
    "experiments/day-mix/gen_day.py DAY 72: eflare-night's lights, flare, sparse sensing "
    "and hot pixels over a street lit as by day, 12-43 events per pixel and second to "
    "keep; 66 sequences, seed 101), side by side in MIX/train and MIX/test; started from "
    "the previous default (src/edeflare/assets/night.safetensors at commit 9893b7a)"
)

if __name__ == "__main__":
    run, out, threshold = sys.argv[1], sys.argv[2], float(sys.argv[3])
    model, card = load_model(run)
    scores = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
    card = dataclasses.replace(
        card,
        command=card.command.replace("/tmp/s18/mix", "MIX")
        .replace("experiments/day-mix/run_d1", "RUN")
        .replace("--init night", "--init night-9893b7a.safetensors"),
        data=DATA,
        keep_threshold=threshold,
        metrics={**card.metrics, **scores},
        notes="the default model: flare mask for real recordings, night and day scenes; see "
        "edeflare/assets/night.md",
    )
    save_model(out, model, card)
    print(card)
