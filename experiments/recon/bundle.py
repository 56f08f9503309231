"""Bundle a trained reconstructor: its weights with a card naming the run and its held-out score.

Run from the repository root::

    python experiments/recon/bundle.py experiments/recon/run2 src/edeflare/assets/firenet.safetensors

The held-out score: mean absolute error of the centred images over three
simulated street clips (seeds 10001-10003, 160x120, 8 windows, burn-in
excluded) against that of a flat gray image.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import torch

from edeflare.recon.clips import BURN_IN, draw_clip
from edeflare.recon.weights import ReconCard, load_reconstructor, save_reconstructor


def held_out(model: torch.nn.Module) -> dict[str, float]:
    errors, flat = [], []
    for k, day in ((10_001, False), (10_002, True), (10_003, False)):
        clip = draw_clip((160, 120), 8, day=day, rng=k)
        state = None
        with torch.no_grad():
            for t in range(clip.voxels.shape[0]):
                image, state = model(torch.from_numpy(clip.voxels[t : t + 1]), state)
                if t >= BURN_IN:
                    target = clip.images[t, 0]
                    errors.append(float(np.abs(image[0, 0].numpy() - target).mean()))
                    flat.append(float(np.abs(0.5 - target).mean()))
    return {
        "held_out_l1": float(np.mean(errors)),
        "flat_gray_l1": float(np.mean(flat)),
        "ratio": float(np.mean(errors) / np.mean(flat)),
    }


def main() -> None:
    run, out = Path(sys.argv[1]), Path(sys.argv[2])
    model, card = load_reconstructor(run / "model.safetensors")
    config = json.loads((run / "config.json").read_text())
    metrics = held_out(model)
    print(metrics)
    bundled = ReconCard(
        bins=card.bins,
        features=card.features,
        window_us=card.window_us,
        iterations=card.iterations,
        command=f"python -m edeflare.recon.train {run.as_posix()} (edeflare.recon.train."
        "train_reconstructor, defaults of ReconTrainConfig)",
        data=json.dumps(config, sort_keys=True),
        seed=card.seed,
        metrics=metrics,
    )
    save_reconstructor(out, model, bundled)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
