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

import numpy as np
import torch

from edeflare.eval.score import score_recording
from edeflare.io import read_events, write_events
from edeflare.lights import bundled_lights
from edeflare.models.event_head import EventHead
from edeflare.models.infer import resolve_weights
from edeflare.models.weights import read_card

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
FILE = "prophesee_gen3_rotating_light.raw"
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
        res = score_recording(
            path,
            ["model"],
            lights=bundled_lights(FILE),
            phases=1,
            method_params={"model": {"weights": weights, "runtime": "torch"}},
        )
    finally:
        EventHead.context_maps = original
    m = res.rows[0]
    return [round(float(v), 4) for v in (m.flare_removed, m.light_kept, m.combined)]


r = read_events(REAL / FILE)
out: dict[str, object] = {"weights": weights}
with tempfile.TemporaryDirectory() as tmp:
    path = Path(tmp) / "half.h5"
    write_events(
        path, r.events[np.random.default_rng(0).random(r.events.size) < 0.5], r.sensor_size
    )
    for arm, factor in (("as thinned", 1.0), ("context counts x 2", 2.0)):
        out[arm] = run(factor, path)
        print(arm, out[arm], flush=True)
dst.write_text(json.dumps(out, indent=1))
