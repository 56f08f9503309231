"""The background source of a recipe, opened once per process.

Examples
--------
>>> from edeflare.data.recipe import RECIPES
>>> type(make_background_source(RECIPES["eflare-mini"])).__name__
'SyntheticBackground'
>>> cached_source(RECIPES["eflare-mini"]) is cached_source(RECIPES["eflare-mini"])
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ParameterError
from ..sim.background import BackgroundSource, RecordedBackground, SyntheticBackground

__all__ = ["cached_source", "check_index", "make_background_source"]

_SOURCES: dict[str, BackgroundSource] = {}


def make_background_source(recipe: Any) -> BackgroundSource:
    """The background source a recipe asks for (recorded files or synthetic streets).

    Its intensities follow the kind's ``weights`` where its config has them
    (the flare kind's PNL-ES weights); other kinds take the default, ``"intensity"``.
    """
    weights = getattr(recipe.config, "weights", "intensity")
    if recipe.background == "recorded":
        return RecordedBackground(
            recipe.background_files,
            intensity="counts" if weights == "counts" else "accumulation",
            accumulation=recipe.accumulation,
        )
    intensity = {"intensity": "video", "accumulation": "accumulation", "counts": "counts"}
    return SyntheticBackground(
        recipe.scene, intensity=intensity[weights], accumulation=recipe.accumulation
    )


def cached_source(recipe: Any) -> BackgroundSource:
    """:func:`make_background_source`, kept for the last recipe used in this process."""
    key = recipe.sha256()
    if key not in _SOURCES:
        _SOURCES.clear()
        _SOURCES[key] = make_background_source(recipe)
    return _SOURCES[key]


def check_index(recipe: Any, index: Any) -> int:
    """``index`` as an int in ``[0, recipe.sequences)`` (else a ParameterError naming it)."""
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise ParameterError(f"index must be an int, got {index!r}")
    if not 0 <= index < recipe.sequences:
        raise ParameterError(f"index must be in [0, {recipe.sequences}), got {index}")
    return int(index)
