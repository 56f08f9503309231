"""Reconstructor weights on disk: safetensors with a JSON card, never a pickle."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch

from ..models.infer import bundled_weights
from ..models.weights import WeightsError, read_metadata, read_tensors, write_weights
from .network import FireNet

__all__ = ["BUNDLED", "ReconCard", "bundled_path", "load_reconstructor", "save_reconstructor"]

_CARD_KEY = "edeflare_recon_card"
BUNDLED = "firenet"
"""Name of the bundled reconstructor (``src/edeflare/assets/firenet.safetensors``)."""


@dataclass(frozen=True)
class ReconCard:
    """What a reconstructor weights file is and how it was made.

    Examples
    --------
    >>> ReconCard.from_dict(ReconCard(iterations=3).to_dict()) == ReconCard(iterations=3)
    True
    """

    bins: int = 5
    features: int = 16
    window_us: int = 20_000
    iterations: int = 0
    command: str = ""
    data: str = ""
    seed: int | None = None
    metrics: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ReconCard:
        """Inverse of :meth:`to_dict` (unknown keys are ignored: newer files load)."""
        known = {k: v for k, v in data.items() if k in cls.__dataclass_fields__}
        return cls(**known)


def bundled_path() -> Path:
    """Path of the bundled reconstructor's weights (a clear error where it is missing)."""
    return bundled_weights(BUNDLED)


def save_reconstructor(path: str | os.PathLike[str], model: FireNet, card: ReconCard) -> None:
    """Write ``model`` and ``card`` to a ``.safetensors`` file, atomically.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "r.safetensors"
    >>> save_reconstructor(p, FireNet(), ReconCard())
    >>> load_reconstructor(p)[1].bins
    5
    """
    write_weights(path, model, _CARD_KEY, card.to_dict())


def load_reconstructor(
    path: str | os.PathLike[str] | None = None, device: str | torch.device = "cpu"
) -> tuple[FireNet, ReconCard]:
    """Load a reconstructor (default: the bundled one): ``(model in eval mode, card)``."""
    path = bundled_path() if path is None or str(path) == BUNDLED else Path(path)
    meta = read_metadata(path)
    if _CARD_KEY not in meta:
        raise WeightsError(f"{path}: no reconstructor card in the metadata (a de-flaring model?)")
    try:
        card = ReconCard.from_dict(json.loads(meta[_CARD_KEY]))
    except (json.JSONDecodeError, TypeError) as exc:
        raise WeightsError(f"{path}: reconstructor card is not valid JSON ({exc})") from None
    model = FireNet(card.bins, card.features)
    tensors = read_tensors(path)
    expected = model.state_dict()
    if set(expected) != set(tensors) or any(
        tensors[k].shape != expected[k].shape for k in expected
    ):
        raise WeightsError(f"{path}: tensors do not fit a FireNet of {card.bins} bins")
    model.load_state_dict(tensors)
    return model.to(device).eval(), card
