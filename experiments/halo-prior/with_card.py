"""python experiments/halo-prior/with_card.py IN.safetensors OUT.safetensors name=JSON...:
the same weights with card fields replaced (e.g. halo_shift=1; a dict such as
metrics='{"a": 1}' is merged into the card's), for scripts that take a weights file and
for the bundled default's card. The tensors are copied unchanged."""

import dataclasses
import json
import sys

from edeflare.models.weights import load_model, save_model

if __name__ == "__main__":
    model, card = load_model(sys.argv[1])
    fields = {k: json.loads(v) for k, v in (a.split("=", 1) for a in sys.argv[3:])}
    for k, v in fields.items():
        if isinstance(v, dict):
            fields[k] = {**getattr(card, k), **v}
    card = dataclasses.replace(card, **fields)
    save_model(sys.argv[2], model, card)
    print({k: v for k, v in dataclasses.asdict(card).items() if k not in ("command", "data")})
