"""python snapshot.py RUN OUT.safetensors: the latest checkpoint of a training run as weights."""
import json
import sys
from pathlib import Path

import torch

from edeflare.models import create_model
from edeflare.models.weights import ModelCard, save_model

if __name__ == "__main__":
    run = Path(sys.argv[1])
    state = torch.load(run / "checkpoint.pt", map_location="cpu", weights_only=True)
    config = json.loads(state["config"])
    model = create_model(config["preset"])
    model.load_state_dict(state["model"])
    card = ModelCard(preset=config["preset"], notes=f"{run} at iteration {int(state['iteration'])}")
    save_model(sys.argv[2], model, card)
    print(sys.argv[2], "iteration", int(state["iteration"]))
