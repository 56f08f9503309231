r"""Sequences of the ``eflare-r-sim`` recipes: the paper's real-capture model, simulated.

A recipe of kind ``"optics"`` (:data:`edeflare.data.generate.RECIPES`
``eflare-r-sim`` and ``eflare-r-sim-mini``) makes a paired **test** set after
E-Flare-R's physical model (Sec. 3.3, App. A.3):
:math:`E_{ob} = \mathcal S(I_{gt} * \mathrm{PSF}_{ob})`,
:math:`E_{gt} = \mathcal S(I_{gt} * \mathrm{PSF}_{clean})`, with a star or
random-pattern filter, point lights, square lamps and strobes moving in front
of a synthetic street (imaged through both lenses) or recorded events (fused
by PNL-ES), one sensor draw per pair (:mod:`edeflare.sim.optics_scene`).

It differs from the training recipes on purpose, as the paper's real set
does (other sources, other filters, the clean lens's own diffraction in the
ground truth, no reflective ghosts or glare), so it measures generalisation.

Sequence ``i`` draws from ``numpy.random.SeedSequence([recipe.seed, i])``
(children: scene, background, pair), like every recipe.

From Python, any number of sequences with any seed (all of them test
sequences), e.g. to evaluate models trained on other recipes::

    from edeflare.data.generate import RECIPES, generate_dataset

    if __name__ == "__main__":  # workers are spawned processes
        recipe = RECIPES["eflare-r-sim-mini"].replace(sequences=20, seed=7)
        generate_dataset(recipe, "data/r-sim-mini", workers=2)  # data/r-sim-mini/test/*.h5
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from ..sim.background import Background, BackgroundSource, NightStreet
from ..sim.optics_scene import (
    OpticsScene,
    OpticsSceneConfig,
    draw_optics_scene,
    simulate_optics_pair,
)
from .kinds import KindSequence, register_kind
from .sources import cached_source

if TYPE_CHECKING:  # pragma: no cover
    from .recipe import Recipe

__all__ = ["optics_sequence"]


def optics_sequence(
    recipe: Recipe, index: int, source: BackgroundSource | None = None
) -> tuple[dict[str, np.ndarray], OpticsScene, dict[str, Any], dict[str, float]]:
    """Simulate sequence ``index`` of an ``"optics"`` recipe.

    Parameters
    ----------
    recipe : Recipe
        Of kind ``"optics"``; uses ``config`` (scene ranges), ``scene`` (the
        synthetic street), ``background`` / ``background_files``, ``sensor_size``,
        ``duration_us`` and ``seed``.
    index : int
    source : BackgroundSource, optional
        The opened recorded-background source (``background="recorded"``).

    Returns
    -------
    (streams, scene, background, seconds, frames)
        ``{"input", "gt"} -> events``, the drawn :class:`OpticsScene`, the
        background's JSON-ready description, seconds per stage, and the clean
        lens's images at the windows' ends, ``(times_us, (T, H, W))`` (None
        with a recorded background).

    Examples
    --------
    >>> from edeflare.data.generate import RECIPES
    >>> from edeflare.sim.optics_scene import OpticsSceneConfig
    >>> r = RECIPES["eflare-r-sim-mini"].replace(sensor_size=(48, 32), duration_us=2_000,
    ...     window_us=1_000, optics=OpticsSceneConfig(psf_grid=64))
    >>> streams, scene, bg, _, (times, images) = optics_sequence(r, 0)
    >>> sorted(streams), bg["kind"], scene.duration_us, times.tolist(), images.shape
    (['gt', 'input'], 'synthetic', 2000, [1000, 2000], (2, 32, 48))
    """
    size, duration = recipe.sensor_size, recipe.duration_us
    t0 = time.perf_counter()
    s_scene, s_bg, s_pair = np.random.SeedSequence([recipe.seed, int(index)]).spawn(3)
    scene = draw_optics_scene(
        recipe.config, duration_us=duration, rng=np.random.default_rng(s_scene)
    )
    if recipe.background == "recorded":
        if source is None:
            raise ValueError("a recorded-background recipe needs its opened source")
        background: Background | NightStreet = source.draw(
            duration, size, scene.sensor, rng=np.random.default_rng(s_bg)
        )
        description = dict(background.description)
    else:
        background = NightStreet(size, recipe.scene, rng=np.random.default_rng(s_bg))
        description = {"kind": "synthetic", "duration_us": duration, "scene": background.describe()}
    drawn = time.perf_counter() - t0
    ends = np.arange(recipe.window_us, duration + 1, recipe.window_us, dtype=np.int64)
    pair = simulate_optics_pair(
        scene, size, background=background, rng=np.random.default_rng(s_pair), frame_times_us=ends
    )
    seconds = {"background": drawn, **pair.seconds}
    frames = None if pair.frames is None else (ends, pair.frames)
    return {"input": pair.input, "gt": pair.gt}, scene, description, seconds, frames


@register_kind(
    "optics",
    config_field="optics",
    config_type=OpticsSceneConfig,
    test_only=True,
    cli_options=("--sequences", "--background"),
)
def _make_sequence(
    recipe: Recipe, index: int, source: BackgroundSource | None = None
) -> KindSequence:
    """The ``"optics"`` kind: :func:`optics_sequence` with the recipe's background source."""
    if recipe.background == "recorded":
        source = source or cached_source(recipe)
    else:
        source = None
    streams, scene, background, seconds, frames = optics_sequence(recipe, index, source)
    return KindSequence(streams, scene, background, seconds, frames=frames)
