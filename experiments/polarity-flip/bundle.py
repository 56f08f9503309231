"""Bundle a run's weights with the card that says how they were made.

    python bundle.py RUN/model.safetensors OUT.safetensors THRESHOLD SCORES_JSON \
        [OLD=NEW ...]

THRESHOLD is the keep threshold to use, SCORES_JSON the real-recording scores to add
to the card's metrics, and each OLD=NEW replaces a scratch path in the recorded
command by the name the card's text uses (the data folder, the run, the init weights).
Unlike the earlier experiments' bundle scripts, the paths are arguments, not edits.
"""

import dataclasses
import json
import sys

from edeflare.models.weights import load_model, save_model

DATA = (
    "MIX = the training files of NIGHT (edeflare simulate NIGHT --recipe eflare-night "
    "--workers 2: 168 sequences of 100 ms at 346x260, seed 0) and of DAY (python "
    "experiments/day-mix/gen_day.py DAY 72: eflare-night's lights, flare, sparse sensing "
    "and hot pixels over a street lit as by day; 66 sequences, seed 101), side by side in "
    "MIX/train and MIX/test (file names prefixed night_ and day_); every window's ON and "
    "OFF swapped at random in half the draws (--polarity-flip); started from the previous "
    "default (src/edeflare/assets/night.safetensors at commit 7e5b73e)"
)

if __name__ == "__main__":
    run, out, threshold = sys.argv[1], sys.argv[2], float(sys.argv[3])
    scores = json.loads(sys.argv[4])
    model, card = load_model(run)
    command = card.command
    for pair in sys.argv[5:]:
        old, new = pair.split("=", 1)
        command = command.replace(old, new)
    card = dataclasses.replace(
        card,
        command=command,
        data=DATA,
        keep_threshold=threshold,
        metrics={**card.metrics, **scores},
        notes="the default model: flare mask for real recordings, night and day scenes, "
        "either polarity order; see edeflare/assets/night.md",
    )
    save_model(out, model, card)
    print(card)
