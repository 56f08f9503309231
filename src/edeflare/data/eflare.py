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
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._validation import nested_from_dicts
from ..errors import ParameterError
from ..sim.background import Background, BackgroundSource
from ..sim.pair import PAIR_VARIANTS, WEIGHTS, StageTimer, simulate_pair
from ..sim.render import flare7k_names
from ..sim.script import FlareScript, ScriptConfig, draw_script
from ..sim.sensing import SensingConfig, sparse_sensing
from ..sim.surround import SurroundConfig
from .kinds import STAGES, GenerationError, KindSequence, register_kind
from .sources import cached_source, check_index

if TYPE_CHECKING:  # pragma: no cover
    from .recipe import Recipe

__all__ = ["FlareConfig", "SequenceInputs", "draw_inputs", "flare_sequence"]

SENSING_STREAM = 7
"""The sparse-sensing stage draws from ``SeedSequence((seed, i, 7))``."""
SURROUND_STREAM = 8
"""The lit surroundings draw from ``SeedSequence((seed, i, 8))``."""


@dataclass(frozen=True)
class FlareConfig:
    """The ``"flare"`` kind's own settings (``recipe.config``): how a training pair is made.

    Parameters
    ----------
    variant : str
        ``"physical"`` (PNL-ES), ``"simple"``, ``"simple+random"``,
        ``"physical+random"``, ``"no-light"`` or ``"forward"`` (full forward
        model; synthetic backgrounds only).
    weights : {"intensity", "accumulation", "counts"}
        Where PNL-ES intensities come from (:data:`edeflare.sim.pair.WEIGHTS`);
        also what the background source computes.
    jitter_us : float
        Half-width of the ``+random`` variants' jitter.
    independent_background : bool
        Thin the background separately for input and ground truth.
    components : bool
        Store the pure flare, light and background streams too.
    flare7k : str, optional
        A Flare7K++ folder; scripts then use its image pairs.
    script : ScriptConfig
        Ranges of the flare scripts (the duration is the recipe's).
    sensing : SensingConfig
        The sparse-sensing stage (:mod:`edeflare.sim.sensing`, off unless
        ``enabled``): scattered light sensed as scattered events, the
        keep-only target ``gt`` and the simulator's own as ``gt_full``.
    surround : SurroundConfig
        How often the light lights the scene around it, flickering with it
        (:mod:`edeflare.sim.surround`; forward model only, off unless ``probability``).

    Examples
    --------
    >>> c = FlareConfig.from_dict({"variant": "forward", "script": {"exposure": [1, 2]}})
    >>> c.variant, c.script.exposure
    ('forward', (1.0, 2.0))
    >>> FlareConfig.from_dict(c.to_dict()) == c
    True
    >>> FlareConfig(variant="fancy")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: variant must be one of (...), got 'fancy'
    """

    variant: str = "physical"
    weights: str = "intensity"
    jitter_us: float = 1000.0
    independent_background: bool = False
    components: bool = True
    flare7k: str | None = None
    script: ScriptConfig = field(default_factory=ScriptConfig)
    sensing: SensingConfig = field(default_factory=SensingConfig)
    surround: SurroundConfig = field(default_factory=SurroundConfig)

    def __post_init__(self) -> None:
        if self.variant not in PAIR_VARIANTS:
            raise ParameterError(f"variant must be one of {PAIR_VARIANTS}, got {self.variant!r}")
        if self.weights not in WEIGHTS:
            raise ParameterError(f"weights must be one of {WEIGHTS}, got {self.weights!r}")
        try:
            ok = math.isfinite(float(self.jitter_us)) and self.jitter_us >= 0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ParameterError(f"jitter_us must be >= 0, got {self.jitter_us!r}")
        for key in ("independent_background", "components"):
            if not isinstance(getattr(self, key), bool):
                raise ParameterError(f"{key} must be a bool, got {getattr(self, key)!r}")
        if self.flare7k is not None:
            object.__setattr__(self, "flare7k", str(self.flare7k))
        for key, config_type in _NESTED.items():
            if not isinstance(getattr(self, key), config_type):
                raise ParameterError(f"{key} must be a {config_type.__name__}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FlareConfig:
        """Build from a mapping (nested configs as mappings); unknown keys are an error."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"a flare config must be a mapping, got {type(data).__name__}")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ParameterError(f"unknown flare key(s) {unknown}; valid keys: {sorted(names)}")
        return cls(**nested_from_dicts(dict(data), _NESTED))

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (:meth:`from_dict` round-trips it).

        ``sensing``, ``surround`` and the script's ``warm_start`` are left out while off,
        so recipes keep the dicts and digests they had before they existed.
        """
        optional = ("sensing", "surround")
        fields = [f.name for f in dataclasses.fields(self) if f.name not in optional]
        d: dict[str, Any] = {name: getattr(self, name) for name in fields}
        d["script"] = dataclasses.asdict(self.script)
        if not self.script.warm_start:  # left out while off, as the optional stages
            del d["script"]["warm_start"]
        if self.sensing.enabled:
            d["sensing"] = self.sensing.to_dict()
        if self.surround.enabled:
            d["surround"] = self.surround.to_dict()
        return json.loads(json.dumps(d))


_NESTED: dict[str, type] = {
    "script": ScriptConfig,
    "sensing": SensingConfig,
    "surround": SurroundConfig,
}


def _check_recipe(recipe: Recipe) -> None:
    """What a flare config asks of the rest of the recipe."""
    if recipe.config.surround.enabled and recipe.config.variant != "forward":
        raise ParameterError(
            "surround (a lamp's lit, flickering surroundings) needs variant='forward': "
            "the scene's video is lit"
        )
    if recipe.config.variant == "forward" and recipe.background != "synthetic":
        raise ParameterError(
            "variant='forward' simulates I_bg + I_f and needs the background as a video: "
            "use background='synthetic'"
        )


def _identity(config: dict[str, Any]) -> dict[str, Any]:
    """The Flare7K++ folder by its name: the same images anywhere give the same dataset."""
    root = config.get("flare7k")
    return {**config, "flare7k": None if root is None else Path(root).name}


def _file_attrs(recipe: Recipe) -> dict[str, Any]:
    return {"variant": recipe.config.variant}


def _file_groups(recipe: Recipe) -> tuple[str, ...] | None:
    """Without ``components`` a file keeps its pair (and ``gt_full``) only."""
    return None if recipe.config.components else ("input", "gt", "gt_full")


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
    config = dataclasses.replace(recipe.config.script, duration_ms=(ms, ms))
    names = _flare7k_names(recipe.config.flare7k) if recipe.config.flare7k else None
    script = draw_script(config, flare7k_names=names, rng=np.random.default_rng(s_script))
    if script.duration_us != duration:  # ScriptConfig rounds ms to µs
        script = dataclasses.replace(script, duration_us=duration)
    if recipe.config.surround.enabled:  # its own stream: the other draws stay as they were
        rng = np.random.default_rng((recipe.seed, index, SURROUND_STREAM))
        script = dataclasses.replace(script, surround=recipe.config.surround.draw(script, rng))
    src = source or cached_source(recipe)
    background = src.draw(duration, size, script.sensor, rng=np.random.default_rng(s_bg))
    return SequenceInputs(index, script, background, s_comp, s_fwd)


@register_kind(
    "flare",
    config_type=FlareConfig,
    validate=_check_recipe,
    identity=_identity,
    file_attrs=_file_attrs,
    file_groups=_file_groups,
    cli_options=(
        "--sequences",
        "--test-sequences",
        "--variant",
        "--weights",
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
    config: FlareConfig = recipe.config
    pair = simulate_pair(
        inputs.script,
        inputs.background,
        recipe.sensor_size,
        variant=config.variant,
        weights=config.weights,
        jitter_us=config.jitter_us,
        independent_background=config.independent_background,
        flare7k=config.flare7k,
        rng=inputs.compose_seed,
        forward_seed=inputs.forward_seed,
        timer=timer,
    )
    streams = pair.streams
    if config.sensing.enabled:
        streams = sparse_sensing(
            streams,
            recipe.sensor_size,
            0,
            config.sensing,
            rng=(recipe.seed, index, SENSING_STREAM),
            t_end_us=recipe.duration_us,
            ghosts=inputs.script.ghosts,
        )
    return KindSequence(
        streams, inputs.script, inputs.background.description, timer.seconds, pair.components
    )
