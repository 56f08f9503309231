r"""Lit sources imaged through two lenses: the paper's physical model of its real captures.

E-Flare-R (Sec. 3.3, App. A.3) records one dynamic scene twice, with a filter
in front of the lens and without it. In Fourier optics the filter multiplies
the pupil, :math:`P_{ob} = P_{clean}\,T`, and

.. math::

    E_{ob} = \mathcal S(I_{gt} * \mathrm{PSF}_{ob}), \qquad
    E_{gt} = \mathcal S(I_{gt} * \mathrm{PSF}_{clean}).

This module simulates exactly that, with the PSFs of :mod:`edeflare.sim.optics`:

- **Filters** (:data:`FILTERS`): a six-point star filter (three line gratings
  60 degrees apart, jittered spacing so the orders smear into streaks) or a
  random-pattern filter (a smooth random phase screen, i.e. a diffuser, with a
  little dust). ``PSF_clean`` is the same lens without the filter (``T = 1``);
  both share the lens's defocus.
- **Sources** (:data:`SOURCE_KINDS`), as in the paper's rig: a steady
  ``point`` light, a square tungsten ``lamp`` (a rotated square with a small
  sine ripple at twice the mains frequency, 100 or 120 Hz) and a
  frequency-controllable ``strobe`` (a point light switched by a square wave
  of a given frequency and duty cycle). Each moves along a straight line.
- **Scene**: the sources in front of a background. A synthetic night street
  (:class:`~edeflare.sim.background.NightStreet`, a slowly moving camera) is
  imaged through both lenses with the sources (the whole irradiance is
  convolved; the street's own lamps flare too). A *recorded* background exists
  only as events, so it cannot be imaged again: the sources are simulated
  through each lens alone and fused with it by PNL-ES
  (:func:`edeflare.sim.compose.compose_pair`, ``"physical"``).
- **Sensor**: one sensor draw per pair. Both passes go through simulators of
  one camera seeded identically (:attr:`OpticsScene.sensor`), so a pixel that
  sees the same irradiance in both passes emits the same events in both; the
  background-activity noise is the same too. Where the filter's light
  changes the irradiance, the streams differ: that difference is the flare.

Rendering is linear and shift-invariant, so a moving source through a lens is
its template (source image convolved with the PSF, computed once per source
and lens) moved and scaled by its modulation; the street's texture is
convolved once per lens and viewed through the camera motion (exact for the
pan and shake; the slow zoom of at most a few per cent per sequence scales
the PSF by as much). Frames are clipped at :data:`~edeflare.sim.flare.WHITE`
like the training renderer's. The frame rate is
``clip(frames_per_period * fastest strobe, *fps)``.

Examples
--------
A 1 kHz strobe behind a star filter, in the dark: the filter's spikes add events.

>>> strobe = LightSourceSpec(kind="strobe", radiance=50 * 255.0, frequency_hz=1000.0, depth=1.0)
>>> scene = OpticsScene(duration_us=2_000, fps=8000.0, sources=(strobe,),
...                     psf=PSFConfig(grid=128, star_orientations=3))
>>> pair = simulate_optics_pair(scene, (48, 32))
>>> pair.input.dtype.names, pair.input.size > pair.gt.size > 0
(('t', 'x', 'y', 'p'), True)
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import ndimage

from ..events import EVENT_DTYPE, SensorSize, check_sensor_size, merge_events
from ._validation import (
    SimError,
    check_choice,
    check_interval,
    check_range,
    dataclass_from_dict,
    make_rng,
)
from .background import Background, NightStreet
from .camera import camera_simulator
from .compose import Components, compose_pair
from .dvs import DVS346_K, IdealParams, VoltmeterParams
from .flare import WHITE, light_source, scattering_flare
from .optics import PSFConfig, psf_pair
from .pair import EventRecorder, FrameRecorder, StageTimer, run_frames
from .render import _warp_add
from .script import SensorSpec, sensor_spec_from_dict

__all__ = [
    "FILTERS",
    "SOURCE_KINDS",
    "LightSourceSpec",
    "OpticsPair",
    "OpticsRenderer",
    "OpticsScene",
    "OpticsSceneConfig",
    "SourceIntensity",
    "draw_optics_scene",
    "simulate_optics_pair",
]

SOURCE_KINDS = ("point", "lamp", "strobe")
"""Light sources of the paper's rig: steady point light, square tungsten lamp, strobe."""
FILTERS = ("star", "random")
"""Filters in front of the lens: six-point star, random pattern (diffuser)."""
_LENSES = ("ob", "gt")
_FLOOR = 0.05  # template values below this (8-bit scale) are cut: no pixel responds to them


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


@dataclass(frozen=True)
class LightSourceSpec:
    """One light source: shape, radiance, motion and modulation.

    Parameters
    ----------
    kind : {"point", "lamp", "strobe"}
    size_px : float
        Disc radius (point, strobe) or half the side of the square (lamp).
    rotation_deg : float
        Rotation of the lamp's square.
    radiance : float
        Level of the lit source on the 8-bit linear scale (255 = white; far above it).
    start : (float, float)
        Position at ``t = 0``, as fractions of the frame's width and height.
    direction_deg, travel_px : float
        Straight-line motion over the sequence.
    frequency_hz : float
        Strobe rate, or the lamp's ripple frequency; 0 for a steady light.
    depth : float
        Modulation depth: the intensity factor spans ``[1 - depth, 1]``.
    duty : float
        Strobe only: the lit fraction of a period.
    phase : float
        Modulation phase, in periods.

    Examples
    --------
    >>> s = LightSourceSpec(kind="strobe", frequency_hz=100.0, depth=1.0, duty=0.25)
    >>> s.gain(np.array([0, 1000, 3000])).tolist()
    [1.0, 1.0, 0.0]
    """

    kind: str = "point"
    size_px: float = 3.0
    rotation_deg: float = 0.0
    radiance: float = 25_500.0
    start: tuple[float, float] = (0.5, 0.5)
    direction_deg: float = 0.0
    travel_px: float = 0.0
    frequency_hz: float = 0.0
    depth: float = 0.0
    duty: float = 0.5
    phase: float = 0.0

    def __post_init__(self) -> None:
        check_choice("kind", self.kind, SOURCE_KINDS)
        check_range("size_px", self.size_px, 0, lo_open=True)
        check_range("rotation_deg", self.rotation_deg)
        check_range("radiance", self.radiance, 0, lo_open=True)
        _set_pair(self, "start")
        check_range("direction_deg", self.direction_deg)
        check_range("travel_px", self.travel_px, 0)
        check_range("frequency_hz", self.frequency_hz, 0)
        check_range("depth", self.depth, 0, 1)
        check_range("duty", self.duty, 0, 1, lo_open=True)
        check_range("phase", self.phase)

    def position_px(
        self, t_us: np.ndarray, duration_us: int, sensor_size: SensorSize
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where the source's centre is at times ``t_us`` (pixels, arrays)."""
        width, height = sensor_size
        frac = np.asarray(t_us, dtype=np.float64) / duration_us
        a = math.radians(self.direction_deg)
        x = self.start[0] * width + self.travel_px * frac * math.cos(a)
        y = self.start[1] * height + self.travel_px * frac * math.sin(a)
        return x, y

    def gain(self, t_us: np.ndarray | float) -> np.ndarray:
        """The modulation factor at times ``t_us``, in ``[1 - depth, 1]``."""
        t = np.asarray(t_us, dtype=np.float64)
        if self.frequency_hz == 0 or self.depth == 0:
            return np.ones_like(t)
        cycles = t * 1e-6 * self.frequency_hz + self.phase
        frac = cycles - np.floor(cycles)
        if self.kind == "strobe":
            lit = (frac < self.duty).astype(np.float64)
        else:
            lit = 0.5 * (1.0 + np.sin(2.0 * np.pi * frac))
        return 1.0 - self.depth * (1.0 - lit)

    def image(self, shape: tuple[int, int], center_xy: tuple[float, float]) -> np.ndarray:
        """The source as an ideal lens images it (float64 ``shape``, peak ``radiance``)."""
        if self.kind != "lamp":
            return light_source(shape, center_xy, self.size_px, self.radiance).astype(np.float64)
        rows = np.arange(shape[0], dtype=np.float64)[:, None] - center_xy[1]
        cols = np.arange(shape[1], dtype=np.float64)[None, :] - center_xy[0]
        a = math.radians(self.rotation_deg)
        u = np.abs(cols * math.cos(a) + rows * math.sin(a))
        v = np.abs(-cols * math.sin(a) + rows * math.cos(a))
        inside = np.clip(self.size_px + 0.5 - np.maximum(u, v), 0.0, 1.0)  # 1-px soft edge
        return self.radiance * inside


@dataclass(frozen=True)
class OpticsScene:
    """Everything that determines one pair apart from its background (stored as JSON).

    Parameters
    ----------
    duration_us : int
    fps : float
        Frame rate of the rendered irradiance.
    filter : {"star", "random"}
    psf : PSFConfig
        The lens with the filter; the clean lens is the same without the filter.
    psf_seed : int
        Seed of the filter's random geometry.
    sources : tuple of LightSourceSpec
    sensor : SensorSpec
        The one camera of both passes.

    Examples
    --------
    >>> s = draw_optics_scene(rng=3)
    >>> OpticsScene.from_json(s.to_json()) == s
    True
    """

    duration_us: int = 100_000
    fps: float = 4000.0
    filter: str = "star"
    psf: PSFConfig = field(default_factory=lambda: PSFConfig(star_orientations=3))
    psf_seed: int = 0
    sources: tuple[LightSourceSpec, ...] = (LightSourceSpec(),)
    sensor: SensorSpec = field(default_factory=SensorSpec)

    def __post_init__(self) -> None:
        if isinstance(self.duration_us, bool) or not isinstance(
            self.duration_us, (int, np.integer)
        ):
            raise SimError(f"duration_us must be an int, got {self.duration_us!r}")
        if self.duration_us <= 0:
            raise SimError(f"duration_us must be > 0, got {self.duration_us}")
        object.__setattr__(self, "duration_us", int(self.duration_us))
        check_range("fps", self.fps, 0, 1e6, lo_open=True)
        check_choice("filter", self.filter, FILTERS)
        if not isinstance(self.psf, PSFConfig):
            raise SimError(f"psf must be a PSFConfig, got {self.psf!r}")
        if isinstance(self.psf_seed, bool) or not isinstance(self.psf_seed, (int, np.integer)):
            raise SimError(f"psf_seed must be an int, got {self.psf_seed!r}")
        object.__setattr__(self, "sources", tuple(self.sources))
        if not all(isinstance(s, LightSourceSpec) for s in self.sources):
            raise SimError("sources must be LightSourceSpec instances")
        if not isinstance(self.sensor, SensorSpec):
            raise SimError(f"sensor must be a SensorSpec, got {self.sensor!r}")

    def frame_times_us(self) -> np.ndarray:
        """Frame timestamps ``round(i * 1e6 / fps)`` up to the duration (both ends included).

        Examples
        --------
        >>> OpticsScene(duration_us=1000, fps=4000.0).frame_times_us().tolist()
        [0, 250, 500, 750, 1000]
        """
        n = math.floor(self.duration_us * self.fps / 1e6 + 1e-9) + 1
        times = np.round(np.arange(n) * (1e6 / self.fps)).astype(np.int64)
        return times if times[-1] == self.duration_us else np.append(times, self.duration_us)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready nested dict."""
        return {
            "kind": "optics",
            "duration_us": self.duration_us,
            "fps": float(self.fps),
            "filter": self.filter,
            "psf": self.psf.to_dict(),
            "psf_seed": int(self.psf_seed),
            "sources": [_plain(s) for s in self.sources],
            "sensor": {
                "model": self.sensor.model,
                "voltmeter": self.sensor.voltmeter.to_dict(),
                "ideal": self.sensor.ideal.to_dict(),
                "seed": int(self.sensor.seed),
            },
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> OpticsScene:
        """Inverse of :meth:`to_dict`; unknown keys at any level are an error."""
        if not isinstance(data, Mapping):
            raise SimError(f"an optics scene must be a mapping, got {type(data).__name__}")
        d = dict(data)
        if d.pop("kind", "optics") != "optics":
            raise SimError(f"not an optics scene (kind {data.get('kind')!r})")
        if "psf" in d:
            d["psf"] = PSFConfig.from_dict(d["psf"])
        if "sources" in d:
            d["sources"] = tuple(
                dataclass_from_dict(LightSourceSpec, s, what="a light source") for s in d["sources"]
            )
        if "sensor" in d:
            d["sensor"] = sensor_spec_from_dict(d["sensor"])
        return dataclass_from_dict(cls, d, what="OpticsScene")

    def to_json(self) -> str:
        """The scene as JSON text (floats round-trip exactly)."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> OpticsScene:
        """Parse :meth:`to_json` output."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SimError(f"an optics scene must be JSON: {exc}") from None
        return cls.from_dict(data)


@dataclass(frozen=True)
class OpticsSceneConfig:
    """The ranges :func:`draw_optics_scene` draws from; pairs are ``(low, high)`` uniform draws.

    Sizes and distances are in pixels and meant for 640x480 (the paper's crops);
    ``radiance`` ranges are log-uniform, in multiples of white (255).

    Examples
    --------
    >>> OpticsSceneConfig.from_dict({"sources": [1, 1]}).sources
    (1, 1)
    >>> OpticsSceneConfig(kinds=("laser",))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.sim._validation.SimError: kinds must be a non-empty subset of ('point', 'lamp', ...
    """

    sources: tuple[int, int] = (1, 3)
    kinds: tuple[str, ...] = SOURCE_KINDS
    kind_weights: tuple[float, ...] = (0.35, 0.3, 0.35)
    point_radius_px: tuple[float, float] = (1.5, 4.0)
    lamp_half_side_px: tuple[float, float] = (3.0, 9.0)
    point_radiance: tuple[float, float] = (10.0, 200.0)
    lamp_radiance: tuple[float, float] = (3.0, 30.0)
    strobe_hz: tuple[float, float] = (40.0, 250.0)
    strobe_duty: tuple[float, float] = (0.2, 0.5)
    lamp_ripple_depth: tuple[float, float] = (0.02, 0.15)
    start: tuple[float, float] = (0.2, 0.8)
    travel_px: tuple[float, float] = (0.0, 150.0)
    star_probability: float = 0.5
    star_period: tuple[float, float] = (0.025, 0.06)
    star_line_width: tuple[float, float] = (0.1, 0.25)
    star_transmission: tuple[float, float] = (0.1, 0.5)
    star_jitter: tuple[float, float] = (0.1, 0.4)
    random_phase_rms: tuple[float, float] = (0.3, 1.0)
    random_phase_scale: tuple[float, float] = (0.02, 0.1)
    random_dust: tuple[int, int] = (0, 30)
    defocus_waves: tuple[float, float] = (0.0, 0.25)
    psf_grid: int = 512
    frames_per_period: float = 16.0
    fps: tuple[float, float] = (2000.0, 6000.0)
    sensor_model: str = "voltmeter"
    k1: tuple[float, float] = (5.0, 10.0)
    ideal_threshold: tuple[float, float] = (0.15, 0.35)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "kinds":
                if not value or any(k not in SOURCE_KINDS for k in value):
                    raise SimError(f"kinds must be a non-empty subset of {SOURCE_KINDS}")
                object.__setattr__(self, f.name, tuple(value))
            elif f.name == "kind_weights":
                w = tuple(float(v) for v in value)
                if len(w) != len(self.kinds) or min(w) < 0 or sum(w) <= 0:
                    raise SimError(
                        f"kind_weights must be {len(self.kinds)} weights >= 0 (one per kind), "
                        f"got {value!r}"
                    )
                object.__setattr__(self, f.name, w)
            elif f.name == "sensor_model":
                check_choice("sensor_model", value, ("voltmeter", "ideal"))
            elif f.name == "psf_grid":
                if isinstance(value, bool) or not isinstance(value, int) or value < 16:
                    raise SimError(f"psf_grid must be an int >= 16, got {value!r}")
            elif f.name.endswith("probability"):
                check_range(f.name, value, 0, 1)
            elif isinstance(f.default, tuple):
                object.__setattr__(self, f.name, check_interval(f.name, value, f.default))
            else:
                check_range(f.name, value, 0, lo_open=True)
        if self.sources[0] < 1:
            raise SimError(f"sources must be at least 1, got {self.sources!r}")
        if min(self.point_radiance[0], self.lamp_radiance[0], self.fps[0], self.strobe_hz[0]) <= 0:
            raise SimError("radiance, fps and strobe_hz ranges must be > 0 (log-uniform draws)")
        if self.strobe_duty[1] > 1 or self.lamp_ripple_depth[1] > 1:
            raise SimError("strobe_duty and lamp_ripple_depth must lie in [0, 1]")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> OpticsSceneConfig:
        """Build from a mapping (e.g. a manifest's recipe); unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (lists for tuples)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in _fields(self).items()}


def _fields(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def draw_optics_scene(
    config: OpticsSceneConfig | None = None,
    *,
    duration_us: int = 100_000,
    rng: np.random.Generator | int | None = None,
) -> OpticsScene:
    """Draw one scene: filter, lens, sources and camera.

    Parameters
    ----------
    config : OpticsSceneConfig, optional
    duration_us : int
    rng : numpy.random.Generator or int, optional

    Examples
    --------
    >>> a, b = draw_optics_scene(rng=5), draw_optics_scene(rng=5)
    >>> a == b, a.filter in FILTERS, 1 <= len(a.sources) <= 3
    (True, True, True)
    """
    cfg = config or OpticsSceneConfig()
    g = make_rng(rng)
    u = lambda pair: float(g.uniform(*pair))  # noqa: E731
    logu = lambda pair: float(np.exp(g.uniform(*np.log(pair))))  # noqa: E731
    star = bool(g.random() < cfg.star_probability)
    common = {"grid": cfg.psf_grid, "defocus_waves": u(cfg.defocus_waves)}
    if star:
        psf = PSFConfig(
            **common,
            star_orientations=3,
            star_rotation_deg=u((0.0, 60.0)),
            star_period=u(cfg.star_period),
            star_line_width=u(cfg.star_line_width),
            star_transmission=u(cfg.star_transmission),
            star_jitter=u(cfg.star_jitter),
        )
    else:
        psf = PSFConfig(
            **common,
            random_phase_rms=u(cfg.random_phase_rms),
            random_phase_scale=u(cfg.random_phase_scale),
            dust_count=int(g.integers(cfg.random_dust[0], cfg.random_dust[1] + 1)),
        )
    psf_seed = int(g.integers(0, 2**63))
    weights = np.asarray(cfg.kind_weights) / sum(cfg.kind_weights)
    sources = []
    for _ in range(int(g.integers(cfg.sources[0], cfg.sources[1] + 1))):
        kind = cfg.kinds[int(g.choice(len(cfg.kinds), p=weights))]
        motion = {
            "start": (u(cfg.start), u(cfg.start)),
            "direction_deg": u((0.0, 360.0)),
            "travel_px": u(cfg.travel_px),
            "phase": float(g.random()),
        }
        if kind == "lamp":
            spec = LightSourceSpec(
                kind=kind,
                size_px=u(cfg.lamp_half_side_px),
                rotation_deg=u((0.0, 90.0)),
                radiance=WHITE * logu(cfg.lamp_radiance),
                frequency_hz=float(g.choice([100.0, 120.0])),  # twice the mains frequency
                depth=u(cfg.lamp_ripple_depth),
                **motion,
            )
        elif kind == "strobe":
            spec = LightSourceSpec(
                kind=kind,
                size_px=u(cfg.point_radius_px),
                radiance=WHITE * logu(cfg.point_radiance),
                frequency_hz=logu(cfg.strobe_hz),
                depth=1.0,
                duty=u(cfg.strobe_duty),
                **motion,
            )
        else:
            spec = LightSourceSpec(
                kind=kind,
                size_px=u(cfg.point_radius_px),
                radiance=WHITE * logu(cfg.point_radiance),
                **motion,
            )
        sources.append(spec)
    strobes = [s.frequency_hz for s in sources if s.kind == "strobe"]
    fps = cfg.fps[0]
    if strobes:
        fps = min(max(cfg.frames_per_period * max(strobes), cfg.fps[0]), cfg.fps[1])
    c = u(cfg.ideal_threshold)
    sensor = SensorSpec(
        model=cfg.sensor_model,
        voltmeter=VoltmeterParams(k=(u(cfg.k1), *DVS346_K[1:])),
        ideal=IdealParams(c_on=c, c_off=c, c_sigma=0.03),
        seed=int(g.integers(0, 2**63)),
    )
    return OpticsScene(
        duration_us=int(duration_us),
        fps=float(fps),
        filter="star" if star else "random",
        psf=psf,
        psf_seed=psf_seed,
        sources=tuple(sources),
        sensor=sensor,
    )


# ------------------------------------------------------------------------------ rendering


@dataclass(frozen=True)
class _Template:
    """A source through one lens: image (zero border of 2 px) and where its centre sits."""

    image: np.ndarray
    anchor: tuple[float, float]


def _template(source: LightSourceSpec, psf: np.ndarray) -> _Template:
    margin = math.ceil(1.5 * source.size_px) + 4
    size = psf.shape[0] + 2 * margin
    c = size // 2
    img = scattering_flare(source.image((size, size), (c, c)), psf)
    rows = np.flatnonzero((img > _FLOOR).any(axis=1))
    cols = np.flatnonzero((img > _FLOOR).any(axis=0))
    if rows.size == 0:  # a source too dim to register anywhere
        return _Template(np.zeros((5, 5), np.float32), (2.0, 2.0))
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    cut = np.pad(np.ascontiguousarray(img[r0:r1, c0:c1], dtype=np.float32), 2)
    return _Template(cut, (float(c - c0 + 2), float(c - r0 + 2)))


class OpticsRenderer:
    """Irradiance frames of one scene through the filtered and the clean lens.

    Parameters
    ----------
    scene : OpticsScene
    sensor_size : (width, height)
    street : NightStreet, optional
        A synthetic background imaged with the sources; None for a dark scene.

    Examples
    --------
    >>> scene = OpticsScene(duration_us=1000, psf=PSFConfig(grid=64, star_orientations=3))
    >>> ob, gt = OpticsRenderer(scene, (48, 32)).frame(0)
    >>> ob.shape, bool(ob.max() == gt.max() == 255.0), bool((ob > 50).sum() > (gt > 50).sum())
    ((32, 48), True, True)
    """

    def __init__(
        self,
        scene: OpticsScene,
        sensor_size: SensorSize,
        *,
        street: NightStreet | None = None,
    ) -> None:
        if not isinstance(scene, OpticsScene):
            raise SimError(f"scene must be an OpticsScene, got {type(scene).__name__}")
        self.scene = scene
        self.sensor_size = check_sensor_size(sensor_size)
        pair = psf_pair(scene.psf, rng=scene.psf_seed)
        self.psfs = {"ob": pair.perturbed, "gt": pair.clean}
        """The two PSFs ``(grid, grid)``, unit sum: ``"ob"`` (filter) and ``"gt"`` (clean)."""
        self.templates = {
            lens: [_template(s, self.psfs[lens]) for s in scene.sources] for lens in _LENSES
        }
        self.streets: dict[str, NightStreet] | None = None
        if street is not None:
            self.streets = {lens: _blurred(street, self.psfs[lens]) for lens in _LENSES}

    def sources_frame(self, t_us: int, lens: str) -> np.ndarray:
        """The sources alone through ``lens`` (``"ob"`` or ``"gt"``), unclipped, float32."""
        width, height = self.sensor_size
        out = np.zeros((height, width), dtype=np.float32)
        self._add_sources(out, t_us, lens)
        return out

    def _add_sources(self, out: np.ndarray, t_us: int, lens: str) -> None:
        t = np.array([t_us], dtype=np.float64)
        for src, tpl in zip(self.scene.sources, self.templates[lens], strict=True):
            gain = float(src.gain(t)[0])
            if gain <= 0:
                continue
            px, py = src.position_px(t, self.scene.duration_us, self.sensor_size)
            ax, ay = tpl.anchor
            _warp_add(tpl.image, out, 1.0, 0.0, 0.0, 1.0, float(px[0]), float(py[0]), ax, ay, gain)

    def frame(self, t_us: int) -> tuple[np.ndarray, np.ndarray]:
        """The observation and ground-truth irradiance at ``t_us``: float32 ``(H, W)``, clipped."""
        out = []
        for lens in _LENSES:
            if self.streets is not None:
                img = self.streets[lens].frame(t_us)
            else:
                width, height = self.sensor_size
                img = np.zeros((height, width), dtype=np.float32)
            self._add_sources(img, t_us, lens)
            out.append(np.minimum(img, WHITE, out=img))
        return out[0], out[1]

    def __iter__(self) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        for t in self.scene.frame_times_us().tolist():
            ob, gt = self.frame(t)
            yield t, ob, gt


def _blurred(street: NightStreet, psf: np.ndarray) -> NightStreet:
    """The street as seen through ``psf``: its texture convolved (edges mirrored)."""
    half = psf.shape[0] // 2
    tex = np.pad(street.texture.astype(np.float64), half, mode="reflect")
    tex = scattering_flare(tex, psf)[half:-half, half:-half]
    view = copy.copy(street)  # same camera motion, another texture
    view.texture = np.ascontiguousarray(tex, dtype=np.float32)
    return view


class SourceIntensity:
    """The sources' irradiance through one lens at any events (an intensity field for PNL-ES).

    Each source's template is sampled bilinearly at the event's pixel relative to
    the source's position at the event's own time, scaled by its modulation; the
    sum is clipped at :data:`~edeflare.sim.flare.WHITE` as the frames are.
    """

    def __init__(self, renderer: OpticsRenderer, lens: str) -> None:
        self.renderer = renderer
        self.lens = check_choice("lens", lens, _LENSES)

    def sample(self, events: np.ndarray) -> np.ndarray:
        """Intensity at each event's ``(t, x, y)``, float64."""
        r = self.renderer
        t = events["t"].astype(np.float64)
        total = np.zeros(events.size)
        for src, tpl in zip(r.scene.sources, r.templates[self.lens], strict=True):
            px, py = src.position_px(t, r.scene.duration_us, r.sensor_size)
            qx = events["x"] - px + tpl.anchor[0]
            qy = events["y"] - py + tpl.anchor[1]
            values = ndimage.map_coordinates(
                tpl.image.astype(np.float64), [qy, qx], order=1, mode="constant", cval=0.0
            )
            total += src.gain(t) * values
        return np.minimum(total, WHITE)


# ------------------------------------------------------------------------------- events


@dataclass(frozen=True)
class OpticsPair:
    """The two streams of one scene and where the time went.

    Attributes
    ----------
    input, gt : numpy.ndarray
        :math:`E_{ob}` and :math:`E_{gt}`, sorted, times in ``[0, duration_us)``.
    seconds : dict
        Seconds spent per stage: ``render``, ``simulate``, ``compose``.
    frames : numpy.ndarray or None
        float32 ``(T, H, W)``: the clean lens's intensity image (the scene the
        ground truth sees, 0-255 scale) at each of ``frame_times_us``; None
        when none were asked for or the background is recorded (no image of it).
    """

    input: np.ndarray
    gt: np.ndarray
    seconds: dict[str, float]
    frames: np.ndarray | None = None


def _noise(rate_hz: float, size: SensorSize, duration_us: int, gen: np.random.Generator):
    """Poisson background activity: ``rate_hz`` per pixel, random polarity, sorted."""
    width, height = size
    n = int(gen.poisson(rate_hz * width * height * duration_us * 1e-6))
    out = np.empty(n, dtype=EVENT_DTYPE)
    out["t"] = gen.integers(0, duration_us, n)
    out["x"] = gen.integers(0, width, n)
    out["y"] = gen.integers(0, height, n)
    out["p"] = gen.integers(0, 2, n)
    return out[np.argsort(out["t"], kind="stable")]


def simulate_optics_pair(
    scene: OpticsScene,
    sensor_size: SensorSize,
    *,
    background: NightStreet | Background | None = None,
    rng: np.random.Generator | int | None = None,
    frame_times_us: Sequence[int] | np.ndarray | None = None,
) -> OpticsPair:
    r"""Simulate :math:`E_{ob}` and :math:`E_{gt}` of one scene (see the module docstring).

    Parameters
    ----------
    scene : OpticsScene
    sensor_size : (width, height)
    background : NightStreet or Background, optional
        A synthetic street (imaged through both lenses with the sources), recorded
        background events (fused with the sources' events by PNL-ES), or None
        (the sources in the dark).
    rng : numpy.random.Generator or int, optional
        Draws the street's background-activity noise or the PNL-ES draws.
    frame_times_us : sequence of int, optional
        Keep the clean lens's image at these instants (sorted), e.g. the
        windows' ends: ground truth for reconstructions (``OpticsPair.frames``).
        Ignored with a recorded background.

    Returns
    -------
    OpticsPair

    Examples
    --------
    >>> scene = draw_optics_scene(OpticsSceneConfig(psf_grid=64), duration_us=5_000, rng=2)
    >>> street = NightStreet((48, 32), rng=0)
    >>> a = simulate_optics_pair(scene, (48, 32), background=street, rng=0)
    >>> b = simulate_optics_pair(scene, (48, 32), background=street, rng=0)
    >>> bool(np.array_equal(a.input, b.input)), a.gt.size > 0, int(a.gt["t"].max()) < 5_000
    (True, True, True)
    """
    size = check_sensor_size(sensor_size)
    gen = make_rng(rng)
    timer = StageTimer(("render", "simulate", "compose"))
    street = background if isinstance(background, NightStreet) else None
    with timer("render"):
        renderer = OpticsRenderer(scene, size, street=street)
    # One camera: both passes get simulators seeded identically (same per-pixel streams).
    recorders = [
        EventRecorder(
            camera_simulator(
                scene.sensor,
                size,
                rng=np.random.default_rng(np.random.SeedSequence(scene.sensor.seed)),
            ),
            lens,
        )
        for lens in _LENSES
    ]
    recorded = isinstance(background, Background)

    def frames() -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        for t in scene.frame_times_us().tolist():
            if recorded:
                images = [np.minimum(renderer.sources_frame(t, lens), WHITE) for lens in _LENSES]
            else:
                images = list(renderer.frame(t))
            yield t, dict(zip(_LENSES, images, strict=True))

    snapshots = (
        FrameRecorder(frame_times_us, "gt") if frame_times_us is not None and not recorded else None
    )
    observers = [*recorders, snapshots] if snapshots is not None else recorders
    run_frames(frames(), observers, timer=timer)
    duration = scene.duration_us
    with timer("compose"):
        ob, gt = (rec.events(duration) for rec in recorders)
        if street is not None:
            noise = _noise(float(street.params["noise_rate_hz"]), size, duration, gen)
            ob, gt = merge_events(ob, noise), merge_events(gt, noise)
        elif recorded:
            assert isinstance(background, Background)
            components = Components.from_fields(
                {"background": background.events, "flare": ob, "light": gt},
                {
                    "background": background.intensity,
                    "flare": SourceIntensity(renderer, "ob"),
                    "light": SourceIntensity(renderer, "gt"),
                },
                0,
                duration,
            )
            ob, gt = compose_pair(components, "physical", rng=gen)
    return OpticsPair(ob, gt, timer.seconds, snapshots.images if snapshots is not None else None)
