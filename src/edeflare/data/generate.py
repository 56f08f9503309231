r"""Paired datasets from the simulator: parallel, sharded, resumable, bit-reproducible.

A :class:`Recipe` says what to make (the paper's E-Flare-2.7K is
``RECIPES["eflare-2.7k"]``: 544 sequences of 100 ms at 640x480, i.e. 2,720
paired 20 ms windows, 509 sequences / 2,545 windows for training and 35 / 175
for testing; ``eflare-mini`` is a small one for CPU training).
:func:`generate_dataset` writes it:

``OUT/train/seq_00000.h5 ... OUT/test/seq_00543.h5``
    One sequence per file (:func:`edeflare.io.dsec.write_dsec_groups`), the
    groups ``input`` (flare-corrupted events), ``gt`` (ground truth),
    ``flare``, ``light`` and ``background`` (the pure streams, so other
    compositions can be rebuilt without simulating again), each in the DSEC
    layout, and root attributes ``sensor_size``, ``t_start_us`` /
    ``t_end_us`` (the span; windows are aligned 20 ms windows from
    ``t_start_us``), ``script`` (the :class:`~edeflare.sim.script.FlareScript`
    JSON), ``background`` (its provenance JSON), ``recipe``, ``recipe_sha256``,
    ``index``, ``seed``, ``variant`` and ``edeflare_version``. This is the
    contract :class:`edeflare.data.pairs.PairedWindows` reads.
``OUT/manifest.json``
    The recipe, the package version, the seeds, per-split counts, and per
    file its split, seed, event counts per group, size and SHA-256. It holds
    nothing that depends on timing or on the order of work, so a resumed run
    ends with the same manifest as an uninterrupted one.

Sequence ``i`` is a pure function of ``(recipe, i)``: its random draws come
from ``numpy.random.SeedSequence([recipe.seed, i])`` (children: script,
background, composition, forward model), so any sequence can be regenerated
alone, on any worker, in any order, and files are byte-identical whatever the
number of workers (HDF5 stores no timestamps; the compressor is deterministic).

One sequence (:func:`generate_sequence`): draw the script; draw the
background (:mod:`edeflare.sim.background`); stream the flare and light
videos frame by frame through one camera (:func:`edeflare.sim.stage1.sensor_pair`),
sampling both videos at every background, flare and light event (linear in
time between frames); compose the pair (:func:`edeflare.sim.compose.compose_pair`,
or for ``variant="forward"`` simulate the sums :math:`I_{bg} + I_f` and
:math:`I_{bg} + I_{light}`, which needs a synthetic background).

Kinds. A recipe's ``kind`` says what a sequence is: ``"flare"`` (above: the
training pipeline), ``"optics"`` (the paper's model of its real captures,
:mod:`edeflare.data.eflare_r_sim`: ``eflare-r-sim`` and ``eflare-r-sim-mini``,
files with ``input`` and ``gt`` only) or ``"dsec"`` (windows of the user's
DSEC copy, :mod:`edeflare.data.dsec_flare`: ``dsec-flare``, files with an
``input`` group only, no ground truth). Both new kinds are test sets: every
sequence goes to ``test/``. Their files record ``kind`` and their provenance
(:class:`~edeflare.sim.optics_scene.OpticsScene` or
:class:`~edeflare.data.dsec_flare.DsecWindow` JSON) as ``script``.

Runs are parallel (a ``spawn`` process pool; numba and ``fork`` do not mix),
sharded (``shard=(i, n)`` makes the sequences with ``index % n == i``, for array
jobs; the run that finds every file present writes ``manifest.json``, the
others ``manifest.shard-i-of-n.json``), and resumable (files are written
atomically and existing ones skipped, so a killed run loses only the
sequences in flight).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import h5py
import numba
import numpy as np

from .. import __version__
from ..errors import EdeflareError, EventFileError, ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_sensor_size
from ..io._atomic import atomic_path
from ..io.dsec import write_dsec_groups
from ..sim.background import (
    Background,
    BackgroundSource,
    RecordedBackground,
    SceneConfig,
    SyntheticBackground,
    camera_simulator,
    relative_names,
)
from ..sim.compose import (
    VARIANTS,
    AccumulationParams,
    Components,
    CountIntensity,
    compose_pair,
)
from ..sim.optics_scene import OpticsScene, OpticsSceneConfig
from ..sim.render import Renderer, flare7k_names
from ..sim.script import FlareScript, ScriptConfig, draw_script
from ..sim.stage1 import sensor_pair
from .dsec_flare import (
    DsecFlareConfig,
    DsecFlareError,
    DsecWindow,
    dsec_sequence,
    expand_windows,
    find_dsec_sequences,
)
from .eflare_r_sim import optics_sequence

__all__ = [
    "GROUPS",
    "KINDS",
    "RECIPES",
    "STAGES",
    "GenerationReport",
    "Recipe",
    "SequenceData",
    "SequenceInputs",
    "draw_inputs",
    "generate_dataset",
    "generate_sequence",
    "list_recipes",
    "make_background_source",
    "sequence_path",
    "write_sequence",
]

GROUPS = ("input", "gt", "flare", "light", "background")
"""Event groups of a sequence file."""
STAGES = ("background", "render", "simulate", "compose", "write")
"""Stages timed per sequence."""
WEIGHTS = ("intensity", "accumulation", "counts")
"""PNL-ES intensities: rendered videos (and the scene or the accumulation estimate for the
background), the accumulation estimate for the background even when synthetic, or the
authors' whole-window event counts for all three streams."""
KINDS = ("flare", "optics", "dsec")
"""What a recipe's sequences are: simulated training pairs, optics test pairs, DSEC windows."""
_ALL_VARIANTS = (*VARIANTS, "forward")
_FORMAT = "edeflare-dataset/1"


class GenerationError(EdeflareError, ValueError):
    """A dataset cannot be generated as asked (the message says why and what to do)."""


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

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"recipe name must be a non-empty string, got {self.name!r}")
        if self.kind not in KINDS:
            raise ParameterError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if self.kind == "dsec" and isinstance(self.dsec, DsecFlareConfig):
            object.__setattr__(self, "sequences", len(expand_windows(self.dsec.windows)))
        if self.kind != "flare":  # test sets only
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
        if self.variant not in _ALL_VARIANTS:
            raise ParameterError(f"variant must be one of {_ALL_VARIANTS}, got {self.variant!r}")
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
        kinds = {
            "script": ScriptConfig,
            "scene": SceneConfig,
            "accumulation": AccumulationParams,
            "optics": OpticsSceneConfig,
            "dsec": DsecFlareConfig,
        }
        for key, kind in kinds.items():
            if not isinstance(getattr(self, key), kind):
                raise ParameterError(f"{key} must be a {kind.__name__}")

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
        nested: dict[str, Any] = {
            "script": ScriptConfig,
            "scene": SceneConfig,
            "accumulation": AccumulationParams,
            "optics": OpticsSceneConfig,
            "dsec": DsecFlareConfig,
        }
        for key, kind in nested.items():
            if key in d and isinstance(d[key], Mapping):
                try:
                    d[key] = kind.from_dict(d[key])
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
        d["optics"], d["dsec"] = self.optics.to_dict(), self.dsec.to_dict()
        if self.kind == "flare":
            del d["kind"]
        if self.kind != "optics":
            del d["optics"]
        if self.kind != "dsec":
            del d["dsec"]
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
        if "dsec" in d:  # the same DSEC data anywhere gives the same dataset
            d["dsec"]["root"] = None
        return d

    def sha256(self) -> str:
        """A digest of :meth:`identity`, stored in every file to detect a changed recipe."""
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()


def _asdict(value: Any) -> Any:
    return dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value


# A slowly moving camera for the optics test sets (E-Flare-R's camera stands still; a
# little motion gives the background events to keep).
_SLOW_STREET = SceneConfig(pan_px_per_s=(10.0, 120.0), zoom_per_s=(0.0, 0.3), shake_px=(0.0, 1.0))

RECIPES: dict[str, Recipe] = {
    "eflare-2.7k": Recipe(name="eflare-2.7k"),
    "eflare-mini": Recipe(
        name="eflare-mini", sequences=120, test_sequences=12, sensor_size=(346, 260)
    ),
    "eflare-r-sim": Recipe(
        name="eflare-r-sim", kind="optics", sequences=30, sensor_size=(640, 480), scene=_SLOW_STREET
    ),
    "eflare-r-sim-mini": Recipe(
        name="eflare-r-sim-mini",
        kind="optics",
        sequences=20,
        sensor_size=(346, 260),
        scene=_SLOW_STREET,
    ),
    "dsec-flare": Recipe(name="dsec-flare", kind="dsec", sensor_size=(640, 480)),
}
"""Named recipes: the paper's E-Flare-2.7K (synthetic backgrounds unless files are given),
and a small one (120 sequences of 100 ms at 346x260: 540 training and 60 test windows);
the optics test sets after E-Flare-R's physical model, ``eflare-r-sim`` (30 sequences of
100 ms at 640x480, the paper's crop: 150 test windows, as E-Flare-R's 150 pairs) and
``eflare-r-sim-mini`` (20 at 346x260: 100 test windows); and ``dsec-flare``, the paper's
DSEC-Flare windows (15 of 100 ms at 640x480 by default) cut from a local DSEC copy
(``dsec=DsecFlareConfig(root=...)``), without ground truth."""


def list_recipes() -> list[str]:
    """Names of :data:`RECIPES`.

    Examples
    --------
    >>> list_recipes()
    ['dsec-flare', 'eflare-2.7k', 'eflare-mini', 'eflare-r-sim', 'eflare-r-sim-mini']
    """
    return sorted(RECIPES)


def make_background_source(recipe: Recipe) -> BackgroundSource:
    """The background source a recipe asks for."""
    if recipe.background == "recorded":
        return RecordedBackground(
            recipe.background_files,
            intensity="counts" if recipe.weights == "counts" else "accumulation",
            accumulation=recipe.accumulation,
        )
    intensity = {"intensity": "video", "accumulation": "accumulation", "counts": "counts"}
    return SyntheticBackground(
        recipe.scene, intensity=intensity[recipe.weights], accumulation=recipe.accumulation
    )


def sequence_path(out: str | os.PathLike[str], recipe: Recipe, index: int) -> Path:
    """Where sequence ``index`` lives: ``out/<split>/seq_<index:05d>.h5``."""
    return Path(out) / recipe.split_of(index) / f"seq_{index:05d}.h5"


@dataclass(frozen=True)
class SequenceData:
    """One generated sequence in memory.

    Attributes
    ----------
    index : int
    streams : dict
        ``{"input", "gt", "flare", "light", "background"} -> events`` (kind
        ``"optics"``: input and gt; ``"dsec"``: input).
    components : Components or None
        The pure streams and their intensities at each other's events, as
        weighted by the recipe (to recompose with other variants or draws);
        None for the other kinds.
    script : FlareScript, OpticsScene or DsecWindow
    background : dict
        The background's provenance.
    sensor_size : (width, height)
    t_start_us, t_end_us : int
    timings : dict
        Seconds per stage (:data:`STAGES`).
    """

    index: int
    streams: dict[str, np.ndarray]
    components: Components | None
    script: FlareScript | OpticsScene | DsecWindow
    background: dict[str, Any]
    sensor_size: SensorSize
    t_start_us: int
    t_end_us: int
    timings: dict[str, float]


@dataclass(frozen=True)
class SequenceInputs:
    """The random inputs of one sequence: script, background and the remaining seeds."""

    index: int
    script: FlareScript
    background: Background
    compose_seed: np.random.SeedSequence
    forward_seed: np.random.SeedSequence


class _Timer:
    def __init__(self) -> None:
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self._stage: str | None = None
        self._t0 = 0.0

    def __call__(self, stage: str) -> _Timer:
        self._stage = stage
        return self

    def __enter__(self) -> None:
        self._t0 = time.perf_counter()

    def __exit__(self, *exc: object) -> None:
        assert self._stage is not None
        self.seconds[self._stage] += time.perf_counter() - self._t0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _interpolate(t, x, y, t0, t1, prev, cur, out):  # pragma: no cover - compiled
    """``out[i]``: the intensity at event ``i``, linear between ``prev`` (t0) and ``cur`` (t1)."""
    span = max(t1 - t0, 1)
    for i in range(t.size):
        frac = min(max((t[i] - t0) / span, 0.0), 1.0)
        a = np.float64(prev[y[i], x[i]])
        out[i] = a + frac * (np.float64(cur[y[i], x[i]]) - a)


def _sample_frames(
    events: np.ndarray, t0: int, t1: int, prev: np.ndarray, cur: np.ndarray
) -> np.ndarray:
    out = np.empty(events.size, dtype=np.float64)
    _interpolate(events["t"], events["x"], events["y"], t0, t1, prev, cur, out)
    return out


_SOURCES: dict[str, BackgroundSource] = {}
_FLARE7K: dict[str, list[str]] = {}


def _source_for(recipe: Recipe) -> BackgroundSource:
    key = recipe.sha256()
    if key not in _SOURCES:
        _SOURCES.clear()
        _SOURCES[key] = make_background_source(recipe)
    return _SOURCES[key]


def _flare7k_names(root: str) -> list[str]:
    if root not in _FLARE7K:
        names = flare7k_names(root)
        if not names:
            raise GenerationError(f"{root}: holds no Flare7K++ image pairs")
        _FLARE7K[root] = names
    return _FLARE7K[root]


def _check_index(recipe: Recipe, index: Any) -> int:
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise ParameterError(f"index must be an int, got {index!r}")
    if not 0 <= index < recipe.sequences:
        raise ParameterError(f"index must be in [0, {recipe.sequences}), got {index}")
    return int(index)


def draw_inputs(
    recipe: Recipe, index: int, *, source: BackgroundSource | None = None
) -> SequenceInputs:
    """Sequence ``index``'s script and background: the first step of :func:`generate_sequence`.

    Examples
    --------
    >>> r = Recipe(sensor_size=(32, 24), duration_us=20_000, scene=SceneConfig(fps=1000.0))
    >>> a, b = draw_inputs(r, 5), draw_inputs(r, 5)
    >>> a.script == b.script, a.background.description == b.background.description
    (True, True)
    """
    index = _check_index(recipe, index)
    size, duration = recipe.sensor_size, recipe.duration_us
    s_script, s_bg, s_comp, s_fwd = np.random.SeedSequence([recipe.seed, index]).spawn(4)
    ms = duration / 1000
    config = dataclasses.replace(recipe.script, duration_ms=(ms, ms))
    names = _flare7k_names(recipe.flare7k) if recipe.flare7k else None
    script = draw_script(config, flare7k_names=names, rng=np.random.default_rng(s_script))
    if script.duration_us != duration:  # ScriptConfig rounds ms to µs
        script = dataclasses.replace(script, duration_us=duration)
    src = source or _source_for(recipe)
    background = src.draw(duration, size, script.sensor, rng=np.random.default_rng(s_bg))
    return SequenceInputs(index, script, background, s_comp, s_fwd)


def generate_sequence(
    recipe: Recipe, index: int, *, source: BackgroundSource | None = None
) -> SequenceData:
    """Simulate sequence ``index`` of ``recipe`` (a pure function of both).

    Parameters
    ----------
    recipe : Recipe
    index : int
        In ``[0, recipe.sequences)``.
    source : BackgroundSource, optional
        Reuse an opened source (default: the recipe's, cached per process).

    Examples
    --------
    >>> r = Recipe(sequences=2, test_sequences=1, sensor_size=(32, 24), duration_us=20_000,
    ...            scene=SceneConfig(fps=1000.0))
    >>> a, b = generate_sequence(r, 1), generate_sequence(r, 1)
    >>> all(np.array_equal(a.streams[k], b.streams[k]) for k in GROUPS)
    True
    >>> sorted(a.streams) == sorted(GROUPS), a.t_end_us
    (True, 20000)
    """
    index = _check_index(recipe, index)
    if recipe.kind != "flare":
        if recipe.kind == "optics":
            recorded = recipe.background == "recorded"
            made = optics_sequence(
                recipe, index, (source or _source_for(recipe)) if recorded else None
            )
        else:
            made = dsec_sequence(recipe, index)
        streams, provenance, described, seconds = made
        timings = dict.fromkeys(STAGES, 0.0) | seconds
        return SequenceData(
            index, streams, None, provenance, described, recipe.sensor_size, 0,
            recipe.duration_us, timings,
        )  # fmt: skip
    timer = _Timer()
    size, duration = recipe.sensor_size, recipe.duration_us
    with timer("background"):
        inputs = draw_inputs(recipe, index, source=source)
    background = inputs.background
    streams, intensity = _stream_pass(recipe, inputs.script, background, inputs.forward_seed, timer)

    with timer("compose"):
        forward = {
            k: streams.pop(f"forward_{k}") for k in ("ob", "gt") if f"forward_{k}" in streams
        }
        if recipe.weights == "counts":
            fields = {name: CountIntensity(streams[name], size) for name in streams}
            components = Components.from_fields(streams, fields, 0, duration)
        else:
            bg_field = background.intensity
            for name in ("background", "flare", "light"):
                intensity["background"][name] = bg_field.sample(streams[name])
            components = Components(streams, intensity, 0, duration)
        if recipe.variant == "forward":
            ob, gt = forward["ob"], forward["gt"]
        else:
            ob, gt = compose_pair(
                components,
                recipe.variant,
                jitter_us=recipe.jitter_us,
                independent_background=recipe.independent_background,
                rng=np.random.default_rng(inputs.compose_seed),
            )
    out = {"input": ob, "gt": gt}
    out.update({k: streams[k] for k in ("flare", "light", "background")})
    return SequenceData(
        index,
        out,
        components,
        inputs.script,
        background.description,
        size,
        0,
        duration,
        timer.seconds,
    )


def _stream_pass(
    recipe: Recipe,
    script: FlareScript,
    background: Background,
    fwd_seq: np.random.SeedSequence,
    timer: _Timer,
) -> tuple[dict[str, np.ndarray], dict[str, dict[str, np.ndarray]]]:
    """Render and simulate the flare and light videos; sample them at every event.

    Returns the streams (cut to ``[0, duration)``) and the flare and light
    intensities at the background, flare and light events.
    """
    size, duration = recipe.sensor_size, recipe.duration_us
    with timer("render"):
        renderer = Renderer(script, size, flare7k=recipe.flare7k)
        frames = iter(renderer)
    sim_f, sim_l = sensor_pair(script.sensor, size)
    forward = recipe.variant == "forward"
    if forward:
        seq_ob, seq_gt = fwd_seq.spawn(2)
        sim_ob = camera_simulator(script.sensor, size, rng=np.random.default_rng(seq_ob))
        sim_gt = camera_simulator(script.sensor, size, rng=np.random.default_rng(seq_gt))
    bg = background.events
    bg_t = np.ascontiguousarray(bg["t"])
    i_f_bg = np.zeros(bg.size)
    i_l_bg = np.zeros(bg.size)
    chunks: dict[str, list[np.ndarray]] = {k: [] for k in ("flare", "light", "ob", "gt")}
    i_f_f: list[np.ndarray] = []
    i_l_l: list[np.ndarray] = []
    prev: tuple[int, np.ndarray, np.ndarray] | None = None
    done = 0  # background events sampled so far
    while True:
        with timer("render"):
            item = next(frames, None)
        if item is None:
            break
        t, flare, light = item
        with timer("simulate"):
            ef = sim_f.feed(flare, t)
            el = sim_l.feed(light, t)
            if forward:
                assert background.video is not None
                bgf = background.video(t).astype(np.float64)
                chunks["ob"].append(sim_ob.feed(bgf + flare, t))
                chunks["gt"].append(sim_gt.feed(bgf + light, t))
        with timer("compose"):
            hi = int(np.searchsorted(bg_t, t, side="right"))
            t0, f0, l0 = prev if prev is not None else (t, flare, light)
            sel = bg[done:hi]
            i_f_bg[done:hi] = _sample_frames(sel, t0, t, f0, flare)
            i_l_bg[done:hi] = _sample_frames(sel, t0, t, l0, light)
            i_f_f.append(_sample_frames(ef, t0, t, f0, flare))
            i_l_l.append(_sample_frames(el, t0, t, l0, light))
            done = hi
            chunks["flare"].append(ef)
            chunks["light"].append(el)
        prev = (t, flare, light)
    with timer("compose"):
        if prev is not None and done < bg.size:  # after the last frame: hold it
            sel = bg[done:]
            i_f_bg[done:] = prev[1][sel["y"], sel["x"]]
            i_l_bg[done:] = prev[2][sel["y"], sel["x"]]
        streams: dict[str, np.ndarray] = {"background": bg}
        values: dict[str, np.ndarray] = {}
        for name, parts, inten in (
            ("flare", chunks["flare"], i_f_f),
            ("light", chunks["light"], i_l_l),
        ):
            events = np.concatenate(parts) if parts else np.empty(0, dtype=EVENT_DTYPE)
            vals = np.concatenate(inten) if inten else np.empty(0)
            n = int(np.searchsorted(events["t"], duration))  # sorted: cut at the end
            streams[name] = events[:n]
            values[name] = vals[:n]
        if forward:
            for name in ("ob", "gt"):
                events = np.concatenate(chunks[name])
                streams[f"forward_{name}"] = events[: int(np.searchsorted(events["t"], duration))]
        intensity = {
            "background": {},
            "flare": {"background": i_f_bg, "flare": values["flare"]},
            "light": {"background": i_l_bg, "light": values["light"]},
        }
    return streams, intensity


def write_sequence(
    path: str | os.PathLike[str], data: SequenceData, recipe: Recipe
) -> dict[str, Any]:
    """Write one sequence file atomically; return its manifest entry (counts, size, SHA-256)."""
    path = Path(path)
    groups = GROUPS if recipe.components else ("input", "gt")
    groups = tuple(g for g in groups if g in data.streams)
    attrs = {
        "t_start_us": np.int64(data.t_start_us),
        "t_end_us": np.int64(data.t_end_us),
        "script": data.script.to_json(),
        "background": json.dumps(data.background, sort_keys=True),
        "recipe": recipe.name,
        "recipe_sha256": recipe.sha256(),
        "index": np.int64(data.index),
        "seed": json.dumps([recipe.seed, data.index]),
        "variant": recipe.variant,
        "edeflare_version": __version__,
    }
    if recipe.kind != "flare":  # no composition variant; say what the file is instead
        del attrs["variant"]
        attrs["kind"] = recipe.kind
    write_dsec_groups(path, {g: data.streams[g] for g in groups}, data.sensor_size, attrs)
    return _entry(path, recipe, data.index)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _entry(path: Path, recipe: Recipe, index: int) -> dict[str, Any]:
    """The manifest entry of an existing file (checked to belong to ``recipe``)."""
    try:
        with h5py.File(path, "r") as f:
            stored = f.attrs.get("recipe_sha256")
            if isinstance(stored, bytes):
                stored = stored.decode()
            counts = {g: int(f[g]["events/t"].shape[0]) for g in GROUPS if g in f}
    except (OSError, KeyError) as exc:
        raise EventFileError(path, f"is not a readable sequence file ({exc}); delete it") from None
    if stored != recipe.sha256():
        raise GenerationError(
            f"{path} was made by another recipe; generate into an empty folder "
            "or delete the old files"
        )
    return {
        "index": int(index),
        "split": recipe.split_of(index),
        "file": f"{recipe.split_of(index)}/{path.name}",
        "seed": [recipe.seed, int(index)],
        "events": counts,
        "bytes": path.stat().st_size,
        "sha256": _sha256(path),
    }


def _manifest(recipe: Recipe, entries: Mapping[int, dict[str, Any]]) -> dict[str, Any]:
    splits: dict[str, dict[str, int]] = {}
    for split in ("train", "test"):
        n = sum(1 for i in range(recipe.sequences) if recipe.split_of(i) == split)
        splits[split] = {"sequences": n, "windows": n * recipe.windows_per_sequence}
    return {
        "format": _FORMAT,
        "edeflare_version": __version__,
        "recipe": recipe.identity(),
        "seed": recipe.seed,
        "seed_rule": "numpy.random.SeedSequence([seed, index])",
        "sequences": recipe.sequences,
        "splits": splits,
        "complete": len(entries) == recipe.sequences,
        "files": [entries[i] for i in sorted(entries)],
    }


def _write_json(path: Path, payload: dict[str, Any]) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n")


# ----------------------------------------------------------------------------- workers


def _watch_parent(parent: int) -> None:
    """Exit when the parent process dies (a killed run must not leave busy orphans)."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(1)


def _init_worker(parent: int, threads: int) -> None:
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _work(recipe: Recipe, index: int, out: str) -> tuple[dict[str, Any], dict[str, float]]:
    data = generate_sequence(recipe, index)
    t0 = time.perf_counter()
    entry = write_sequence(sequence_path(out, recipe, index), data, recipe)
    timings = dict(data.timings)
    timings["write"] += time.perf_counter() - t0
    return entry, timings


@dataclass(frozen=True)
class GenerationReport:
    """What :func:`generate_dataset` did.

    Attributes
    ----------
    manifest : dict
        The manifest written (``complete`` tells whether every sequence exists).
    manifest_path : Path
    generated, skipped : int
        Sequences made in this run, and found complete.
    stage_seconds : dict
        Summed per-stage seconds of the sequences made (:data:`STAGES`).
    wall_seconds : float
    """

    manifest: dict[str, Any]
    manifest_path: Path
    generated: int
    skipped: int
    stage_seconds: dict[str, float]
    wall_seconds: float


def _parse_shard(shard: tuple[int, int] | str) -> tuple[int, int]:
    if isinstance(shard, str):
        try:
            i, n = (int(v) for v in shard.split("/"))
        except ValueError:
            raise ParameterError(f"shard must look like 0/4 (i/n), got {shard!r}") from None
    else:
        i, n = shard
    if not (n >= 1 and 0 <= i < n):
        raise ParameterError(f"shard i/n needs n >= 1 and 0 <= i < n, got {i}/{n}")
    return int(i), int(n)


def generate_dataset(
    recipe: Recipe,
    out: str | os.PathLike[str],
    *,
    workers: int = 1,
    shard: tuple[int, int] | str = (0, 1),
    progress: bool = True,
    on_sequence: Callable[[int, dict[str, float]], None] | None = None,
) -> GenerationReport:
    """Generate (or resume) a dataset into ``out`` (see the module docstring).

    Parameters
    ----------
    recipe : Recipe
    out : path-like
        Dataset folder (created).
    workers : int
        Processes (1: in this process).
    shard : (i, n) or "i/n"
        Make only the sequences with ``index % n == i``.
    progress : bool
        Show a progress bar with an ETA on stderr.
    on_sequence : callable, optional
        Called with ``(index, stage_seconds)`` as each sequence is written.

    Returns
    -------
    GenerationReport

    Examples
    --------
    >>> import tempfile
    >>> r = Recipe(sequences=2, test_sequences=1, sensor_size=(32, 24), duration_us=20_000,
    ...            scene=SceneConfig(fps=1000.0))
    >>> report = generate_dataset(r, tempfile.mkdtemp(), progress=False)
    >>> report.generated, report.manifest["complete"], [f["file"] for f in report.manifest["files"]]
    (2, True, ['train/seq_00000.h5', 'test/seq_00001.h5'])
    """
    if not isinstance(recipe, Recipe):
        raise ParameterError(f"recipe must be a Recipe, got {type(recipe).__name__}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}")
    shard_i, shard_n = _parse_shard(shard)
    out = Path(out)
    start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    manifest_path = out / "manifest.json"
    _check_existing_manifest(manifest_path, recipe)
    mine = [i for i in range(recipe.sequences) if i % shard_n == shard_i]
    for i in mine:  # temporary files of a killed run of this shard
        path = sequence_path(out, recipe, i)
        for stale in path.parent.glob(f".{path.name}.*.partial.h5"):
            stale.unlink(missing_ok=True)
    entries: dict[int, dict[str, Any]] = {}
    todo = []
    for i in mine:
        path = sequence_path(out, recipe, i)
        if path.is_file():
            entries[i] = _entry(path, recipe, i)
        else:
            todo.append(i)
    skipped = len(entries)
    own_path = (
        manifest_path if shard_n == 1 else out / f"manifest.shard-{shard_i}-of-{shard_n}.json"
    )
    if todo and recipe.kind == "dsec":  # find the DSEC files here: errors surface early
        _check_dsec(recipe)
    elif todo:
        _source_for(recipe)  # open the background files once here: errors surface early
    stage_seconds = dict.fromkeys(STAGES, 0.0)
    bar = _progress(len(mine), skipped, recipe.name, progress)
    last_write = 0.0

    def finished(index: int, entry: dict[str, Any], timings: dict[str, float]) -> None:
        nonlocal last_write
        entries[index] = entry
        for k in STAGES:
            stage_seconds[k] += timings.get(k, 0.0)
        if bar is not None:
            bar.update(1)
        if on_sequence is not None:
            on_sequence(index, timings)
        now = time.perf_counter()
        if now - last_write > 2.0:  # keep the manifest current without rewriting it per file
            _write_json(own_path, _manifest(recipe, entries))
            last_write = now

    try:
        if workers == 1 or len(todo) <= 1:
            for i in todo:
                entry, timings = _work(recipe, i, str(out))
                finished(i, entry, timings)
        else:
            _run_pool(recipe, todo, out, workers, finished)
    finally:
        if bar is not None:
            bar.close()
    final_entries = dict(entries)
    if shard_n > 1:  # other shards' files, if they are all there
        for i in range(recipe.sequences):
            if i not in final_entries and sequence_path(out, recipe, i).is_file():
                final_entries[i] = _entry(sequence_path(out, recipe, i), recipe, i)
    manifest = _manifest(recipe, final_entries)
    target = manifest_path if manifest["complete"] else own_path
    if not manifest["complete"]:
        manifest = _manifest(recipe, entries)
    _write_json(target, manifest)
    return GenerationReport(
        manifest, target, len(todo), skipped, stage_seconds, time.perf_counter() - start
    )


def _check_dsec(recipe: Recipe) -> None:
    if recipe.dsec.root is None:
        raise DsecFlareError(
            f"recipe {recipe.name!r} needs the local DSEC folder: --dsec-root PATH "
            "(or dsec=DsecFlareConfig(root=...))"
        )
    find_dsec_sequences(recipe.dsec.root, recipe.dsec.sequences)


def _check_existing_manifest(path: Path, recipe: Recipe) -> None:
    if not path.is_file():
        return
    try:
        old = json.loads(path.read_text())
        old_recipe = old["recipe"]
    except (OSError, ValueError, KeyError, TypeError):
        raise EventFileError(path, "is not a dataset manifest; use an empty folder") from None
    if old_recipe != recipe.identity():
        raise GenerationError(
            f"{path.parent} holds a dataset of another recipe ({old_recipe.get('name')!r}, "
            "different settings); generate into an empty folder"
        )


def _run_pool(
    recipe: Recipe,
    todo: Sequence[int],
    out: Path,
    workers: int,
    finished: Callable[[int, dict[str, Any], dict[str, float]], None],
) -> None:
    threads = max(1, (os.cpu_count() or 1) // workers)
    ctx = get_context("spawn")
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(os.getpid(), threads),
    ) as pool:
        pending: dict[Future[Any], int] = {}
        queue = list(todo)
        try:
            while queue or pending:
                while queue and len(pending) < 2 * workers:  # bounded: cancel stays quick
                    i = queue.pop(0)
                    pending[pool.submit(_work, recipe, i, str(out))] = i
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in sorted(done, key=lambda f: pending[f]):
                    i = pending.pop(fut)
                    entry, timings = fut.result()
                    finished(i, entry, timings)
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise


def _progress(total: int, initial: int, name: str, enabled: bool) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        desc=name,
        unit="seq",
        file=sys.stderr,
        dynamic_ncols=True,
        disable=None,  # no bar when stderr is not a terminal (logs, nohup)
    )
