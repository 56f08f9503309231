"""The per-sample script: every random choice of one flare sample, drawn once, stored as JSON.

A :class:`FlareScript` fully determines one sample of stage 1: the clip
(duration, frame rate), the light source and its linear trajectory, the affine
augmentation, the flicker, the lens (PSF parameters and the seed of their
random geometry), the glare, the reflective ghosts, the optional Flare7K++
asset, and the event sensor (model, parameters, seed). **One script drives both
the flare video and the light-source video**, and both are simulated by one
sensor draw (the authors' code drew a different sensor gain for each, which
misaligned input and ground truth).

Draws follow the paper (Appendix A.2) where it gives numbers:

- frame rate :math:`\\min(48 f, 6000)` fps for the base flicker frequency
  :math:`f \\sim U(100, 140)` Hz (also drawn, and used for the rate, when the
  flicker is disabled, which happens in 30 % of samples);
- waveform sine / square / triangle, depth :math:`U(0.3, 1)`;
- start anywhere in the central 60 % of the frame, direction :math:`U(0, 360)`,
  travel :math:`U(0, 180)` px along a straight line;
- rotation :math:`U(0, 360)`, scale :math:`U(0.8, 1.5)`, translation
  :math:`\\pm 20 \\%` of the frame, shear :math:`\\pm 20` degrees;
- reflective ghosts in 90 % of samples;
- DVS-Voltmeter contrast: :math:`k_1 \\sim U(5, 7)` half the time, else
  :math:`U(7, 16)` (the authors' randomisation); :math:`k_2..k_6` of the DAVIS346.

Positions are stored as fractions of the sensor size and distances in pixels,
so a script renders at any sensor size (the ranges are meant for 640x480).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._validation import SimError, check_choice, check_range, dataclass_from_dict, make_rng
from .dvs import DVS346_K, IdealParams, VoltmeterParams
from .flare import GhostSpec, GlareSpec
from .optics import PSFConfig
from .surround import LitSurround, surround_from_dict

__all__ = [
    "WAVEFORMS",
    "Affine",
    "Flare7KChoice",
    "FlareScript",
    "Flicker",
    "LightSpec",
    "ScriptConfig",
    "SensorSpec",
    "Trajectory",
    "draw_script",
]

WAVEFORMS = ("sine", "square", "triangle")
"""Flicker waveforms."""


@dataclass(frozen=True)
class Trajectory:
    """Straight-line motion of the light: start (fractions of the frame), direction, travel."""

    start: tuple[float, float] = (0.5, 0.5)
    direction_deg: float = 0.0
    travel_px: float = 0.0

    def __post_init__(self) -> None:
        _set_pair(self, "start")
        check_range("direction_deg", self.direction_deg)
        check_range("travel_px", self.travel_px, 0)


@dataclass(frozen=True)
class Affine:
    """Augmentation of the flare pattern about the light: rotation, scale, translation, shear."""

    rotation_deg: float = 0.0
    scale: float = 1.0
    translate: tuple[float, float] = (0.0, 0.0)
    shear_deg: float = 0.0

    def __post_init__(self) -> None:
        check_range("rotation_deg", self.rotation_deg)
        check_range("scale", self.scale, 0, lo_open=True)
        _set_pair(self, "translate")
        check_range("shear_deg", self.shear_deg, -80, 80)

    def matrix(self) -> np.ndarray:
        """The 2x2 linear part: rotation @ shear (along x) @ scale."""
        a = math.radians(self.rotation_deg)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        shear = np.array([[1.0, math.tan(math.radians(self.shear_deg))], [0.0, 1.0]])
        return rot @ shear * self.scale


@dataclass(frozen=True)
class Flicker:
    """Periodic intensity factor ``1 - depth (1 - w(t))`` with a waveform ``w`` in [0, 1]."""

    frequency_hz: float = 120.0
    waveform: str = "sine"
    depth: float = 0.5
    phase: float = 0.0  # fraction of a period

    def __post_init__(self) -> None:
        check_range("frequency_hz", self.frequency_hz, 0, lo_open=True)
        check_choice("waveform", self.waveform, WAVEFORMS)
        check_range("depth", self.depth, 0, 1)
        check_range("phase", self.phase)

    def factor(self, t_us: np.ndarray | float) -> np.ndarray:
        """The intensity factor at times ``t_us`` (µs), in ``[1 - depth, 1]``.

        Examples
        --------
        >>> Flicker(100.0, "square", 0.5).factor(np.array([1000, 6000])).tolist()
        [1.0, 0.5]
        """
        cycles = np.asarray(t_us, dtype=np.float64) * 1e-6 * self.frequency_hz + self.phase
        frac = cycles - np.floor(cycles)
        if self.waveform == "sine":
            w = 0.5 * (1.0 + np.sin(2.0 * np.pi * frac))
        elif self.waveform == "square":
            w = (frac < 0.5).astype(np.float64)
        else:
            w = 1.0 - 2.0 * np.abs(frac - 0.5)
        return 1.0 - self.depth * (1.0 - w)


@dataclass(frozen=True)
class LightSpec:
    """The light source: size, profile, radiance (relative to white) and the frame's white level."""

    radius_px: float = 4.0
    profile: str = "disc"
    exposure: float = 100.0
    peak: float = 255.0

    def __post_init__(self) -> None:
        check_range("radius_px", self.radius_px, 0, lo_open=True)
        check_choice("profile", self.profile, ("disc", "gaussian"))
        check_range("exposure", self.exposure, 0, lo_open=True)
        check_range("peak", self.peak, 0, lo_open=True)


@dataclass(frozen=True)
class SensorSpec:
    """The event sensor of a sample: one draw shared by the flare and light videos.

    ``warm_start``: every simulator of the sample starts each pixel between its
    thresholds rather than on its reference (:mod:`edeflare.sim.dvs`).
    """

    model: str = "voltmeter"
    voltmeter: VoltmeterParams = field(default_factory=VoltmeterParams)
    ideal: IdealParams = field(default_factory=IdealParams)
    seed: int = 0
    warm_start: bool = False

    def __post_init__(self) -> None:
        check_choice("model", self.model, ("voltmeter", "ideal"))
        _check_seed("sensor seed", self.seed)
        if not isinstance(self.warm_start, bool):
            raise SimError(f"warm_start must be a bool, got {self.warm_start!r}")

    @property
    def params(self) -> VoltmeterParams | IdealParams:
        """The parameters of the selected model."""
        return self.voltmeter if self.model == "voltmeter" else self.ideal


@dataclass(frozen=True)
class Flare7KChoice:
    """A Flare7K++ pair, by its compound image's path relative to the asset root, and a gamma."""

    name: str
    gamma: float = 2.2

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise SimError(f"flare7k name must be a non-empty path string, got {self.name!r}")
        check_range("gamma", self.gamma, 1.0, 3.0)


@dataclass(frozen=True)
class FlareScript:
    """Everything that determines one stage-1 sample (see the module docstring).

    Examples
    --------
    >>> s = draw_script(rng=3)
    >>> FlareScript.from_json(s.to_json()) == s
    True
    """

    duration_us: int = 100_000
    fps: float = 6000.0
    trajectory: Trajectory = field(default_factory=Trajectory)
    affine: Affine = field(default_factory=Affine)
    flicker: Flicker | None = None
    light: LightSpec = field(default_factory=LightSpec)
    psf: PSFConfig = field(default_factory=PSFConfig)
    psf_seed: int = 0
    glare: GlareSpec | None = None
    ghosts: tuple[GhostSpec, ...] = ()
    sensor: SensorSpec = field(default_factory=SensorSpec)
    flare7k: Flare7KChoice | None = None
    gt_lens: str = "ideal"
    surround: LitSurround | None = None
    """The scene around the light, lit by it (:mod:`edeflare.sim.surround`; forward model)."""

    def __post_init__(self) -> None:
        if isinstance(self.duration_us, bool) or not isinstance(
            self.duration_us, (int, np.integer)
        ):
            raise SimError(f"duration_us must be an int, got {self.duration_us!r}")
        if self.duration_us <= 0:
            raise SimError(f"duration_us must be > 0, got {self.duration_us}")
        check_range("fps", self.fps, 0, 1e6, lo_open=True)
        _check_seed("psf_seed", self.psf_seed)
        object.__setattr__(self, "ghosts", tuple(self.ghosts))
        check_choice("gt_lens", self.gt_lens, ("ideal", "clean"))
        kinds = {
            "trajectory": Trajectory,
            "affine": Affine,
            "light": LightSpec,
            "psf": PSFConfig,
            "sensor": SensorSpec,
        }
        for name, cls in kinds.items():
            if not isinstance(getattr(self, name), cls):
                raise SimError(f"{name} must be a {cls.__name__}, got {getattr(self, name)!r}")
        if not all(isinstance(g, GhostSpec) for g in self.ghosts):
            raise SimError("ghosts must be GhostSpec instances")
        if self.surround is not None and not isinstance(self.surround, LitSurround):
            raise SimError(f"surround must be a LitSurround, got {self.surround!r}")

    def frame_times_us(self) -> np.ndarray:
        """Frame timestamps: ``round(i * 1e6 / fps)`` for every frame up to the duration.

        Examples
        --------
        >>> FlareScript(duration_us=1000, fps=4000.0).frame_times_us().tolist()
        [0, 250, 500, 750, 1000]
        """
        n = math.floor(self.duration_us * self.fps / 1e6 + 1e-9) + 1
        return np.round(np.arange(n) * (1e6 / self.fps)).astype(np.int64)

    def position_px(self, t_us: float, sensor_size: tuple[int, int]) -> tuple[float, float]:
        """Where the light is at ``t_us`` on a sensor of ``(width, height)``."""
        width, height = sensor_size
        tr, af = self.trajectory, self.affine
        x0 = (tr.start[0] + af.translate[0]) * width
        y0 = (tr.start[1] + af.translate[1]) * height
        frac = float(t_us) / self.duration_us
        a = math.radians(tr.direction_deg)
        return x0 + tr.travel_px * frac * math.cos(a), y0 + tr.travel_px * frac * math.sin(a)

    def intensity(self, t_us: np.ndarray | float) -> np.ndarray:
        """The light's flicker factor at ``t_us`` (1 without flicker)."""
        if self.flicker is None:
            return np.ones_like(np.asarray(t_us, dtype=np.float64))
        return self.flicker.factor(t_us)

    # ---------------------------------------------------------------- serialisation

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready nested dict."""
        d: dict[str, Any] = {
            "duration_us": int(self.duration_us),
            "fps": float(self.fps),
            "trajectory": _plain(self.trajectory),
            "affine": _plain(self.affine),
            "flicker": None if self.flicker is None else _plain(self.flicker),
            "light": _plain(self.light),
            "psf": self.psf.to_dict(),
            "psf_seed": int(self.psf_seed),
            "glare": None if self.glare is None else _plain(self.glare),
            "ghosts": [_plain(g) for g in self.ghosts],
            "sensor": {
                "model": self.sensor.model,
                "voltmeter": self.sensor.voltmeter.to_dict(),
                "ideal": self.sensor.ideal.to_dict(),
                "seed": int(self.sensor.seed),
                # left out while off: older scripts read the same, and their files stay
                **({"warm_start": True} if self.sensor.warm_start else {}),
            },
            "flare7k": None if self.flare7k is None else _plain(self.flare7k),
            "gt_lens": self.gt_lens,
        }
        if self.surround is not None:  # left out when absent: older scripts read the same
            d["surround"] = self.surround.to_dict()
        return d

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FlareScript:
        """Inverse of :meth:`to_dict`; unknown keys at any level are an error."""
        if not isinstance(data, Mapping):
            raise SimError(f"a script must be a mapping, got {type(data).__name__}")
        d = dict(data)
        nested = {
            "trajectory": Trajectory,
            "affine": Affine,
            "flicker": Flicker,
            "light": LightSpec,
            "psf": PSFConfig,
            "glare": GlareSpec,
            "flare7k": Flare7KChoice,
        }
        for key, kind in nested.items():
            if d.get(key) is not None:
                d[key] = dataclass_from_dict(kind, d[key], what=f"script {key!r}")
        if "ghosts" in d:
            if not isinstance(d["ghosts"], Sequence):
                raise SimError("script 'ghosts' must be a list")
            d["ghosts"] = tuple(
                dataclass_from_dict(GhostSpec, g, what="a ghost") for g in d["ghosts"]
            )
        if "sensor" in d:
            d["sensor"] = sensor_spec_from_dict(d["sensor"], what="script 'sensor'")
        if d.get("surround") is not None:
            d["surround"] = surround_from_dict(d["surround"])
        return dataclass_from_dict(cls, d, what="FlareScript")

    def to_json(self) -> str:
        """The script as JSON text (floats round-trip exactly)."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> FlareScript:
        """Parse :meth:`to_json` output."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SimError(f"a script must be JSON: {exc}") from None
        return cls.from_dict(data)


def sensor_spec_from_dict(data: Any, what: str = "the sensor") -> SensorSpec:
    """A :class:`SensorSpec` from its :func:`dataclasses.asdict` form (nested params included).

    Examples
    --------
    >>> spec = SensorSpec(model="ideal")
    >>> sensor_spec_from_dict(dataclasses.asdict(spec)) == spec
    True
    """
    if not isinstance(data, Mapping):
        raise SimError(f"{what} must be a mapping")
    d = dict(data)
    if "voltmeter" in d:
        d["voltmeter"] = VoltmeterParams.from_dict(d["voltmeter"])
    if "ideal" in d:
        d["ideal"] = IdealParams.from_dict(d["ideal"])
    return dataclass_from_dict(SensorSpec, d, what=what)


def _plain(obj: Any) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(obj).items()}


def _set_pair(obj: Any, name: str) -> None:
    value = getattr(obj, name)
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise SimError(f"{name} must be a pair of numbers, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise SimError(f"{name} must be finite, got {value!r}")
    object.__setattr__(obj, name, (a, b))


def _check_seed(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise SimError(f"{name} must be a non-negative int, got {value!r}")


@dataclass(frozen=True)
class ScriptConfig:
    """The ranges :func:`draw_script` draws from (defaults: the paper's, see the module docstring).

    Pairs are ``(low, high)`` of a uniform draw unless noted. ``warm_start`` draws
    nothing: every sample's sensor starts its pixels warm (:mod:`edeflare.sim.dvs`).

    Examples
    --------
    >>> ScriptConfig.from_dict({"ghost_probability": 0.5}).ghost_probability
    0.5
    """

    duration_ms: tuple[float, float] = (50.0, 100.0)
    fps_per_hz: float = 48.0
    max_fps: float = 6000.0
    flicker_hz: tuple[float, float] = (100.0, 140.0)
    no_flicker_probability: float = 0.3
    flicker_depth: tuple[float, float] = (0.3, 1.0)
    waveforms: tuple[str, ...] = WAVEFORMS
    start: tuple[float, float] = (0.2, 0.8)
    travel_px: tuple[float, float] = (0.0, 180.0)
    rotation_deg: tuple[float, float] = (0.0, 360.0)
    scale: tuple[float, float] = (0.8, 1.5)
    translate: float = 0.2
    shear_deg: float = 20.0
    light_radius_px: tuple[float, float] = (2.0, 8.0)
    gaussian_light_probability: float = 0.3
    exposure: tuple[float, float] = (10.0, 1000.0)  # log-uniform
    peak: tuple[float, float] = (180.0, 255.0)
    star_probability: float = 0.5
    star_orientations: tuple[int, int] = (2, 4)  # inclusive
    dust_count: tuple[int, int] = (0, 80)
    scratch_count: tuple[int, int] = (0, 6)
    blade_probability: float = 0.3
    blades: tuple[int, int] = (5, 9)
    defocus_waves: tuple[float, float] = (0.0, 0.4)
    random_filter_probability: float = 0.3
    random_phase_rms: tuple[float, float] = (0.1, 1.0)
    psf_grid: int = 512
    glare_probability: float = 0.5
    glare_level: tuple[float, float] = (5.0, 60.0)
    glare_streaks: tuple[int, int] = (0, 12)
    ghost_probability: float = 0.9
    ghost_count: tuple[int, int] = (3, 8)
    ghost_k: tuple[float, float] = (-5.0, 1.0)
    ghost_radius_px: tuple[float, float] = (4.0, 50.0)
    ghost_level: tuple[float, float] = (2.0, 25.0)
    sensor_model: str = "voltmeter"
    k1_low: tuple[float, float] = (5.0, 7.0)
    k1_high: tuple[float, float] = (7.0, 16.0)
    k1_low_probability: float = 0.5
    ideal_threshold: tuple[float, float] = (0.15, 0.35)
    ideal_threshold_sigma: float = 0.03
    warm_start: bool = False

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "waveforms":
                if not value or any(w not in WAVEFORMS for w in value):
                    raise SimError(f"waveforms must be a non-empty subset of {WAVEFORMS}")
                object.__setattr__(self, "waveforms", tuple(value))
            elif f.name == "sensor_model":
                check_choice("sensor_model", value, ("voltmeter", "ideal"))
            elif f.name == "warm_start":
                if not isinstance(value, bool):
                    raise SimError(f"warm_start must be a bool, got {value!r}")
            elif f.name.endswith("probability"):
                check_range(f.name, value, 0, 1)
            elif isinstance(f.default, tuple):
                lo, hi = (float(v) for v in value)
                if not lo <= hi:
                    raise SimError(f"{f.name} must be (low, high) with low <= high, got {value!r}")
                cast = int if isinstance(f.default[0], int) else float
                object.__setattr__(self, f.name, (cast(lo), cast(hi)))
            else:
                check_range(f.name, value, 0)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ScriptConfig:
        """Build from a mapping (e.g. parsed JSON); unknown keys are an error."""
        return dataclass_from_dict(cls, data)


def draw_script(
    config: ScriptConfig | None = None,
    *,
    flare7k_names: Sequence[str] | None = None,
    rng: np.random.Generator | int | None = None,
) -> FlareScript:
    """Draw one sample's script.

    Parameters
    ----------
    config : ScriptConfig, optional
        The ranges; defaults follow the paper.
    flare7k_names : sequence of str, optional
        Names of available Flare7K++ pairs (see :func:`edeflare.sim.render.flare7k_names`);
        when given, the script uses one of them instead of the synthetic PSF flare.
    rng : numpy.random.Generator or int, optional

    Examples
    --------
    >>> a, b = draw_script(rng=7), draw_script(rng=7)
    >>> a == b, 4800 <= a.fps <= 6000
    (True, True)
    """
    cfg = config or ScriptConfig()
    g = make_rng(rng)
    u = lambda pair: float(g.uniform(*pair))  # noqa: E731
    ui = lambda pair: int(g.integers(pair[0], pair[1] + 1))  # noqa: E731

    duration_us = round(u(cfg.duration_ms) * 1000)
    base_hz = u(cfg.flicker_hz)
    fps = min(cfg.fps_per_hz * base_hz, cfg.max_fps)
    flicker = None
    if g.random() >= cfg.no_flicker_probability:
        flicker = Flicker(
            frequency_hz=base_hz,
            waveform=str(g.choice(cfg.waveforms)),
            depth=u(cfg.flicker_depth),
            phase=float(g.random()),
        )
    trajectory = Trajectory(
        start=(u(cfg.start), u(cfg.start)),
        direction_deg=u((0.0, 360.0)),
        travel_px=u(cfg.travel_px),
    )
    affine = Affine(
        rotation_deg=u(cfg.rotation_deg),
        scale=u(cfg.scale),
        translate=(u((-cfg.translate, cfg.translate)), u((-cfg.translate, cfg.translate))),
        shear_deg=u((-cfg.shear_deg, cfg.shear_deg)),
    )
    light = LightSpec(
        radius_px=u(cfg.light_radius_px),
        profile="gaussian" if g.random() < cfg.gaussian_light_probability else "disc",
        exposure=float(np.exp(u(tuple(np.log(cfg.exposure))))),
        peak=u(cfg.peak),
    )
    star = g.random() < cfg.star_probability
    psf = PSFConfig(
        grid=cfg.psf_grid,
        blades=ui(cfg.blades) if g.random() < cfg.blade_probability else 0,
        blade_rotation_deg=u((0.0, 360.0)),
        defocus_waves=u(cfg.defocus_waves),
        dust_count=ui(cfg.dust_count),
        scratch_count=ui(cfg.scratch_count),
        star_orientations=ui(cfg.star_orientations) if star else 0,
        star_rotation_deg=u((0.0, 180.0)),
        random_phase_rms=(
            u(cfg.random_phase_rms) if g.random() < cfg.random_filter_probability else 0.0
        ),
    )
    psf_seed = int(g.integers(0, 2**63))
    glare = None
    if g.random() < cfg.glare_probability:
        glare = GlareSpec(
            level=u(cfg.glare_level),
            core_px=u((3.0, 12.0)),
            streaks=ui(cfg.glare_streaks),
            rotation_deg=u((0.0, 360.0)),
        )
    ghosts: tuple[GhostSpec, ...] = ()
    if g.random() < cfg.ghost_probability:
        ghosts = tuple(
            GhostSpec(
                k=u(cfg.ghost_k),
                radius_px=u(cfg.ghost_radius_px),
                level=u(cfg.ghost_level),
                softness=u((0.05, 0.4)),
                hollow=u((0.0, 0.7)),
                fringe=u((0.0, 0.05)),
            )
            for _ in range(ui(cfg.ghost_count))
        )
    k1 = u(cfg.k1_low) if g.random() < cfg.k1_low_probability else u(cfg.k1_high)
    c = u(cfg.ideal_threshold)
    sensor = SensorSpec(
        model=cfg.sensor_model,
        voltmeter=VoltmeterParams(k=(k1, *DVS346_K[1:])),
        ideal=IdealParams(c_on=c, c_off=c, c_sigma=cfg.ideal_threshold_sigma),
        seed=int(g.integers(0, 2**63)),
        warm_start=cfg.warm_start,
    )
    flare7k = None
    if flare7k_names:
        names = sorted(flare7k_names)
        flare7k = Flare7KChoice(name=str(names[int(g.integers(len(names)))]), gamma=u((1.8, 2.2)))
    return FlareScript(
        duration_us=duration_us,
        fps=fps,
        trajectory=trajectory,
        affine=affine,
        flicker=flicker,
        light=light,
        psf=psf,
        psf_seed=psf_seed,
        glare=glare,
        ghosts=ghosts,
        sensor=sensor,
        flare7k=flare7k,
    )
