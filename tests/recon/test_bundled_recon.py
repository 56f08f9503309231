"""The bundled reconstructor: loads safely and reconstructs held-out simulated clips."""

from __future__ import annotations

import pytest

from edeflare.recon.train import held_out_error
from edeflare.recon.weights import bundled_path, load_reconstructor


def test_bundled_weights_load_with_their_card():
    model, card = load_reconstructor()
    assert bundled_path().stat().st_size < 400_000
    assert card.iterations > 0 and card.window_us == 20_000 and card.bins == model.bins
    assert "train_reconstructor" in card.command


def test_bundled_reconstructor_beats_a_flat_image_on_held_out_clips():
    """Seeds far from the training pool's; night and day streets at a larger size."""
    model, card = load_reconstructor()
    scores = held_out_error(model)
    # 0.894 when bundled (firenet.md); untrained 0.985, after 500 of 2500 iterations 0.922
    assert scores["ratio"] < 0.91
    assert scores["ratio"] == pytest.approx(card.metrics["ratio"], abs=1e-4)  # the card is true
