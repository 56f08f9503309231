"""Where does a head read the rate once its per-event features are relative? The Gen3 light
with half its events (each kept with probability 0.5, seed 0), scored at one phase as
``thin_probe.py`` scores it, with the cell counts the head's context reads given the values
twice the rate would give them (each count channel is log(1 + n): n doubled; the share of
firing pixels and the network's logits left): if the light comes back, the context maps
carry the rest of the rate.

Run: python experiments/relative-rates/context_counts.py WEIGHTS OUT.json
"""

import json
import sys
import tempfile
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "rate-thinning"))
from _half import score_half, write_half

from edeflare.models.event_head import EventHead
from edeflare.models.infer import resolve_weights
from edeflare.models.weights import read_card

weights, dst = sys.argv[1], Path(sys.argv[2])
bins = read_card(resolve_weights(weights)).bins
original = EventHead.context_maps


def run(factor: float, path: Path) -> list[float]:
    def scaled(self, cells):  # type: ignore[no-untyped-def]
        counts = cells.shape[1] - 2 * bins - 1  # the log counts; then the share, the logits
        cells = cells.clone()
        cells[:, :counts] = torch.log1p(factor * torch.expm1(cells[:, :counts]))
        return original(self, cells)

    EventHead.context_maps = scaled
    try:
        return score_half(path, {"weights": weights, "runtime": "torch"})
    finally:
        EventHead.context_maps = original


out: dict[str, object] = {"weights": weights}
with tempfile.TemporaryDirectory() as tmp:
    path = write_half(tmp)
    for arm, factor in (("as thinned", 1.0), ("context counts x 2", 2.0)):
        out[arm] = run(factor, path)
        print(arm, out[arm], flush=True)
dst.write_text(json.dumps(out, indent=1))
