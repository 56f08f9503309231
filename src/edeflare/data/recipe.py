"""Recipes: what a dataset holds and how it is simulated (:class:`Recipe`, :data:`RECIPES`).

A recipe holds what every dataset kind shares (name, sizes, seed, the
background) and, in ``config``, its kind's own settings (the kind's config
dataclass, :mod:`edeflare.data.kinds`): :class:`~edeflare.data.eflare.FlareConfig`
for training pairs, :class:`~edeflare.sim.optics_scene.OpticsSceneConfig` for
the optics test sets, :class:`~edeflare.data.dsec_flare.DsecFlareConfig` for
DSEC windows. Its dict (:meth:`Recipe.identity`) is each dataset's recorded
identity: manifests and files store it and its digest.

That dict keeps the flat layout recipes had before kinds existed (format 1):
the flare kind's settings sit beside the common ones, another kind's config
under its own key together with the flare kind's defaults. So every dataset
made before the split keeps its digest and resumes (``tests/data/test_recipe.py``
pins them). :meth:`Recipe.from_dict` reads that layout; :meth:`Recipe.replace`
takes the same flat keys.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._registry import Registry
from .._validation import nested_from_dicts
from ..errors import EdeflareError, ParameterError
from ..events import check_sensor_size
from ..sim.background import SceneConfig, relative_names
from ..sim.compose import AccumulationParams
from ..sim.pair import WEIGHTS
from ..sim.script import ScriptConfig
from ..sim.sensing import SensingConfig
from .eflare import FlareConfig
from .kinds import DatasetKind, GenerationError, get_kind, list_kinds
from .sources import make_background_source

__all__ = [
    "KINDS",
    "RECIPES",
    "WEIGHTS",
    "FlareConfig",
    "GenerationError",
    "Recipe",
    "list_recipes",
    "make_background_source",
]

KINDS = ("flare", "optics", "dsec")
"""The built-in dataset kinds (:mod:`edeflare.data.kinds`): simulated training pairs,
optics test pairs, DSEC windows."""

_DEFAULT_KIND = "flare"


@dataclass(frozen=True)
class Recipe:
    """What a dataset holds and how it is simulated.

    Parameters
    ----------
    name : str
        Recorded in the manifest and in every file.
    sequences, test_sequences : int
        Number of sequences; the last ``test_sequences`` indices form the test split.
    duration_us, window_us : int
        Sequence length and training window (a sequence holds ``duration / window`` windows).
    sensor_size : (width, height)
    seed : int
        Dataset seed.
    background : {"synthetic", "recorded"}
    background_files : tuple of str
        Event files for ``background="recorded"``.
    scene : SceneConfig
        Ranges of the synthetic backgrounds.
    accumulation : AccumulationParams
        The background intensity estimator (recorded backgrounds).
    kind : {"flare", "optics", "dsec"}
        See :data:`KINDS`. For ``"optics"`` and ``"dsec"`` every sequence is a
        test sequence (``test_sequences`` follows ``sequences``), and for
        ``"dsec"`` the windows set ``sequences``.
    config : dataclass, optional
        The kind's own settings (default: its config type's defaults):
        :class:`~edeflare.data.eflare.FlareConfig` (variant, weights, flare
        scripts, sparse sensing...), :class:`~edeflare.sim.optics_scene.OpticsSceneConfig`
        or :class:`~edeflare.data.dsec_flare.DsecFlareConfig`.

    Examples
    --------
    >>> r = Recipe.from_dict({"sequences": 4, "test_sequences": 1, "sensor_size": [64, 48]})
    >>> r.split_of(3), r.windows_per_sequence, r.config.variant
    ('test', 5, 'physical')
    >>> r.replace(variant="forward", sequences=6).config.variant
    'forward'
    >>> Recipe.from_dict({"sequencs": 4})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: unknown recipe key(s) ['sequencs']; valid keys: [...]
    """

    name: str = "custom"
    sequences: int = 544
    test_sequences: int = 35
    duration_us: int = 100_000
    window_us: int = 20_000
    sensor_size: tuple[int, int] = (640, 480)
    seed: int = 0
    background: str = "synthetic"
    background_files: tuple[str, ...] = ()
    scene: SceneConfig = field(default_factory=SceneConfig)
    accumulation: AccumulationParams = field(default_factory=AccumulationParams)
    kind: str = _DEFAULT_KIND
    config: Any = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"recipe name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.kind, str) or self.kind not in list_kinds():
            raise ParameterError(f"kind must be one of {tuple(list_kinds())}, got {self.kind!r}")
        kind = get_kind(self.kind)
        if self.config is None:
            object.__setattr__(self, "config", kind.config_type())
        if not isinstance(self.config, kind.config_type):
            raise ParameterError(
                f"a {self.kind!r} recipe's config must be a {kind.config_type.__name__}, "
                f"got {type(self.config).__name__}"
            )
        if kind.count is not None:
            object.__setattr__(self, "sequences", kind.count(self.config))
        if kind.test_only:
            object.__setattr__(self, "test_sequences", self.sequences)
        for key in ("sequences", "test_sequences", "duration_us", "window_us", "seed"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ParameterError(f"{key} must be an int >= 0, got {value!r}")
            object.__setattr__(self, key, int(value))
        if self.sequences < 1:
            raise ParameterError(f"sequences must be >= 1, got {self.sequences}")
        if self.test_sequences > self.sequences:
            raise ParameterError(
                f"test_sequences ({self.test_sequences}) exceeds sequences ({self.sequences})"
            )
        if self.window_us <= 0 or self.duration_us < self.window_us:
            raise ParameterError(
                f"need 0 < window_us <= duration_us, got window_us={self.window_us}, "
                f"duration_us={self.duration_us}"
            )
        try:
            object.__setattr__(self, "sensor_size", check_sensor_size(tuple(self.sensor_size)))
        except (TypeError, EdeflareError):
            raise ParameterError(
                f"sensor_size must be (width, height), got {self.sensor_size!r}"
            ) from None
        if self.background not in ("synthetic", "recorded"):
            raise ParameterError(
                f"background must be 'synthetic' or 'recorded', got {self.background!r}"
            )
        object.__setattr__(self, "background_files", tuple(str(p) for p in self.background_files))
        if self.background == "recorded" and not self.background_files:
            raise ParameterError("background='recorded' needs background_files (event files)")
        for key, config_type in _NESTED.items():
            if not isinstance(getattr(self, key), config_type):
                raise ParameterError(f"{key} must be a {config_type.__name__}")
        if kind.validate is not None:
            kind.validate(self)

    @property
    def windows_per_sequence(self) -> int:
        """Aligned windows per sequence: ``ceil(duration / window)``."""
        return -(-self.duration_us // self.window_us)

    def split_of(self, index: int) -> str:
        """``"train"`` or ``"test"``: the last ``test_sequences`` indices are the test split."""
        return "test" if index >= self.sequences - self.test_sequences else "train"

    def replace(self, **changes: Any) -> Recipe:
        """A copy with ``changes``: common fields, the kind's config, or the config's fields.

        Keys are those of :meth:`to_dict`: a common field (``sequences``,
        ``seed``...), the kind's config key (``optics=``, ``dsec=``: a whole
        config) or one of the config's fields (a flare recipe's ``variant``,
        ``script``...). An unknown key is an error listing the valid ones.

        Examples
        --------
        >>> r = RECIPES["eflare-mini"].replace(seed=3, variant="simple", components=False)
        >>> r.seed, r.config.variant, r.config.components, r.sensor_size
        (3, 'simple', False, (346, 260))
        """
        kind = get_kind(changes.get("kind", self.kind))
        common = {f.name for f in dataclasses.fields(self)} - {"config"}
        own = _config_keys(kind)
        unknown = sorted(set(changes) - common - own - {"config"} - _key_of(kind))
        if unknown:
            raise ParameterError(
                f"unknown recipe key(s) {unknown} for a {kind.name!r} recipe; valid keys: "
                f"{sorted(common | own | _key_of(kind))}"
            )
        config = changes.get("config")
        for key in _key_of(kind):
            if key in changes:
                config = changes[key]
        if config is None:
            config = self.config if isinstance(self.config, kind.config_type) else None
        mine = {k: v for k, v in changes.items() if k in own}
        if mine:
            config = dataclasses.replace(config or kind.config_type(), **mine)
        kept = {k: v for k, v in changes.items() if k in common}
        return dataclasses.replace(self, **kept, config=config)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Recipe:
        """Build from a recipe dict (e.g. a manifest's ``recipe``); unknown keys are an error.

        Another kind's dict holds the flare kind's default settings too (the
        format-1 layout, see the module docstring); they are checked to be the
        defaults and otherwise ignored.
        """
        if not isinstance(data, Mapping):
            raise ParameterError(f"a recipe must be a mapping, got {type(data).__name__}")
        kind_name = data.get("kind", _DEFAULT_KIND)
        if not isinstance(kind_name, str) or kind_name not in list_kinds():
            raise ParameterError(f"kind must be one of {tuple(list_kinds())}, got {kind_name!r}")
        kind = get_kind(kind_name)
        common = {f.name for f in dataclasses.fields(cls)} - {"config"}
        own = _config_keys(kind) | _key_of(kind)
        legacy = _legacy_flare_defaults() if kind.config_field is not None else {}
        unknown = sorted(set(data) - common - own - set(legacy))
        if unknown:
            raise ParameterError(
                f"unknown recipe key(s) {unknown}; valid keys: {sorted(common | own)}"
            )
        for key in set(data) & set(legacy):
            if json.loads(json.dumps(data[key])) != legacy[key]:
                raise ParameterError(
                    f"recipe key {key!r} applies to 'flare' recipes, not to a {kind_name!r} one"
                )
        d = nested_from_dicts({k: v for k, v in data.items() if k in common}, _NESTED)
        if kind.config_field is None:
            raw: Any = {k: v for k, v in data.items() if k in own}
        else:
            raw = data.get(kind.config_field)
        if isinstance(raw, Mapping):
            try:
                raw = kind.config_type.from_dict(raw)
            except EdeflareError as exc:
                where = kind.config_field or kind_name
                raise ParameterError(f"recipe {where!r}: {exc}") from None
        if "sensor_size" in d:
            d["sensor_size"] = tuple(d["sensor_size"])
        if "background_files" in d:
            d["background_files"] = tuple(d["background_files"])
        return cls(**d, config=raw)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict in the format-1 layout (:meth:`from_dict` round-trips it)."""
        d: dict[str, Any] = {
            f.name: _asdict(getattr(self, f.name))
            for f in dataclasses.fields(self)
            if f.name != "config"
        }
        kind = get_kind(self.kind)
        if self.kind == _DEFAULT_KIND:
            del d["kind"]
        if kind.config_field is None:
            d.update(self.config.to_dict())
        else:
            d.update(_legacy_flare_defaults())
            d[kind.config_field] = self.config.to_dict()
        return json.loads(json.dumps(d))

    def identity(self) -> dict[str, Any]:
        """:meth:`to_dict` with input paths reduced to names that do not depend on their place.

        Background files become paths relative to their common folder and the
        kind's own paths (a Flare7K++ folder, a DSEC root) names or nothing,
        so the same data in another place gives the same manifest and
        byte-identical files. This is what manifests record.
        """
        d = self.to_dict()
        d["background_files"] = (
            relative_names(self.background_files) if self.background_files else []
        )
        kind = get_kind(self.kind)
        if kind.identity is not None:
            if kind.config_field is None:
                d.update(kind.identity({k: d[k] for k in self.config.to_dict()}))
            else:
                d[kind.config_field] = kind.identity(d[kind.config_field])
        return d

    def sha256(self) -> str:
        """A digest of :meth:`identity`, stored in every file to detect a changed recipe."""
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


_NESTED: dict[str, type] = {"scene": SceneConfig, "accumulation": AccumulationParams}


def _config_keys(kind: DatasetKind) -> set[str]:
    """The config's own field names when they sit beside the common keys (flat kinds)."""
    if kind.config_field is not None:
        return set()
    return {f.name for f in dataclasses.fields(kind.config_type)}


def _key_of(kind: DatasetKind) -> set[str]:
    return set() if kind.config_field is None else {kind.config_field}


def _legacy_flare_defaults() -> dict[str, Any]:
    """The flare kind's default settings, which format-1 dicts of other kinds carry."""
    return FlareConfig().to_dict()


def _asdict(value: Any) -> Any:
    return dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value


# A slowly moving camera for the optics test sets (E-Flare-R's camera stands still; a
# little motion gives the background events to keep).
_SLOW_STREET = SceneConfig(pan_px_per_s=(10.0, 120.0), zoom_per_s=(0.0, 0.3), shake_px=(0.0, 1.0))

# Calibrated on real recordings (docs/benchmarks.md, "Real against simulated flare"):
# weaker scattered light, more star filters, lights of 3-28 px that travel, sparse and
# slow backgrounds up to busy ones, and the sparse-sensing stage.
_NIGHT_SCRIPT = ScriptConfig(
    exposure=(2.0, 200.0),
    glare_level=(0.3, 6.0),
    ghost_level=(0.3, 4.0),
    star_probability=0.8,
    glare_probability=0.7,
    light_radius_px=(3.0, 28.0),
    travel_px=(0.0, 260.0),
)
_NIGHT_SCENE = SceneConfig(
    pan_px_per_s=(2.0, 250.0),
    texture_contrast=(0.05, 0.4),
    shake_px=(0.0, 1.5),
    zoom_per_s=(0.0, 0.8),
    lamps=(0, 5),
)
_NIGHT_SENSING = SensingConfig(enabled=True, hot_pixels=(0, 8))
_NIGHT_RECIPE = Recipe(
    name="eflare-night",
    sequences=180,
    test_sequences=12,
    sensor_size=(346, 260),
    scene=_NIGHT_SCENE,
    config=FlareConfig(script=_NIGHT_SCRIPT, sensing=_NIGHT_SENSING),
)
# eflare-night-sparse (2026-11-26): the night recipe with the backgrounds as sparse as the
# real recordings' (3-5 events/px/s where they have 0.4-6.7 and eflare-night 18-24:
# "speckle-dense" streets), less background activity, and ghosts bright enough
# to fire over a dark sky, sensed at their own rate wherever they land (the ghost rings
# of ../shared/reference/real_flare_example.png). Closer to real recordings in every
# density statistic (docs/benchmarks.md); a model fine-tuned on it deletes dense real
# scenes, so no bundled model is trained on it (docs/studies.md, "ghosts").
_SPARSE_NIGHT_SCRIPT = dataclasses.replace(_NIGHT_SCRIPT, ghost_level=(1.0, 12.0))
_SPARSE_NIGHT_SCENE = dataclasses.replace(
    _NIGHT_SCENE,
    pan_px_per_s=(2.0, 60.0),
    texture_contrast=(0.03, 0.2),
    shake_px=(0.0, 0.5),
    zoom_per_s=(0.0, 0.2),
)
_SPARSE_NIGHT_SENSING = dataclasses.replace(
    _NIGHT_SENSING, noise_rate=(0.1, 5.0), ghost_survival=(0.03, 0.3)
)

# eflare-day-street (2026-11-25): eflare-night's lights, flare script, sparse sensing and hot
# pixels over a synthetic street lit as by day: bright sky, buildings and road with strong
# texture, 12-43 events per pixel and second to keep (the Prophesee Gen4.1 daytime street
# has 27, the night recipe's streets 1-5). The `night` model's training data mixes it with
# eflare-night, so that density alone does not read as light.
_DAY_SCENE = SceneConfig(
    sky_level=(80.0, 200.0),
    building_level=(60.0, 200.0),
    road_level=(50.0, 150.0),
    marking_level=(120.0, 230.0),
    window_level=(80.0, 230.0),
    texture_contrast=(0.1, 0.35),
    pan_px_per_s=(20.0, 200.0),
    zoom_per_s=(0.0, 0.8),
    lamps=(0, 2),
)

RECIPES: Registry[Recipe] = Registry("recipe")
for _recipe in (
    Recipe(name="eflare-2.7k"),
    Recipe(name="eflare-mini", sequences=120, test_sequences=12, sensor_size=(346, 260)),
    Recipe(
        name="eflare-r-sim", kind="optics", sequences=30, sensor_size=(640, 480), scene=_SLOW_STREET
    ),
    Recipe(
        name="eflare-r-sim-mini",
        kind="optics",
        sequences=20,
        sensor_size=(346, 260),
        scene=_SLOW_STREET,
    ),
    Recipe(name="dsec-flare", kind="dsec", sensor_size=(640, 480)),
    _NIGHT_RECIPE,
    dataclasses.replace(
        _NIGHT_RECIPE,
        name="eflare-night-sparse",
        scene=_SPARSE_NIGHT_SCENE,
        config=FlareConfig(script=_SPARSE_NIGHT_SCRIPT, sensing=_SPARSE_NIGHT_SENSING),
    ),
    dataclasses.replace(
        _NIGHT_RECIPE,
        name="eflare-day-street",
        sequences=72,
        test_sequences=6,
        scene=_DAY_SCENE,
        seed=101,
    ),
):
    RECIPES.register(_recipe.name, _recipe)
"""Named recipes: the paper's E-Flare-2.7K (synthetic backgrounds unless files are given),
and a small one (120 sequences of 100 ms at 346x260: 540 training and 60 test windows);
the optics test sets after E-Flare-R's physical model, ``eflare-r-sim`` (30 sequences of
100 ms at 640x480, the paper's crop: 150 test windows, as E-Flare-R's 150 pairs) and
``eflare-r-sim-mini`` (20 at 346x260: 100 test windows); and ``dsec-flare``, the paper's
DSEC-Flare windows (15 of 100 ms at 640x480 by default) cut from a local DSEC copy
(``recipe.replace(dsec=DsecFlareConfig(root=...))``), without ground truth; and
``eflare-night`` (180 of 100 ms at 346x260), the simulator calibrated on real night
recordings: weaker scattered light, travelling lights of 3-28 px, and the sparse-sensing stage
(:mod:`edeflare.sim.sensing`, with up to 8 hot pixels to remove), whose ``gt`` is a keep-only
target; ``eflare-night-sparse`` (180 of 100 ms at 346x260), the same with sparse
backgrounds and ghosts sensed at their own rate; and ``eflare-day-street`` (72 of 100 ms at
346x260, 6 of them test, dataset seed 101), eflare-night's lights, flare and sensing over a
street lit as by day (12-43 events per pixel and second to keep), the day half of the
``night`` model's training data."""


def list_recipes() -> list[str]:
    """Names of :data:`RECIPES`.

    Examples
    --------
    >>> list_recipes()  # doctest: +NORMALIZE_WHITESPACE
    ['dsec-flare', 'eflare-2.7k', 'eflare-day-street', 'eflare-mini', 'eflare-night',
     'eflare-night-sparse', 'eflare-r-sim', 'eflare-r-sim-mini']
    """
    return RECIPES.names()
