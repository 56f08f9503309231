r"""Sequences of the training recipes (kind ``"flare"``): E-Flare-2.7K and eflare-mini.

Sequence ``i`` draws from ``numpy.random.SeedSequence([recipe.seed, i])``
(children: script, background, composition, forward model): the script
(:func:`~edeflare.sim.script.draw_script`, duration the recipe's), the
background (the recipe's source, drawn with the script's camera), then the
pair (:func:`edeflare.sim.pair.simulate_pair`: the flare and light videos
through one camera, sampled at every event, composed with the recipe's
variant and weights).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ParameterError
from ..sim.background import Background, BackgroundSource
from ..sim.pair import StageTimer, simulate_pair
from ..sim.render import flare7k_names
from ..sim.script import FlareScript, draw_script
from .kinds import STAGES, GenerationError, KindSequence, register_kind
from .sources import cached_source, check_index

if TYPE_CHECKING:  # pragma: no cover
    from .recipe import Recipe

__all__ = ["SequenceInputs", "draw_inputs", "flare_sequence"]

_FLARE7K: dict[str, list[str]] = {}


@dataclass(frozen=True)
class SequenceInputs:
    """The random inputs of one sequence: script, background and the remaining seeds."""

    index: int
    script: FlareScript
    background: Background
    compose_seed: np.random.SeedSequence
    forward_seed: np.random.SeedSequence


def _flare7k_names(root: str) -> list[str]:
    if root not in _FLARE7K:
        names = flare7k_names(root)
        if not names:
            raise GenerationError(f"{root}: holds no Flare7K++ image pairs")
        _FLARE7K[root] = names
    return _FLARE7K[root]


def draw_inputs(
    recipe: Recipe, index: int, *, source: BackgroundSource | None = None
) -> SequenceInputs:
    """Sequence ``index``'s script and background: the first step of a flare sequence.

    Examples
    --------
    >>> from edeflare.data.recipe import Recipe
    >>> from edeflare.sim.background import SceneConfig
    >>> r = Recipe(sensor_size=(32, 24), duration_us=20_000, scene=SceneConfig(fps=1000.0))
    >>> a, b = draw_inputs(r, 5), draw_inputs(r, 5)
    >>> a.script == b.script, a.background.description == b.background.description
    (True, True)
    """
    index = check_index(recipe, index)
    size, duration = recipe.sensor_size, recipe.duration_us
    s_script, s_bg, s_comp, s_fwd = np.random.SeedSequence([recipe.seed, index]).spawn(4)
    ms = duration / 1000
    config = dataclasses.replace(recipe.script, duration_ms=(ms, ms))
    names = _flare7k_names(recipe.flare7k) if recipe.flare7k else None
    script = draw_script(config, flare7k_names=names, rng=np.random.default_rng(s_script))
    if script.duration_us != duration:  # ScriptConfig rounds ms to µs
        script = dataclasses.replace(script, duration_us=duration)
    src = source or cached_source(recipe)
    background = src.draw(duration, size, script.sensor, rng=np.random.default_rng(s_bg))
    return SequenceInputs(index, script, background, s_comp, s_fwd)


@register_kind(
    "flare",
    cli_options=(
        "--sequences",
        "--test-sequences",
        "--variant",
        "--flare7k",
        "--no-components",
        "--background",
    ),
)
def flare_sequence(
    recipe: Recipe, index: int, source: BackgroundSource | None = None
) -> KindSequence:
    """Simulate sequence ``index`` of a ``"flare"`` recipe (see the module docstring).

    Examples
    --------
    >>> from edeflare.data.recipe import Recipe
    >>> from edeflare.sim.background import SceneConfig
    >>> r = Recipe(sensor_size=(32, 24), duration_us=20_000, scene=SceneConfig(fps=1000.0))
    >>> made = flare_sequence(r, 0)
    >>> list(made.streams)
    ['input', 'gt', 'flare', 'light', 'background']
    """
    if recipe.kind != "flare":
        raise ParameterError(f"flare_sequence needs a 'flare' recipe, got kind {recipe.kind!r}")
    timer = StageTimer(STAGES)
    with timer("background"):
        inputs = draw_inputs(recipe, index, source=source)
    pair = simulate_pair(
        inputs.script,
        inputs.background,
        recipe.sensor_size,
        variant=recipe.variant,
        weights=recipe.weights,
        jitter_us=recipe.jitter_us,
        independent_background=recipe.independent_background,
        flare7k=recipe.flare7k,
        rng=inputs.compose_seed,
        forward_seed=inputs.forward_seed,
        timer=timer,
    )
    return KindSequence(
        pair.streams, inputs.script, inputs.background.description, timer.seconds, pair.components
    )
