"""A recording's scores at several window phases, from each event's keep logits.

A model judges an event by the windows it falls in, and a lamp's 100 Hz flicker falls
differently into 20 ms windows at each phase, so the annotated recordings are scored at
several window phases (``score_recording(phases=...)``: the recording delayed by
``k * window / phases``, each phase the mean of the model's two views, the second
``shift`` later). Given each event's keep logits in every windowing those phases run,
:func:`measure_phases` scores any keep threshold without running the model again.

Examples
--------
Four events' keep logits at two phases; two of them flare, one the light. Each phase's
combined score (2/3, then 1) is taken before the mean:

>>> import numpy as np
>>> flare = np.array([True, True, False, False])
>>> light = np.array([False, False, True, False])
>>> phases = [np.array([-3.0, 2.0, 3.0, 1.0]), np.array([-3.0, -2.0, 3.0, 1.0])]
>>> measure_phases(phases, (flare, light, None), [0.5]).round(3).tolist()
[[0.75, 1.0, nan, 0.833]]
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..models.mask_kernels import keep_logit_threshold
from .score import combined_score

__all__ = ["TERMS", "measure_phases", "phase_views"]

TERMS = ("flare removed", "light kept", "scene kept", "combined")
"""The columns of :func:`measure_phases` (without an annotation, the share kept stands in
the combined column)."""


def phase_views(
    window_us: int, shift_us: int, phases: int
) -> tuple[list[int], list[tuple[int, int]]]:
    """The windowings (delays, sorted) that ``phases`` window phases with a second view
    ``shift_us`` later run, and each phase's two views as indices into them.

    Examples
    --------
    >>> phase_views(20_000, 5_000, 4)
    ([0, 5000, 10000, 15000], [(0, 1), (1, 2), (2, 3), (3, 0)])
    """
    w = window_us
    views = [(k * w // phases % w, (k * w // phases + shift_us) % w) for k in range(phases)]
    delays = sorted({d for pair in views for d in pair})
    return delays, [(delays.index(a), delays.index(b)) for a, b in views]


def measure_phases(
    phases: Sequence[np.ndarray],
    regions: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None,
    thresholds: Sequence[float],
) -> np.ndarray:
    """``(thresholds, 4)``: flare removed, light kept, scene kept and the combined score
    (:data:`TERMS`), each the mean over the phases' keep logits ``phases`` (NaN where a
    region is empty); ``regions`` the events' flare, light and scored scene masks (None:
    the share kept, in the combined column)."""
    out = np.full((len(thresholds), len(TERMS)), math.nan)
    for i, threshold in enumerate(thresholds):
        cut = keep_logit_threshold(threshold)
        rows = []
        for logits in phases:
            kept = logits > cut
            if regions is None:
                rows.append((math.nan, math.nan, math.nan, kept.mean()))
                continue
            flare, light, back = regions
            removed = 1 - kept[flare].mean() if flare.any() else math.nan
            lit = kept[light].mean() if light.any() else math.nan
            scene = kept[back].mean() if back is not None and back.any() else math.nan
            rows.append((removed, lit, scene, combined_score(removed, lit, scene)))
        out[i] = np.mean(rows, axis=0)
    return out
