"""Recipes: what a dataset holds and how it is simulated (:class:`Recipe`, :data:`RECIPES`).

A recipe is one flat, frozen record: the fields every kind shares (name,
sizes, seed, background), the composition fields of the training kind and
one config field per other kind (``optics``, ``dsec``). Its dict
(:meth:`Recipe.identity`) is each dataset's recorded identity: manifests and
files store it and its digest. What a sequence *is* belongs to its kind
(:mod:`edeflare.data.kinds`): the kind validates and serialises its own
config and makes the sequences.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._registry import Registry
from ..errors import EdeflareError, ParameterError
from ..events import check_sensor_size
from ..sim.background import SceneConfig, relative_names
from ..sim.compose import AccumulationParams
from ..sim.optics_scene import OpticsSceneConfig
from ..sim.pair import PAIR_VARIANTS, WEIGHTS
from ..sim.script import ScriptConfig
from ..sim.sensing import SensingConfig
from .dsec_flare import DsecFlareConfig
from .kinds import GenerationError, get_kind, list_kinds
from .sources import make_background_source

__all__ = [
    "KINDS",
    "RECIPES",
    "WEIGHTS",
    "GenerationError",
    "Recipe",
    "list_recipes",
    "make_background_source",
]

KINDS = ("flare", "optics", "dsec")
"""The built-in dataset kinds (:mod:`edeflare.data.kinds`): simulated training pairs,
optics test pairs, DSEC windows."""


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
    variant : str
        ``"physical"`` (PNL-ES), ``"simple"``, ``"simple+random"``,
        ``"physical+random"``, ``"no-light"`` or ``"forward"`` (full forward
        model; synthetic backgrounds only).
    background : {"synthetic", "recorded"}
    background_files : tuple of str
        Event files for ``background="recorded"``.
    weights : {"intensity", "accumulation", "counts"}
        Where PNL-ES intensities come from (see :data:`WEIGHTS`).
    jitter_us : float
        Half-width of the ``+random`` variants' jitter.
    independent_background : bool
        Thin the background separately for input and ground truth.
    components : bool
        Store the pure flare, light and background streams too.
    seed : int
        Dataset seed.
    flare7k : str, optional
        A Flare7K++ folder; scripts then use its image pairs.
    script : ScriptConfig
        Ranges of the flare scripts (the duration is the recipe's).
    scene : SceneConfig
        Ranges of the synthetic backgrounds.
    accumulation : AccumulationParams
        The background intensity estimator (recorded backgrounds).
    kind : {"flare", "optics", "dsec"}
        See :data:`KINDS`. For ``"optics"`` and ``"dsec"`` every sequence is a
        test sequence (``test_sequences`` follows ``sequences``), and for
        ``"dsec"`` the windows set ``sequences``.
    optics : OpticsSceneConfig
        Ranges of the optics scenes (kind ``"optics"``).
    dsec : DsecFlareConfig
        DSEC folder and windows (kind ``"dsec"``).
    sensing : SensingConfig
        The sparse-sensing stage (:mod:`edeflare.sim.sensing`; kind ``"flare"``,
        off unless ``enabled``): scattered light sensed as scattered events, the
        keep-only target ``gt`` and the simulator's own as ``gt_full``.

    Examples
    --------
    >>> r = Recipe.from_dict({"sequences": 4, "test_sequences": 1, "sensor_size": [64, 48]})
    >>> r.split_of(3), r.windows_per_sequence
    ('test', 5)
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
    variant: str = "physical"
    background: str = "synthetic"
    background_files: tuple[str, ...] = ()
    weights: str = "intensity"
    jitter_us: float = 1000.0
    independent_background: bool = False
    components: bool = True
    seed: int = 0
    flare7k: str | None = None
    script: ScriptConfig = field(default_factory=ScriptConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    accumulation: AccumulationParams = field(default_factory=AccumulationParams)
    kind: str = "flare"
    optics: OpticsSceneConfig = field(default_factory=OpticsSceneConfig)
    dsec: DsecFlareConfig = field(default_factory=DsecFlareConfig)
    sensing: SensingConfig = field(default_factory=SensingConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"recipe name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.kind, str) or self.kind not in list_kinds():
            raise ParameterError(f"kind must be one of {tuple(list_kinds())}, got {self.kind!r}")
        kind = get_kind(self.kind)
        own = getattr(self, kind.config_field) if kind.config_field else None
        if kind.count is not None and isinstance(own, kind.config_type):
            object.__setattr__(self, "sequences", kind.count(own))
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
        if self.variant not in PAIR_VARIANTS:
            raise ParameterError(f"variant must be one of {PAIR_VARIANTS}, got {self.variant!r}")
        if self.background not in ("synthetic", "recorded"):
            raise ParameterError(
                f"background must be 'synthetic' or 'recorded', got {self.background!r}"
            )
        object.__setattr__(self, "background_files", tuple(str(p) for p in self.background_files))
        if self.background == "recorded" and not self.background_files:
            raise ParameterError("background='recorded' needs background_files (event files)")
        if self.weights not in WEIGHTS:
            raise ParameterError(f"weights must be one of {WEIGHTS}, got {self.weights!r}")
        if self.variant == "forward" and self.background != "synthetic":
            raise ParameterError(
                "variant='forward' simulates I_bg + I_f and needs the background as a video: "
                "use background='synthetic'"
            )
        if not (math.isfinite(float(self.jitter_us)) and self.jitter_us >= 0):
            raise ParameterError(f"jitter_us must be >= 0, got {self.jitter_us!r}")
        for key, config_type in _nested().items():
            if not isinstance(getattr(self, key), config_type):
                raise ParameterError(f"{key} must be a {config_type.__name__}")

    @property
    def windows_per_sequence(self) -> int:
        """Aligned windows per sequence: ``ceil(duration / window)``."""
        return -(-self.duration_us // self.window_us)

    def split_of(self, index: int) -> str:
        """``"train"`` or ``"test"``: the last ``test_sequences`` indices are the test split."""
        return "test" if index >= self.sequences - self.test_sequences else "train"

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Recipe:
        """Build from a mapping (e.g. a manifest's ``recipe``); unknown keys are an error."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"a recipe must be a mapping, got {type(data).__name__}")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ParameterError(f"unknown recipe key(s) {unknown}; valid keys: {sorted(names)}")
        d = dict(data)
        for key, config_type in _nested().items():
            if key in d and isinstance(d[key], Mapping):
                try:
                    d[key] = config_type.from_dict(d[key])
                except EdeflareError as exc:
                    raise ParameterError(f"recipe {key!r}: {exc}") from None
        if "sensor_size" in d:
            d["sensor_size"] = tuple(d["sensor_size"])
        if "background_files" in d:
            d["background_files"] = tuple(d["background_files"])
        return cls(**d)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (:meth:`from_dict` round-trips it).

        Settings of the other kinds are left out (so flare recipes keep the
        dicts and digests they had before kinds existed).
        """
        d = {f.name: _asdict(getattr(self, f.name)) for f in dataclasses.fields(self)}
        for name in list_kinds():
            kind = get_kind(name)
            if kind.config_field is None:
                continue
            if name == self.kind:
                d[kind.config_field] = getattr(self, kind.config_field).to_dict()
            else:
                del d[kind.config_field]
        if self.kind == _DEFAULT_KIND:
            del d["kind"]
        if self.sensing.enabled:
            d["sensing"] = self.sensing.to_dict()
        else:  # off: recipes keep the dicts and digests they had before the stage existed
            del d["sensing"]
        return json.loads(json.dumps(d))

    def identity(self) -> dict[str, Any]:
        """:meth:`to_dict` with input paths reduced to names that do not depend on their place.

        Background files become paths relative to their common folder and the
        Flare7K++ folder its name, so the same data in another place gives the
        same manifest and byte-identical files. This is what manifests record.
        """
        d = self.to_dict()
        d["background_files"] = (
            relative_names(self.background_files) if self.background_files else []
        )
        d["flare7k"] = None if self.flare7k is None else Path(self.flare7k).name
        kind = get_kind(self.kind)
        if kind.identity is not None and kind.config_field is not None:
            d[kind.config_field] = kind.identity(d[kind.config_field])
        return d

    def sha256(self) -> str:
        """A digest of :meth:`identity`, stored in every file to detect a changed recipe."""
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


_DEFAULT_KIND = "flare"


def _nested() -> dict[str, type]:
    """Recipe fields holding config dataclasses, and their types."""
    out: dict[str, type] = {
        "script": ScriptConfig,
        "scene": SceneConfig,
        "accumulation": AccumulationParams,
        "sensing": SensingConfig,
    }
    for name in list_kinds():
        kind = get_kind(name)
        if kind.config_field is not None and kind.config_type is not None:
            out[kind.config_field] = kind.config_type
    return out


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
    Recipe(
        name="eflare-night",
        sequences=180,
        test_sequences=12,
        sensor_size=(346, 260),
        script=_NIGHT_SCRIPT,
        scene=_NIGHT_SCENE,
        sensing=SensingConfig(enabled=True),
    ),
):
    RECIPES.register(_recipe.name, _recipe)
"""Named recipes: the paper's E-Flare-2.7K (synthetic backgrounds unless files are given),
and a small one (120 sequences of 100 ms at 346x260: 540 training and 60 test windows);
the optics test sets after E-Flare-R's physical model, ``eflare-r-sim`` (30 sequences of
100 ms at 640x480, the paper's crop: 150 test windows, as E-Flare-R's 150 pairs) and
``eflare-r-sim-mini`` (20 at 346x260: 100 test windows); and ``dsec-flare``, the paper's
DSEC-Flare windows (15 of 100 ms at 640x480 by default) cut from a local DSEC copy
(``dsec=DsecFlareConfig(root=...)``), without ground truth; and ``eflare-night`` (180 of
100 ms at 346x260), the simulator calibrated on real night recordings: weaker scattered
light, travelling lights of 3-28 px, and the sparse-sensing stage
(:mod:`edeflare.sim.sensing`), whose ``gt`` is a keep-only target."""


def list_recipes() -> list[str]:
    """Names of :data:`RECIPES`.

    Examples
    --------
    >>> list_recipes()  # doctest: +NORMALIZE_WHITESPACE
    ['dsec-flare', 'eflare-2.7k', 'eflare-mini', 'eflare-night', 'eflare-r-sim',
     'eflare-r-sim-mini']
    """
    return RECIPES.names()
