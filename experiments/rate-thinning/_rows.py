"""The cache file a head run over ``base`` keeps its drawn rows of the subset ``RUNS/s0`` in
(``features-SPLIT-KEY.npz``, the key as :mod:`edeflare.models.head_training` names it)."""

from pathlib import Path

from edeflare.io.sequence import list_sequences
from edeflare.models.head_training import HeadTrainingConfig, _identity


def cache_path(run: Path, base: Path, config: HeadTrainingConfig, split: str) -> Path:
    """``run``'s rows of ``split`` over ``base``, for the subset beside ``run``."""
    folders = sorted((run.parent / "s0").iterdir())  # as the shell's RUNS/s0/* lists them
    files = [f for d in folders if (d / split).is_dir() for f in list_sequences(d / split)]
    return run / f"features-{split}-{_identity(files, base, config, split)}.npz"
