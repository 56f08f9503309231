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

A :class:`Mix` is a recipe whose parts are recipes (``eflare-mix``): each part is
generated as a dataset of its own in a folder named after it, and training reads
the mix's folder as its parts'.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
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
from ..sim.surround import SurroundConfig
from .eflare import FlareConfig
from .kinds import DatasetKind, GenerationError, get_kind, list_kinds
from .sources import make_background_source

__all__ = [
    "KINDS",
    "RECIPES",
    "WEIGHTS",
    "FlareConfig",
    "GenerationError",
    "Mix",
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
    if isinstance(value, SceneConfig):  # its own form: no near_* fields where it has none
        return value.to_dict()
    return dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value


_PART_NAME = re.compile(r"^[a-z0-9][a-z0-9._-]*$")
_RESERVED_PARTS = ("train", "test")


@dataclass(frozen=True)
class Mix:
    """A dataset of datasets: named parts, each an ordinary :class:`Recipe`.

    :func:`~edeflare.data.generate.generate_dataset` builds part ``p`` into
    ``OUT/<p>/`` as a dataset of its own (its ``train/``, ``test/`` and
    ``manifest.json``) and writes ``OUT/manifest.json``, which lists the
    parts, their recipes' digests and their manifests' digests. Training
    reads a mix folder as its parts' folders in the mix's order
    (:func:`edeflare.data.folders.dataset_folders`).

    The mix's order is every part's sequences in turn: sequence ``i`` of the
    ``k``-th part is item ``offset_k + i``, where ``offset_k`` counts the
    sequences of the parts before it; ``shard="i/n"`` makes the items whose
    position has ``position % n == i``.

    Parameters
    ----------
    name : str
    parts : tuple of (str, Recipe)
        Part names (folder names: lower-case letters, digits, ``.``, ``_``,
        ``-``; not ``train`` or ``test``) and their recipes, in order.

    Examples
    --------
    >>> m = Mix("pair", (("a", Recipe(sequences=3, test_sequences=1)),
    ...                  ("b", Recipe(sequences=2, test_sequences=1, seed=1))))
    >>> m.sequences, m.part_names, m.shard_of("b", (1, 2))
    (5, ('a', 'b'), (0, 2))
    >>> m.replace(sequences=2).sequences
    4
    >>> Mix("x", (("a", Recipe()), ("a", Recipe(seed=1))))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: mix 'x': part names must be unique, got ['a', 'a']
    """

    name: str
    parts: tuple[tuple[str, Recipe], ...]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"mix name must be a non-empty string, got {self.name!r}")
        try:
            parts = tuple((str(n), r) for n, r in self.parts)
        except (TypeError, ValueError):
            raise ParameterError(
                f"mix {self.name!r}: parts must be (name, Recipe) pairs, got {self.parts!r}"
            ) from None
        if not parts:
            raise ParameterError(f"mix {self.name!r} needs at least one part")
        names = [n for n, _ in parts]
        if len(set(names)) != len(names):
            raise ParameterError(f"mix {self.name!r}: part names must be unique, got {names}")
        for part, recipe in parts:
            if not _PART_NAME.match(part) or part in _RESERVED_PARTS:
                raise ParameterError(
                    f"mix {self.name!r}: part name {part!r} must be a folder name of lower-case "
                    f"letters, digits, '.', '_' and '-', not one of {_RESERVED_PARTS}"
                )
            if not isinstance(recipe, Recipe):
                raise ParameterError(
                    f"mix {self.name!r}: part {part!r} must be a Recipe, got "
                    f"{type(recipe).__name__}"
                )
        object.__setattr__(self, "parts", parts)

    @property
    def part_names(self) -> tuple[str, ...]:
        """The parts' names, in the mix's order."""
        return tuple(n for n, _ in self.parts)

    @property
    def sequences(self) -> int:
        """Sequences of every part together."""
        return sum(r.sequences for _, r in self.parts)

    def part(self, name: str) -> Recipe:
        """The recipe of part ``name`` (an unknown name lists the parts)."""
        for part, recipe in self.parts:
            if part == name:
                return recipe
        raise ParameterError(
            f"mix {self.name!r} has no part {name!r}; parts: {', '.join(self.part_names)}"
        )

    def offset(self, name: str) -> int:
        """Position of part ``name``'s first sequence in the mix's order."""
        self.part(name)
        total = 0
        for part, recipe in self.parts:
            if part == name:
                return total
            total += recipe.sequences
        raise AssertionError("unreachable")  # pragma: no cover

    def shard_of(self, name: str, shard: tuple[int, int]) -> tuple[int, int]:
        """Part ``name``'s own shard ``(j, n)`` for the mix's shard ``(i, n)``: its
        sequences ``k`` with ``(offset + k) % n == i`` are those with ``k % n == j``."""
        i, n = shard
        return (i - self.offset(name)) % n, n

    def replace(self, **changes: Any) -> Mix:
        """A copy with ``changes`` made to every part (:meth:`Recipe.replace`'s keys).

        ``name=`` renames the mix instead (its parts keep their recipes' names).
        """
        name = changes.pop("name", self.name)
        return Mix(name, tuple((p, r.replace(**changes) if changes else r) for p, r in self.parts))

    def identity(self) -> dict[str, Any]:
        """The mix's name and, per part, its name and its recipe's digest."""
        return {
            "name": self.name,
            "parts": [{"name": p, "recipe_sha256": r.sha256()} for p, r in self.parts],
        }

    def sha256(self) -> str:
        """A digest of :meth:`identity`: a mix's manifest records it."""
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


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

# Dense flare: strong sources (headlights, near street lamps) through the full forward model
# (variant "forward": I_bg + I_f through one simulated sensor, Eq. 5-6), for eflare-mix's
# dense parts and the eflare-forward test sets. What `exposure` means against the background:
# the light's radiance is R = exposure * peak on the 8-bit scale (sim/render.py), peak ~
# U(180, 255) (mean 217); its flare is R * (disc * PSF) + glare, clipped at peak, added to
# the background frame. The night street (_NIGHT_SCENE) has a median level B of about 17
# (medians of 20 draws at 640x480: quartiles 13-20). So a source is S = R / B ~ 12.8 *
# exposure times the background, and exposure log-uniform in (2.5, 8000) spans S from about
# 10^1.5 to 10^5 (within a factor of 2 either way, from peak and B). A pixel fires where the
# flare adds about a fifth of B (log contrast ~0.2), i.e. where disc * PSF > 0.2 / S: at
# S = 10^5 the diffraction spikes, blade streaks and scattered halo fill hundreds of pixels,
# saturated near the source. Glare and ghost levels are absolute (8-bit scale), raised over
# the paper's so that they stand out of a lit street; star filters (spikes), polygonal
# apertures (blade streaks), ghosts and glare are common. The PSF grid (512) bounds the
# flare template: full strength to about 215-240 px from the source, gone by 265-300 px.
_DENSE_SCRIPT = ScriptConfig(
    exposure=(2.5, 8000.0),
    light_radius_px=(2.0, 10.0),
    star_probability=0.7,
    blade_probability=0.6,
    glare_probability=0.8,
    glare_level=(5.0, 120.0),
    ghost_probability=0.95,
    ghost_level=(2.0, 40.0),
)
# The same at 1280x720: pixel ranges x1.5 (the height's ratio; lights, travel, ghosts, the
# camera's pan and shake) and a PSF grid of 576, whose template keeps full strength to about
# 240-280 px from the source (halo, spikes and glare reach ~250 px) and is gone by 300-350 px.
_HD = 1.5
_DENSE_HD_SCRIPT = dataclasses.replace(
    _DENSE_SCRIPT,
    light_radius_px=(2.0 * _HD, 10.0 * _HD),
    travel_px=(0.0, 180.0 * _HD),
    ghost_radius_px=(4.0 * _HD, 50.0 * _HD),
    psf_grid=576,
)
_NIGHT_SCENE_HD = dataclasses.replace(
    _NIGHT_SCENE, pan_px_per_s=(2.0 * _HD, 250.0 * _HD), shake_px=(0.0, 1.5 * _HD)
)
# eflare-night's lights and sensing at 1280x720 (sparse scattered flare of weak or distant
# sources), its pixel ranges x1.5.
_NIGHT_HD_SCRIPT = dataclasses.replace(
    _NIGHT_SCRIPT,
    light_radius_px=(3.0 * _HD, 28.0 * _HD),
    travel_px=(0.0, 260.0 * _HD),
    ghost_radius_px=(4.0 * _HD, 50.0 * _HD),
)
_FORWARD = FlareConfig(variant="forward", script=_DENSE_SCRIPT)
_FORWARD_HD = FlareConfig(variant="forward", script=_DENSE_HD_SCRIPT)

# eflare-mix: dense and sparse flare over night and day streets at three sensor sizes, for a
# de-flarer that must handle both. One-sequence times, one at a time on one core of a 2-core
# machine (100 ms sequences, simulated and written): night-346 about 4 s, day-346 4.5 s,
# dense-640 14 s, dense-1280 35 s, sparse-1280 23 s. The counts below sum to about 1,300
# core-seconds: about 11 minutes with --workers 2 on two idle cores, about 15 allowing for
# the workers slowing each other down (and a busy machine takes longer). Every part has test
# sequences (validation) and its own seed; the forward parts and sparse-1280 store input and
# gt only (no components), to keep the 1280x720 files small (about 1.5 GB in all, estimated
# from the files written while timing).
_MIX_PARTS = (
    (
        "night-346",
        dataclasses.replace(
            _NIGHT_RECIPE, name="eflare-mix.night-346", sequences=60, test_sequences=6, seed=201
        ),
    ),
    (
        "day-346",
        dataclasses.replace(
            _NIGHT_RECIPE,
            name="eflare-mix.day-346",
            sequences=20,
            test_sequences=2,
            scene=_DAY_SCENE,
            seed=202,
        ),
    ),
    (
        "dense-640",
        Recipe(
            name="eflare-mix.dense-640",
            sequences=28,
            test_sequences=3,
            sensor_size=(640, 480),
            seed=203,
            scene=_NIGHT_SCENE,
            config=dataclasses.replace(_FORWARD, components=False),
        ),
    ),
    (
        "dense-1280",
        Recipe(
            name="eflare-mix.dense-1280",
            sequences=10,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=204,
            scene=_NIGHT_SCENE_HD,
            config=dataclasses.replace(_FORWARD_HD, components=False),
        ),
    ),
    (
        "sparse-1280",
        Recipe(
            name="eflare-mix.sparse-1280",
            sequences=10,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=205,
            scene=_NIGHT_SCENE_HD,
            config=FlareConfig(script=_NIGHT_HD_SCRIPT, sensing=_NIGHT_SENSING, components=False),
        ),
    ),
)

# eflare-gaps: what eflare-mix lacks, to train beside it (`edeflare train-head MIX GAPS`):
# dense flare at 640x480 with the scene alone stored (eflare-mix's dense parts store input
# and gt only, so no scene-alone windows of that size), and eflare-night-sparse's dim
# night streets (backgrounds as sparse as the real recordings', with their background
# activity), the scene alone stored too. Seeds no other recipe uses.
_GAPS_PARTS = (
    (
        "dense-640",
        dataclasses.replace(
            dict(_MIX_PARTS)["dense-640"],
            name="eflare-gaps.dense-640",
            sequences=30,
            test_sequences=3,
            seed=206,
            config=_FORWARD,
        ),
    ),
    (
        "sparse-346",
        dataclasses.replace(
            _NIGHT_RECIPE,
            name="eflare-gaps.sparse-346",
            sequences=30,
            test_sequences=3,
            seed=207,
            scene=_SPARSE_NIGHT_SCENE,
            config=FlareConfig(script=_SPARSE_NIGHT_SCRIPT, sensing=_SPARSE_NIGHT_SENSING),
        ),
    ),
)

# eflare-day: eflare-mix's day street at the larger sensor sizes, where eflare-mix has night
# streets only: eflare-night's weak lights and sensing (sparse flare) and the forward model's
# strong sources (dense flare) over a street lit as by day, at 640x480 and 1280x720, each
# storing the scene alone (a dense day scene without a light, every event kept). Pixel
# ranges x1.5 at 1280x720 as for eflare-mix. Seeds no other recipe uses. 543 s for the
# first four parts' 50 sequences with --workers 2 on a 2-core machine (about 2 GB).
_DAY_SCENE_HD = dataclasses.replace(
    _DAY_SCENE, pan_px_per_s=(20.0 * _HD, 200.0 * _HD), shake_px=(0.0, 1.5 * _HD)
)
# Driving: the day street seen from a car moving forward, the expansion about the focus
# 1-3 per second (eflare-day-street's streets expand at most 0.8 per second), so that a
# large radial flow without a light is seen as scene. A point 400 px from the focus moves
# 400-1,200 px/s, so a dense fan of streaks radiates from the focus as from a light. Its
# texture is fainter: eflare-day-street's contrast at this speed fired about 140 events per
# pixel and second in a 640x480 trial; with this, 27-142 (the first eight training
# sequences of each size), as many as the still day streets (day-640: 15-143).
_DRIVE_SCENE = dataclasses.replace(
    _DAY_SCENE, zoom_per_s=(1.0, 3.0), pan_px_per_s=(0.0, 80.0), texture_contrast=(0.05, 0.2)
)
_DRIVE_SCENE_HD = dataclasses.replace(
    _DRIVE_SCENE, pan_px_per_s=(0.0, 80.0 * _HD), shake_px=(0.0, 1.5 * _HD)
)
_DAY_PARTS = (
    (
        "day-640",
        dataclasses.replace(
            _NIGHT_RECIPE,
            name="eflare-day.day-640",
            sequences=18,
            test_sequences=2,
            sensor_size=(640, 480),
            scene=_DAY_SCENE,
            seed=208,
        ),
    ),
    (
        "day-1280",
        Recipe(
            name="eflare-day.day-1280",
            sequences=9,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=209,
            scene=_DAY_SCENE_HD,
            config=FlareConfig(script=_NIGHT_HD_SCRIPT, sensing=_NIGHT_SENSING),
        ),
    ),
    (
        "dense-day-640",
        Recipe(
            name="eflare-day.dense-day-640",
            sequences=16,
            test_sequences=2,
            sensor_size=(640, 480),
            seed=210,
            scene=_DAY_SCENE,
            config=_FORWARD,
        ),
    ),
    (
        "dense-day-1280",
        Recipe(
            name="eflare-day.dense-day-1280",
            sequences=7,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=211,
            scene=_DAY_SCENE_HD,
            config=_FORWARD_HD,
        ),
    ),
    (
        "drive-640",
        Recipe(
            name="eflare-day.drive-640",
            sequences=14,
            test_sequences=2,
            sensor_size=(640, 480),
            seed=214,
            scene=_DRIVE_SCENE,
            config=_FORWARD,
        ),
    ),
    (
        "drive-1280",
        Recipe(
            name="eflare-day.drive-1280",
            sequences=8,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=215,
            scene=_DRIVE_SCENE_HD,
            config=FlareConfig(script=_NIGHT_HD_SCRIPT, sensing=_NIGHT_SENSING),
        ),
    ),
)

# eflare-train: every part a learned de-flarer with a context was trained on, in one
# recipe: eflare-mix's five parts and eflare-day's six (the same recipes, so their folders
# are byte for byte those mixes' parts), and fast-640: eflare-mix's dense flare at 640x480
# with lights of 2-40 px radius travelling up to 1,200 px in a sequence (eflare-mix's:
# 2-10 px, 180 px), the scene alone stored. Those ranges were chosen after seeing a real
# light (36 px, 13 px per ms) fail. 218 sequences; about 30 minutes with --workers 2 on 2
# cores (the parts' times above; fast-640 about 3).
_FAST_PART = dataclasses.replace(
    dict(_MIX_PARTS)["dense-640"],
    name="eflare-train.fast-640",
    sequences=18,
    test_sequences=2,
    seed=212,
    config=dataclasses.replace(
        _FORWARD,
        script=dataclasses.replace(
            _DENSE_SCRIPT, light_radius_px=(2.0, 40.0), travel_px=(0.0, 1200.0)
        ),
    ),
)
_TRAIN_PARTS = (*_MIX_PARTS, *_DAY_PARTS, ("fast-640", _FAST_PART))

# eflare-lit: lamps that light the scene around them (edeflare.sim.surround), the forward
# model's dense flare over night streets at 346x260 and 640x480, every sequence's lamp lighting
# its surroundings (its illuminance at its foot 0.5-20 times the ambient, its distance from
# them 1-3 light radii: the author's ranges, fitted to no recording); where the lamp flickers
# (70 % of scripts, 100-140 Hz), its lit texture fires at each half period as flare. Sources
# 2.5-250 times the street (eflare-mix's dense parts: up to 8,000), as a stronger source's
# own flare covers the frame and hides its lit surroundings (seen in the first sequences
# drawn). The scene alone stored. Seeds no other recipe uses. 282 s with --workers 2 on 2 cores.
_LIT = dataclasses.replace(
    _FORWARD,
    script=dataclasses.replace(_DENSE_SCRIPT, exposure=(2.5, 250.0)),
    surround=SurroundConfig(probability=1.0),
)
_LIT_PARTS = (
    (
        "lit-346",
        Recipe(
            name="eflare-lit.lit-346",
            sequences=24,
            test_sequences=3,
            sensor_size=(346, 260),
            seed=216,
            scene=_NIGHT_SCENE,
            config=_LIT,
        ),
    ),
    (
        "lit-640",
        Recipe(
            name="eflare-lit.lit-640",
            sequences=16,
            test_sequences=2,
            sensor_size=(640, 480),
            seed=217,
            scene=_NIGHT_SCENE,
            config=_LIT,
        ),
    ),
)

# eflare-near: large textured objects close to the camera (edeflare.sim.background.NearObject:
# a head, a hand, a passer-by, 0.3-0.8 of the frame's height), swinging at up to 300-3,000 px/s
# (x1.5 at 1280x720) before day and night streets, under the forward model's dense flare and
# eflare-night's sparse flare, the scene alone stored: a large, dense, compact patch of events
# that moves fast and is no light, which eflare-train lacks. The ranges were chosen after a
# real face turning fast before the camera was seen deleted (benchmarks/unseen_scenes.py),
# so that face is no evidence for them. Seeds no other recipe uses. 348 s with --workers 2 on
# 2 cores.
_NEAR = {"near_objects": (1, 2)}
_NEAR_HD = {**_NEAR, "near_speed_px_per_s": (300.0 * _HD, 3000.0 * _HD)}
_NEAR_PARTS = (
    (
        "near-346",
        dataclasses.replace(
            _NIGHT_RECIPE,
            name="eflare-near.near-346",
            sequences=16,
            test_sequences=2,
            seed=218,
            scene=dataclasses.replace(_NIGHT_SCENE, **_NEAR),
        ),
    ),
    (
        "near-640",
        Recipe(
            name="eflare-near.near-640",
            sequences=16,
            test_sequences=2,
            sensor_size=(640, 480),
            seed=219,
            scene=dataclasses.replace(_DAY_SCENE, **_NEAR),
            config=_FORWARD,
        ),
    ),
    (
        "near-night-640",
        Recipe(
            name="eflare-near.near-night-640",
            sequences=10,
            test_sequences=1,
            sensor_size=(640, 480),
            seed=220,
            scene=dataclasses.replace(_NIGHT_SCENE, **_NEAR),
            config=_FORWARD,
        ),
    ),
    (
        "near-1280",
        Recipe(
            name="eflare-near.near-1280",
            sequences=7,
            test_sequences=1,
            sensor_size=(1280, 720),
            seed=221,
            scene=dataclasses.replace(_DAY_SCENE_HD, **_NEAR_HD),
            config=_FORWARD_HD,
        ),
    ),
)

RECIPES: Registry[Recipe | Mix] = Registry("recipe")
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
    # Test sets of the full forward model (every sequence in test/, seeds no training
    # recipe uses): dense flare over night streets, with ground truth.
    Recipe(
        name="eflare-forward",
        sequences=12,
        test_sequences=12,
        sensor_size=(640, 480),
        seed=301,
        scene=_NIGHT_SCENE,
        config=_FORWARD,
    ),
    Recipe(
        name="eflare-forward-hd",
        sequences=4,
        test_sequences=4,
        sensor_size=(1280, 720),
        seed=302,
        scene=_NIGHT_SCENE_HD,
        config=_FORWARD_HD,
    ),
    Mix("eflare-mix", _MIX_PARTS),
    Mix("eflare-gaps", _GAPS_PARTS),
    Mix("eflare-day", _DAY_PARTS),
    Mix("eflare-train", _TRAIN_PARTS),
    Mix("eflare-lit", _LIT_PARTS),
    Mix("eflare-near", _NEAR_PARTS),
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
``night`` model's training data; the test sets of the full forward model, ``eflare-forward``
(12 of 100 ms at 640x480) and ``eflare-forward-hd`` (4 at 1280x720): dense flare (star
filters, aperture blades, glare, ghosts; sources 10^1.5-10^5 times the street) over night
streets, all test; and the :class:`Mix` ``eflare-mix``, training data for dense and sparse
flare in five parts: ``night-346`` (eflare-night, 60), ``day-346`` (eflare-day-street, 20),
``dense-640`` (the forward model's dense flare, 28 at 640x480), ``dense-1280`` (the same at
1280x720, 10) and ``sparse-1280`` (eflare-night at 1280x720, 10), each with test
sequences and its own seed: about 1,300 core-seconds, 11-15 minutes with ``--workers 2``
on 2 cores (the one-sequence times are in the comment above ``_MIX_PARTS``); and the
:class:`Mix` ``eflare-gaps``, to train beside it: ``dense-640`` (30, the scene alone stored)
and ``sparse-346`` (eflare-night-sparse, 30); and the :class:`Mix` ``eflare-day``, day
streets at the larger sensors: ``day-640`` and ``day-1280`` (eflare-night's weak lights, 18
and 9), ``dense-day-640`` and ``dense-day-1280`` (the forward model's strong sources, 16
and 7), ``drive-640`` and ``drive-1280`` (the street seen from a car driving forward, under
strong sources, 14, and weak lights, 8), the scene alone stored in each; and the
:class:`Mix` ``eflare-train``, all of those parts of ``eflare-mix`` and ``eflare-day`` and
``fast-640`` (large, fast lights over night streets, 18), for a de-flarer with a context;
and the :class:`Mix` ``eflare-lit``, lamps that light the scene around them, flickering
(:mod:`edeflare.sim.surround`): ``lit-346`` (24) and ``lit-640`` (16), the forward model's
flare of sources 2.5-250 times the street over night streets, the scene alone stored; and the
:class:`Mix` ``eflare-near``, large textured objects swinging fast close to the camera
(:class:`~edeflare.sim.background.NearObject`) before night and day streets: ``near-346``
(eflare-night's sparse flare, 16), ``near-640`` and ``near-night-640`` (the forward model's
dense flare over day and night streets, 16 and 10) and ``near-1280`` (7), the scene alone
stored."""


def list_recipes() -> list[str]:
    """Names of :data:`RECIPES` (recipes and mixes).

    Examples
    --------
    >>> list_recipes()  # doctest: +NORMALIZE_WHITESPACE
    ['dsec-flare', 'eflare-2.7k', 'eflare-day', 'eflare-day-street', 'eflare-forward',
     'eflare-forward-hd', 'eflare-gaps', 'eflare-lit', 'eflare-mini', 'eflare-mix',
     'eflare-near', 'eflare-night', 'eflare-night-sparse', 'eflare-r-sim',
     'eflare-r-sim-mini', 'eflare-train']
    """
    return RECIPES.names()
