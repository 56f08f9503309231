"""The bundled ``paper`` model: the paper's 3D network trained once on a GPU."""

from __future__ import annotations

import numpy as np
import torch

from conftest import random_events
from edeflare.methods import create_method
from edeflare.models.infer import bundled_weights
from edeflare.models.weights import load_model, read_card, read_tensors


def test_its_card_says_what_it_is_and_the_float16_weights_load_as_float32():
    path = bundled_weights("paper")
    card = read_card(path)
    assert card.preset == "unet3d.paper" and (card.bins, card.window_us) == (8, 20_000)
    assert card.metrics["iteration"] == 1252 and "eflare-2.7k" in card.data
    # the scores it was bundled with: better than the raw input on eflare-r-sim's Chamfer
    # (raw 1.1700) and its reconstruction (raw 21.208 dB), and than eflare on eflare-mini
    assert card.metrics["eflare_r_sim_chamfer"] < 1.17
    assert card.metrics["eflare_r_sim_recon_psnr"] > 21.208
    assert card.metrics["eflare_mini_chamfer"] < 1.0937
    assert {t.dtype for t in read_tensors(path).values()} == {torch.float16}  # half the size
    model, _ = load_model(path)
    assert next(model.parameters()).dtype == torch.float32
    assert sum(p.numel() for p in model.parameters()) == 7_068_961


def test_it_runs_by_name_and_edits_the_input(rng):
    size = (32, 24)
    ev = random_events(rng, 3000, size, t0=0, span_us=20_000)
    out = create_method("model", weights="paper")(ev, size, rng=0)
    assert 0 < len(out) and out["t"].min() >= 0 and out["t"].max() < 20_000
    assert not np.array_equal(out, ev)  # a trained network changes the stream
