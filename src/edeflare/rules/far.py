"""The far rule: flare lies around its source, so far from every light an event is scene.

An event of a window with lights is far from them where it lies beyond
:data:`~edeflare.rules.halo.FAR_REACH` of the sensor's width and
:data:`~edeflare.rules.halo.FAR_RADII` of each light's radii
(:func:`~edeflare.rules.halo.far_from_lights`), and neither where their ghosts can
be (:func:`~edeflare.rules.ghost.ghost_cells`) nor on their diffraction spikes
(:func:`~edeflare.rules.streak.in_streak_prior`): the flare that does reach far.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from . import Rule, knob
from .context import WindowContext
from .halo import far_from_lights

__all__ = ["FAR_RULE", "FarParams"]


@dataclasses.dataclass(frozen=True)
class FarParams:
    """The far rule's knob."""

    far_shift: float = knob(
        0.0,
        "--far-shift",
        "raise the keep logit by this much for the events far from every light of their "
        "window (beyond 0.3 of the sensor's width and 8 of the light's radii, and not "
        "where the lights' ghosts can be nor on their spikes: flare lies around its "
        "source; 0: off)",
    )


def _far_shift(params: FarParams, ctx: WindowContext) -> np.ndarray:
    far = far_from_lights(
        ctx.events, ctx.sensor_size, ctx.span_us, lights=ctx.lights, exclude=ctx.ghost_cells
    )
    return params.far_shift * (far & ~ctx.on_spikes)


FAR_RULE = Rule(
    "far", FarParams, _far_shift, lambda p: bool(p.far_shift), "lights",
    "far from every light (flare lies around its source)",
)  # fmt: skip
