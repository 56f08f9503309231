r"""Background event sources for stage 2: recorded event files, or a synthetic night street.

A source's :meth:`draw` returns a :class:`Background`: the events of one
sequence (times shifted to start at 0, on the target sensor), an intensity
field for PNL-ES (:mod:`edeflare.sim.compose`), a JSON-ready description, and
for synthetic scenes the intensity video itself (for the full forward model).

Recorded events (:class:`RecordedBackground`)
---------------------------------------------
Any file :func:`edeflare.io.open_events` reads (DSEC ``events.h5``,
``.raw``, ``.aedat4``, ``.dat``, ``.es``, ``.csv``...). Each draw picks a file
with probability proportional to its usable span, a uniform start, and cuts
``duration_us`` from it (the paper's windows are 50-100 ms); the sensor is
centre-cropped or zero-padded to the target size. DSEC files are read window
by window through their index; other formats are decoded once per process and
kept in memory. The intensity for PNL-ES is estimated from the events
(:class:`~edeflare.sim.compose.AccumulatedIntensity` by default, or the
authors' :class:`~edeflare.sim.compose.CountIntensity`).

Synthetic night street (:class:`SyntheticBackground`)
-----------------------------------------------------
No download needed. A procedural texture on the 8-bit linear scale of the
rendered flare (white = 255): a dark sky brightening towards the horizon,
buildings with edges and a grid of windows (a fraction lit, 60-230), a dark
road with perspective lane markings, poles with street lamps, and multiplicative
value noise at several scales. A camera drives through it: expansion about a
focus near the vanishing point (forward motion) at ``zoom_per_s``, a pan at
``pan_px_per_s`` and a small vertical shake, so sensor pixel :math:`p` sees
texture point

.. math::

    q(p, t) = c_0 + (p - f)\,e^{-z t} + v t + (0, a \sin(2\pi \nu t + \phi)).

Frames at ``fps`` go through the sample's own camera (the script's sensor
spec, its own random stream) and Poisson background-activity noise is added
(``noise_rate_hz`` per pixel, random polarity). Event rates come out at
about 2 M events/s at 640x480 (median; 1-10 across scenes). The intensity
field is the texture sampled exactly at each event (no estimate needed), and
:meth:`Background.video` renders any frame for the forward model.

Where ``SceneConfig.near_objects`` asks for them, one or more :class:`NearObject` (large
textured ellipses close to the camera, a head or a passer-by) swing fast in front of the
street: scene, not light, that fills much of the frame and moves fast.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numba
import numpy as np
from scipy import ndimage

from ..errors import EventFileError
from ..events import EVENT_DTYPE, SensorSize, check_sensor_size, slice_time
from ..io import open_events
from ..io.dsec import DsecReader
from ._validation import (
    SimError,
    check_choice,
    check_interval,
    check_range,
    dataclass_from_dict,
    make_rng,
)
from .camera import camera_simulator
from .compose import AccumulatedIntensity, AccumulationParams, CountIntensity, IntensityField
from .pair import EventRecorder, run_frames
from .script import SensorSpec

__all__ = [
    "INTENSITY_ESTIMATORS",
    "Background",
    "BackgroundSource",
    "NearObject",
    "NightStreet",
    "RecordedBackground",
    "SceneConfig",
    "SyntheticBackground",
    "fit_to_sensor",
    "relative_names",
]

INTENSITY_ESTIMATORS = ("accumulation", "counts", "video")
"""How a background's intensity for PNL-ES is obtained (``video``: synthetic scenes only)."""


@dataclass(frozen=True)
class Background:
    """One sequence's background.

    Attributes
    ----------
    events : numpy.ndarray
        Times in ``[0, duration_us)``, on ``sensor_size``.
    intensity : IntensityField
        Linear intensity at any events (8-bit scale), for PNL-ES.
    sensor_size : (width, height)
    duration_us : int
    description : dict
        JSON-ready provenance (source kind, file, start, crop, scene parameters).
    video : callable ``t_us -> (H, W) float32`` or None
        The intensity frame at any time (synthetic scenes only).
    """

    events: np.ndarray
    intensity: IntensityField
    sensor_size: SensorSize
    duration_us: int
    description: dict[str, Any]
    video: Callable[[int], np.ndarray] | None = None


class BackgroundSource(Protocol):
    """Draws backgrounds: :class:`RecordedBackground`, :class:`SyntheticBackground`."""

    def draw(
        self,
        duration_us: int,
        sensor_size: SensorSize,
        sensor: SensorSpec | None = None,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> Background:
        """One background of ``duration_us`` on ``sensor_size``; ``sensor``: the camera."""
        ...  # pragma: no cover

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings (for a dataset manifest)."""
        ...  # pragma: no cover


def _duration(duration_us: Any) -> int:
    if isinstance(duration_us, bool) or not isinstance(duration_us, (int, np.integer)):
        raise SimError(f"duration_us must be an int, got {duration_us!r}")
    if duration_us <= 0:
        raise SimError(f"duration_us must be > 0, got {duration_us}")
    return int(duration_us)


def fit_to_sensor(
    events: np.ndarray, sensor_size: SensorSize, target: SensorSize
) -> tuple[np.ndarray, tuple[int, int]]:
    """Centre ``events`` of ``sensor_size`` on ``target``: crop what exceeds, pad what is short.

    Returns the new events and the ``(dx, dy)`` offset added to the coordinates.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1], [0, 3], [0, 1], [1, 1])
    >>> out, offset = fit_to_sensor(ev, (6, 2), (4, 4))
    >>> out[["x", "y"]].tolist(), offset
    ([(2, 2)], (-1, 1))
    """
    width, height = check_sensor_size(sensor_size)
    tw, th = check_sensor_size(target)
    dx, dy = (tw - width) // 2, (th - height) // 2
    x = events["x"].astype(np.int64) + dx
    y = events["y"].astype(np.int64) + dy
    keep = (x >= 0) & (x < tw) & (y >= 0) & (y < th)
    out = events[keep]
    out["x"] = x[keep]
    out["y"] = y[keep]
    return out, (dx, dy)


# ---------------------------------------------------------------------------- recorded


def relative_names(paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    """Paths relative to their common folder (a lone file: its name), in POSIX form.

    Provenance recorded this way does not depend on where the data lives, and
    DSEC's many ``events.h5`` stay distinct.

    Examples
    --------
    >>> relative_names(["/d/zurich_00/events.h5", "/d/interlaken_00/events.h5"])
    ['zurich_00/events.h5', 'interlaken_00/events.h5']
    >>> relative_names(["data/drive.raw"])
    ['drive.raw']
    """
    absolute = [Path(os.path.abspath(p)) for p in paths]
    if len(absolute) == 1:
        return [absolute[0].name]
    root = Path(os.path.commonpath([p.parent for p in absolute]))
    return [p.relative_to(root).as_posix() for p in absolute]


_CACHE: dict[tuple[str, int, int], tuple[np.ndarray, SensorSize]] = {}
_CACHE_FILES = 8


class RecordedBackground:
    """Random windows of recorded event files (see the module docstring).

    Parameters
    ----------
    paths : sequence of path-like
        Event files of any format :mod:`edeflare.io` reads.
    sensor_size : (width, height), optional
        For files that record no sensor size (else inferred, with a warning).
    intensity : {"accumulation", "counts"}
        The PNL-ES intensity estimator of the background.
    accumulation : AccumulationParams, optional
        Parameters of the accumulation estimator.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.io import write_events
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "drive.npz"
    >>> i = np.arange(1000)
    >>> write_events(path, make_events(i * 200, i % 8, i % 6, i % 2), (8, 6))
    >>> bg = RecordedBackground([path]).draw(50_000, (4, 4), rng=0)
    >>> ev = bg.events
    >>> ev.size > 0, 0 <= int(ev["t"].min()) <= int(ev["t"].max()) < 50_000, int(ev["x"].max()) < 4
    (True, True, True)
    """

    def __init__(
        self,
        paths: Sequence[str | os.PathLike[str]],
        *,
        sensor_size: SensorSize | None = None,
        intensity: str = "accumulation",
        accumulation: AccumulationParams | None = None,
    ) -> None:
        if isinstance(paths, (str, os.PathLike)):
            paths = [paths]
        self.paths = [Path(p) for p in paths]
        if not self.paths:
            raise SimError("RecordedBackground needs at least one event file")
        self.names = relative_names(self.paths)
        """Names of the files that do not depend on where they live (see :func:`relative_names`)."""
        self.sensor_size = None if sensor_size is None else check_sensor_size(sensor_size)
        self.intensity = check_choice("intensity", intensity, ("accumulation", "counts"))
        self.accumulation = accumulation or AccumulationParams()
        self._spans: list[tuple[int, int]] = []
        self._sizes: list[SensorSize] = []
        for path in self.paths:
            source = open_events(path, self.sensor_size)
            self._sizes.append(source.sensor_size)
            self._spans.append(self._span(path, source))

    def _span(self, path: Path, source: Any) -> tuple[int, int]:
        if _is_dsec(path):
            with DsecReader(path) as reader:
                span = reader.time_range()
        else:
            events, _ = self._load(path)
            span = (int(events["t"][0]), int(events["t"][-1])) if events.size else None
        if span is None:
            raise EventFileError(path, "holds no events; it cannot serve as a background")
        return span[0], span[1] + 1

    def _load(self, path: Path) -> tuple[np.ndarray, SensorSize]:
        stat = path.stat()
        key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
        if key not in _CACHE:
            if len(_CACHE) >= _CACHE_FILES:
                _CACHE.pop(next(iter(_CACHE)))
            source = open_events(path, self.sensor_size)
            _CACHE[key] = (source.read(), source.sensor_size)
        return _CACHE[key]

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings."""
        return {
            "kind": "recorded",
            "files": list(self.names),
            "intensity": self.intensity,
            "accumulation": self.accumulation.to_dict(),
        }

    def draw(
        self,
        duration_us: int,
        sensor_size: SensorSize,
        sensor: SensorSpec | None = None,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> Background:
        """A random window of ``duration_us`` from one of the files (``sensor`` is unused)."""
        duration = _duration(duration_us)
        target = check_sensor_size(sensor_size)
        gen = make_rng(rng)
        usable = np.array([max(0, (b - a) - duration + 1) for a, b in self._spans], dtype=float)
        if usable.sum() <= 0:
            longest = max(b - a for a, b in self._spans)
            raise SimError(
                f"no background file spans {duration} µs (the longest spans {longest} µs); "
                "use shorter sequences or longer recordings"
            )
        i = int(gen.choice(len(self.paths), p=usable / usable.sum()))
        path = self.paths[i]
        start = self._spans[i][0] + int(gen.integers(0, int(usable[i])))
        if _is_dsec(path):
            with DsecReader(path) as reader:
                events = reader.read_time(start, start + duration)
        else:
            events = slice_time(self._load(path)[0], start, start + duration).copy()
        events["t"] -= start
        events, offset = fit_to_sensor(events, self._sizes[i], target)
        if self.intensity == "accumulation":
            field: IntensityField = AccumulatedIntensity(
                events, target, 0, duration, self.accumulation
            )
        else:
            field = CountIntensity(events, target, floor=1e-3)
        description = {
            "kind": "recorded",
            "file": self.names[i],
            "start_us": start,
            "duration_us": duration,
            "source_sensor_size": list(self._sizes[i]),
            "offset_xy": list(offset),
            "intensity": self.intensity,
        }
        return Background(events, field, target, duration, description)


def _is_dsec(path: Path) -> bool:
    return path.suffix.lower() in (".h5", ".hdf5")


# ---------------------------------------------------------------------------- synthetic


@dataclass(frozen=True)
class SceneConfig:
    """Ranges of the synthetic night street; pairs are ``(low, high)`` of uniform draws.

    Examples
    --------
    >>> SceneConfig.from_dict({"fps": 1000.0}).fps
    1000.0
    """

    margin: float = 0.35
    horizon: tuple[float, float] = (0.38, 0.5)
    sky_level: tuple[float, float] = (1.5, 5.0)
    building_level: tuple[float, float] = (8.0, 35.0)
    window_lit_fraction: tuple[float, float] = (0.1, 0.4)
    window_level: tuple[float, float] = (60.0, 230.0)
    road_level: tuple[float, float] = (10.0, 30.0)
    marking_level: tuple[float, float] = (40.0, 110.0)
    lamps: tuple[int, int] = (1, 5)
    lamp_level: tuple[float, float] = (150.0, 255.0)
    texture_contrast: tuple[float, float] = (0.15, 0.4)
    zoom_per_s: tuple[float, float] = (0.0, 0.8)
    pan_px_per_s: tuple[float, float] = (20.0, 250.0)
    shake_px: tuple[float, float] = (0.0, 1.5)
    shake_hz: tuple[float, float] = (2.0, 12.0)
    noise_rate_hz: tuple[float, float] = (0.05, 0.5)
    fps: float = 2000.0
    near_objects: tuple[int, int] = (0, 0)
    near_height: tuple[float, float] = (0.3, 0.8)
    near_speed_px_per_s: tuple[float, float] = (300.0, 3000.0)
    near_level: tuple[float, float] = (15.0, 120.0)
    near_contrast: tuple[float, float] = (0.3, 0.9)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(f.default, tuple):
                object.__setattr__(self, f.name, check_interval(f.name, value, f.default))
        check_range("margin", self.margin, 0, 4)
        check_range("fps", self.fps, 1, 1e6)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SceneConfig:
        """Build from a mapping; unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (without the ``near_*`` fields where there is no near object, so
        that a scene without one keeps the digest it had before they existed)."""
        d = {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}
        if self.near_objects[1] == 0:
            d = {k: v for k, v in d.items() if not k.startswith("near_")}
        return d


def _value_noise(shape: tuple[int, int], scale: float, gen: np.random.Generator) -> np.ndarray:
    """Smooth noise of unit standard deviation with features of about ``scale`` pixels."""
    noise = ndimage.gaussian_filter(gen.standard_normal(shape), scale, mode="wrap")
    return noise / max(float(noise.std()), 1e-12)


class NightStreet:
    """A procedural night street and a moving camera (see the module docstring).

    Parameters
    ----------
    sensor_size : (width, height)
    config : SceneConfig, optional
    rng : numpy.random.Generator or int, optional
        Draws the scene and the motion.

    Examples
    --------
    >>> scene = NightStreet((64, 48), rng=0)
    >>> frame = scene.frame(0)
    >>> frame.shape, frame.dtype, bool(0 < np.median(frame) < 60)
    ((48, 64), dtype('float32'), True)
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        config: SceneConfig | None = None,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        self.config = cfg = config or SceneConfig()
        gen = make_rng(rng)
        u = lambda pair: float(gen.uniform(*pair))  # noqa: E731
        width, height = self.sensor_size
        mx, my = round(cfg.margin * width) + 4, round(cfg.margin * height) + 4
        tw, th = width + 2 * mx, height + 2 * my
        self.params: dict[str, Any] = {
            "horizon": u(cfg.horizon),
            "sky_level": u(cfg.sky_level),
            "building_level": u(cfg.building_level),
            "window_lit_fraction": u(cfg.window_lit_fraction),
            "road_level": u(cfg.road_level),
            "texture_contrast": u(cfg.texture_contrast),
            "zoom_per_s": u(cfg.zoom_per_s),
            "pan_px_per_s": u(cfg.pan_px_per_s),
            "pan_direction_deg": u((0.0, 360.0)),
            "shake_px": u(cfg.shake_px),
            "shake_hz": u(cfg.shake_hz),
            "shake_phase": u((0.0, 2 * math.pi)),
            "focus": (u((0.4, 0.6)) * width, 0.0),
            "noise_rate_hz": u(cfg.noise_rate_hz),
        }
        p = self.params
        horizon_row = p["horizon"] * th
        p["focus"] = (p["focus"][0], p["horizon"] * height)
        self.texture = self._paint(tw, th, horizon_row, gen)
        # Texture point under the focus of expansion at t = 0.
        self._c0 = (p["focus"][0] + mx, p["focus"][1] + my)
        a = math.radians(p["pan_direction_deg"])
        speed = p["pan_px_per_s"] * 1e-6
        self._v = (speed * math.cos(a), speed * math.sin(a) * 0.3)  # mostly horizontal pans
        # Near objects: drawn only when asked, after every other draw, so that a scene
        # without them draws exactly what it drew before they existed.
        self.objects: list[NearObject] = []
        if cfg.near_objects[1] > 0:
            n = int(gen.integers(cfg.near_objects[0], cfg.near_objects[1] + 1))
            self.objects = [NearObject.draw(self.sensor_size, cfg, gen) for _ in range(n)]

    # -- the texture ---------------------------------------------------------------------
    def _paint(self, tw: int, th: int, hz: float, gen: np.random.Generator) -> np.ndarray:
        cfg, p = self.config, self.params
        u = lambda pair: float(gen.uniform(*pair))  # noqa: E731
        rows = np.arange(th, dtype=np.float64)[:, None]
        cols = np.arange(tw, dtype=np.float64)[None, :]
        sky = p["sky_level"] * (1.0 + 2.0 * np.exp(-np.maximum(hz - rows, 0) / (0.12 * th)))
        img = np.broadcast_to(sky, (th, tw)).copy()
        # Road: below the horizon, slightly brighter towards the camera.
        below = rows >= hz
        road = p["road_level"] * (0.7 + 0.6 * np.clip((rows - hz) / max(th - hz, 1), 0, 1))
        img = np.where(below, road, img)
        # Lane markings: lines from the vanishing point, dashed in perspective.
        vx = tw / 2
        depth = np.maximum(rows - hz, 1e-3)
        for slope in gen.uniform(-3.0, 3.0, int(gen.integers(2, 5))):
            x_line = vx + slope * depth
            half = 0.5 + 0.012 * depth
            dashed = np.floor(np.log(depth + 1.0) * 6.0) % 2 == 0
            on = below & (np.abs(cols - x_line) <= half) & dashed
            img = np.where(on, u(cfg.marking_level), img)
        # Buildings along the horizon, with edges and windows.
        x = 0.0
        while x < tw:
            bw = u((0.05, 0.16)) * tw
            bh = u((0.08, 0.35)) * th
            level = u(cfg.building_level)
            x0, x1 = int(x), int(min(tw, x + bw))
            y0, y1 = int(max(0, hz - bh)), int(min(th, hz + 0.02 * th))
            if gen.random() < 0.85:
                img[y0:y1, x0:x1] = level
                img[y0:y1, x0 : min(x0 + 1, x1)] = 0.4 * level  # edges
                img[y0:y1, max(x1 - 1, x0) : x1] = 0.4 * level
                img[y0 : min(y0 + 1, y1), x0:x1] = 0.4 * level
                sx, sy = int(gen.integers(9, 18)), int(gen.integers(10, 20))
                ww, wh = int(gen.integers(3, max(4, sx - 3))), int(gen.integers(4, max(5, sy - 4)))
                for wy in range(y0 + 4, y1 - wh - 2, sy):
                    for wx in range(x0 + 3, x1 - ww - 2, sx):
                        lit = gen.random() < p["window_lit_fraction"]
                        img[wy : wy + wh, wx : wx + ww] = (
                            u(cfg.window_level) if lit else 0.5 * level
                        )
            x += bw + u((0.0, 0.03)) * tw
        # Poles with street lamps.
        for _ in range(int(gen.integers(cfg.lamps[0], cfg.lamps[1] + 1))):
            px = u((0.0, tw))
            top = hz - u((0.15, 0.4)) * th
            pole = (np.abs(cols - px) <= 1.0) & (rows >= top) & (rows <= hz + 0.1 * th)
            img = np.where(pole, 0.5 * p["building_level"], img)
            r2 = (cols - px) ** 2 + (rows - top) ** 2
            img = img + u(cfg.lamp_level) * np.exp(-r2 / (2 * 2.5**2))
            img = img + 0.08 * u(cfg.lamp_level) * np.exp(-r2 / (2 * 12.0**2))
        # Texture: multiplicative value noise at three scales.
        c = p["texture_contrast"]
        shape = (th, tw)
        noise = (
            0.5 * _value_noise(shape, 1.0, gen)
            + 0.35 * _value_noise(shape, 4.0, gen)
            + 0.15 * _value_noise(shape, 16.0, gen)
        )
        img = img * np.exp(c * noise)
        return np.clip(img, 0.5, None).astype(np.float32)

    # -- the camera ----------------------------------------------------------------------
    def _map(self, t_us: float) -> tuple[float, float, float, float, float]:
        """``(scale, fx, fy, ox, oy)``: texture point ``(o + (p - f) * scale)`` of pixel ``p``."""
        p = self.params
        scale = math.exp(-p["zoom_per_s"] * t_us * 1e-6)
        shake = p["shake_px"] * math.sin(
            2 * math.pi * p["shake_hz"] * t_us * 1e-6 + p["shake_phase"]
        )
        ox = self._c0[0] + self._v[0] * t_us
        oy = self._c0[1] + self._v[1] * t_us + shake
        return scale, p["focus"][0], p["focus"][1], ox, oy

    def frame(self, t_us: float) -> np.ndarray:
        """The intensity frame ``(H, W)`` float32 at ``t_us``."""
        width, height = self.sensor_size
        out = np.empty((height, width), dtype=np.float32)
        _render(self.texture, out, *self._map(float(t_us)))
        for obj in self.objects:
            _paste(obj.texture, out, *obj.centre(float(t_us)), obj.ax, obj.ay)
        return out

    def sample(self, events: np.ndarray) -> np.ndarray:
        """The exact intensity at each event's ``(t, x, y)`` (float64): :meth:`frame` there."""
        p = self.params
        out = np.empty(events.size, dtype=np.float64)
        _sample(
            self.texture, events["t"], events["x"], events["y"], out,
            p["zoom_per_s"], p["shake_px"], p["shake_hz"], p["shake_phase"],
            p["focus"][0], p["focus"][1], self._c0[0], self._c0[1], self._v[0], self._v[1],
        )  # fmt: skip
        for obj in self.objects:
            _sample_object(
                obj.texture, events["t"], events["x"], events["y"], out,
                obj.cx, obj.cy, obj.dx, obj.dy, obj.omega, obj.phase, obj.ax, obj.ay,
            )  # fmt: skip
        return out

    def describe(self) -> dict[str, Any]:
        """The drawn scene parameters, JSON-ready."""
        d = {k: list(v) if isinstance(v, tuple) else v for k, v in self.params.items()}
        if self.objects:
            d["near_objects"] = [obj.describe() for obj in self.objects]
        return d


@dataclass(frozen=True)
class NearObject:
    """A large textured object close to the camera (a head, a hand, a passer-by), swinging
    to and fro in front of the street: no light, but a large, dense, compact patch of events
    that moves fast, which a de-flarer must keep.

    It is an ellipse of semi-axes ``ax, ay`` pixels with its own texture (value noise at
    three scales, multiplicative, and a darker rim), centred at
    ``(cx, cy) + (dx, dy) sin(omega t + phase)``: it stays in view for any duration, at its
    fastest ``omega * |(dx, dy)|`` pixels per microsecond.

    Examples
    --------
    >>> cfg = SceneConfig(near_objects=(1, 1))
    >>> obj = NearObject.draw((64, 48), cfg, np.random.default_rng(0))
    >>> bool(0.3 * 24 <= obj.ay <= 0.8 * 24), obj.texture.shape == (2 * obj.iy + 3, 2 * obj.ix + 3)
    (True, True)
    """

    texture: np.ndarray
    cx: float
    cy: float
    dx: float
    dy: float
    omega: float
    phase: float
    ax: float
    ay: float

    @property
    def ix(self) -> int:
        return math.ceil(self.ax)

    @property
    def iy(self) -> int:
        return math.ceil(self.ay)

    @classmethod
    def draw(
        cls, sensor_size: SensorSize, cfg: SceneConfig, gen: np.random.Generator
    ) -> NearObject:
        """One object of ``cfg``'s ranges on a sensor of ``sensor_size``."""
        width, height = sensor_size
        u = lambda pair: float(gen.uniform(*pair))  # noqa: E731
        ay = u(cfg.near_height) * height / 2
        ax = ay * u((0.6, 1.0))
        cx, cy = u((0.25, 0.75)) * width, u((0.3, 0.7)) * height
        swing = u((0.05, 0.2)) * width
        angle = u((-0.5, 0.5))  # mostly sideways, as a head turns or a person passes
        dx, dy = swing * math.cos(angle), swing * math.sin(angle)
        omega = u(cfg.near_speed_px_per_s) * 1e-6 / swing
        phase = u((0.0, 2 * math.pi))
        ix, iy = math.ceil(ax), math.ceil(ay)
        shape = (2 * iy + 3, 2 * ix + 3)
        c = u(cfg.near_contrast)
        noise = (
            0.4 * _value_noise(shape, 1.0, gen)
            + 0.35 * _value_noise(shape, 3.0, gen)
            + 0.25 * _value_noise(shape, 8.0, gen)
        )
        yy, xx = np.mgrid[: shape[0], : shape[1]]
        r = np.hypot((xx - ix - 1) / max(ax, 1.0), (yy - iy - 1) / max(ay, 1.0))
        rim = np.where(r > 0.85, 0.5, 1.0)  # an outline, as hair or a sleeve gives
        tex = u(cfg.near_level) * rim * np.exp(c * noise)
        texture = np.clip(tex, 0.5, None).astype(np.float32)
        return cls(texture, cx, cy, dx, dy, omega, phase, ax, ay)

    def centre(self, t_us: float) -> tuple[float, float]:
        """Its centre at ``t_us``."""
        s = math.sin(self.omega * t_us + self.phase)
        return self.cx + self.dx * s, self.cy + self.dy * s

    def describe(self) -> dict[str, float]:
        """Its drawn parameters (not its texture), JSON-ready."""
        names = ("cx", "cy", "dx", "dy", "omega", "phase", "ax", "ay")
        return {k: float(getattr(self, k)) for k in names}


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _bilinear(tex, qx, qy):  # pragma: no cover - compiled
    """``tex`` at the point ``(qx, qy)``, bilinear (the caller keeps it inside the texture)."""
    ix = np.int64(qx)
    iy = np.int64(qy)
    wx = qx - ix
    wy = qy - iy
    top = (1.0 - wx) * tex[iy, ix] + wx * tex[iy, ix + 1]
    bottom = (1.0 - wx) * tex[iy + 1, ix] + wx * tex[iy + 1, ix + 1]
    return (1.0 - wy) * top + wy * bottom


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _object_value(tex, qx, qy, ax, ay):  # pragma: no cover - compiled
    """The object's intensity at offset ``(qx, qy)`` from its centre, or -1 outside it."""
    if ax <= 0.0 or ay <= 0.0 or (qx / ax) ** 2 + (qy / ay) ** 2 > 1.0:
        return -1.0
    th, tw = tex.shape
    return _bilinear(tex, qx + (tw - 1) // 2, qy + (th - 1) // 2)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _paste(tex, out, cx, cy, ax, ay):  # pragma: no cover - compiled
    """Draw an object centred at ``(cx, cy)`` over ``out`` (the pixels its ellipse covers)."""
    h, w = out.shape
    y0, y1 = max(0, np.int64(cy - ay) - 1), min(h, np.int64(cy + ay) + 2)
    x0, x1 = max(0, np.int64(cx - ax) - 1), min(w, np.int64(cx + ax) + 2)
    for y in range(y0, y1):
        for x in range(x0, x1):
            v = _object_value(tex, x - cx, y - cy, ax, ay)
            if v >= 0.0:
                out[y, x] = v


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _sample_object(
    tex, t, x, y, out, cx, cy, dx, dy, omega, phase, ax, ay
):  # pragma: no cover - compiled
    """:func:`_paste` at each event's own time and pixel (the same arithmetic)."""
    for i in range(t.size):
        s = math.sin(omega * np.float64(t[i]) + phase)
        v = _object_value(tex, x[i] - (cx + dx * s), y[i] - (cy + dy * s), ax, ay)
        if v >= 0.0:
            out[i] = v


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _sample(
    tex, t, x, y, out, zoom, shake_px, shake_hz, phase, fx, fy, c0x, c0y, vx, vy
):  # pragma: no cover
    """:meth:`NightStreet.frame` at each event's own time and pixel (the same arithmetic)."""
    th, tw = tex.shape
    qx_hi = tw - 1.000001
    qy_hi = th - 1.000001
    for i in range(t.size):
        tt = np.float64(t[i])
        scale = math.exp(-zoom * tt * 1e-6)
        shake = shake_px * math.sin(2 * math.pi * shake_hz * tt * 1e-6 + phase)
        qx = min(max(c0x + vx * tt + (x[i] - fx) * scale, 0.0), qx_hi)
        qy = min(max(c0y + vy * tt + shake + (y[i] - fy) * scale, 0.0), qy_hi)
        out[i] = _bilinear(tex, qx, qy)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _render(tex, out, scale, fx, fy, ox, oy):  # pragma: no cover - compiled
    """``out[y, x] = tex(o + (x - fx, y - fy) * scale)``, bilinear, clamped at the edges
    (:func:`_bilinear`'s arithmetic, its row terms kept out of the inner loop)."""
    th, tw = tex.shape
    h, w = out.shape
    qx_hi = tw - 1.000001
    qy_hi = th - 1.000001
    for y in range(h):
        qy = min(max(oy + (y - fy) * scale, 0.0), qy_hi)
        iy = np.int64(qy)
        wy = qy - iy
        for x in range(w):
            qx = min(max(ox + (x - fx) * scale, 0.0), qx_hi)
            ix = np.int64(qx)
            wx = qx - ix
            top = (1.0 - wx) * tex[iy, ix] + wx * tex[iy, ix + 1]
            bottom = (1.0 - wx) * tex[iy + 1, ix] + wx * tex[iy + 1, ix + 1]
            out[y, x] = (1.0 - wy) * top + wy * bottom


def _noise_events(
    n_pixels_hz: float, sensor_size: SensorSize, duration_us: int, gen: np.random.Generator
) -> np.ndarray:
    width, height = sensor_size
    n = int(gen.poisson(n_pixels_hz * width * height * duration_us * 1e-6))
    out = np.empty(n, dtype=EVENT_DTYPE)
    out["t"] = gen.integers(0, duration_us, n)
    out["x"] = gen.integers(0, width, n)
    out["y"] = gen.integers(0, height, n)
    out["p"] = gen.integers(0, 2, n)
    return out[np.argsort(out["t"], kind="stable")]


class SyntheticBackground:
    """Synthetic night-street backgrounds (see the module docstring); no download needed.

    Parameters
    ----------
    config : SceneConfig, optional
    intensity : {"video", "accumulation", "counts"}
        The PNL-ES intensity: the exact scene (default), or an estimate from
        the events as for recorded backgrounds (to study the estimators).
    accumulation : AccumulationParams, optional

    Examples
    --------
    >>> bg = SyntheticBackground(SceneConfig(fps=1000.0)).draw(5_000, (32, 24), rng=0)
    >>> bg.events.size > 0, bg.video(0).shape
    (True, (24, 32))
    """

    def __init__(
        self,
        config: SceneConfig | None = None,
        *,
        intensity: str = "video",
        accumulation: AccumulationParams | None = None,
    ) -> None:
        self.config = config or SceneConfig()
        self.intensity = check_choice("intensity", intensity, INTENSITY_ESTIMATORS)
        self.accumulation = accumulation or AccumulationParams()

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings."""
        return {
            "kind": "synthetic",
            "scene": self.config.to_dict(),
            "intensity": self.intensity,
            "accumulation": self.accumulation.to_dict(),
        }

    def draw(
        self,
        duration_us: int,
        sensor_size: SensorSize,
        sensor: SensorSpec | None = None,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> Background:
        """Draw a scene and its motion, and simulate its events with the camera ``sensor``.

        ``sensor`` defaults to a DAVIS346-like DVS-Voltmeter.
        """
        duration = _duration(duration_us)
        size = check_sensor_size(sensor_size)
        scene_seq, sim_seq, noise_seq = np.random.SeedSequence(
            int(make_rng(rng).integers(0, 2**63))
        ).spawn(3)
        scene = NightStreet(size, self.config, rng=np.random.default_rng(scene_seq))
        sim = camera_simulator(sensor or SensorSpec(), size, rng=np.random.default_rng(sim_seq))
        n = max(2, math.ceil(duration * self.config.fps * 1e-6) + 1)
        times = np.round(np.linspace(0, duration, n)).astype(np.int64)
        recorder = EventRecorder(sim, "street")
        run_frames(((int(t), {"street": scene.frame(int(t))}) for t in times), [recorder])
        events = recorder.events()
        events = events[events["t"] < duration]
        noise = _noise_events(
            scene.params["noise_rate_hz"], size, duration, np.random.default_rng(noise_seq)
        )
        if noise.size:
            events = np.concatenate([events, noise])
            events = events[np.argsort(events["t"], kind="stable")]
        if self.intensity == "video":
            field: IntensityField = scene
        elif self.intensity == "accumulation":
            field = AccumulatedIntensity(events, size, 0, duration, self.accumulation)
        else:
            field = CountIntensity(events, size, floor=1e-3)
        description = {
            "kind": "synthetic",
            "duration_us": duration,
            "fps": self.config.fps,
            "intensity": self.intensity,
            "scene": scene.describe(),
        }
        return Background(events, field, size, duration, description, video=scene.frame)
