r"""Bundle a trained reconstructor: its weights with a card naming the run and its held-out score.

Run from the repository root::

    python experiments/recon/bundle.py experiments/recon/run2 \
        src/edeflare/assets/firenet.safetensors

The held-out score: ``edeflare.recon.train.held_out_error`` (mean absolute
error of the centred images over three simulated street clips, seeds
10001-10003, 160x120, 8 windows, burn-in excluded, against that of a flat
gray image).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from edeflare.recon.train import held_out_error
from edeflare.recon.weights import ReconCard, load_reconstructor, save_reconstructor


def main() -> None:
    run, out = Path(sys.argv[1]), Path(sys.argv[2])
    model, card = load_reconstructor(run / "model.safetensors")
    config = json.loads((run / "config.json").read_text())
    metrics = held_out_error(model)
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
