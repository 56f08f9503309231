"""Sparse flare sensing: how a real sensor records scattered light, as a stage after the pair.

Measured on real recordings (``benchmarks/flare_stats.py``, docs/benchmarks.md), a
real sensor fires the pixels of scattered light 2-6 source radii out at 0.02-2 % of
the source's own rate, while the simulator, whose log-intensity events fire wherever
the flare dominates a dark pixel, fires them at 10-65 %: solid streaks where real
ones are scattered single events. The physical cause is the photoreceptor's slow
response in dim pixels (DVS-Voltmeter's intensity-dependent bandwidth), which fires
a pixel lit only by scattered light rarely. :func:`sparse_sensing` reproduces the
measured statistics on a simulated pair, per sequence:

1. **Scattered light is sensed sparsely.** Each flare event of the input (an input
   event equal to one of the ``flare`` stream's; PNL-ES keeps events unchanged)
   farther than ``near_px`` from the source's own events of the same ``step_us``
   survives with probability ``q * min(1, (2 r / d) ** falloff)``: ``q``
   log-uniform in ``survival`` per sequence, ``d`` the distance from the source's
   centre and ``r`` its radius (the disc of its pixels) in that step.
2. **The glow next to the source belongs to it.** Flare events within ``near_px``
   of the source's events are kept and count as the source: a real sensor
   records a bright light's immediate glow as part of the blob (the annotations'
   5 % density rule does the same).
3. **The source is recorded.** Events of the ``light`` stream missing from the
   input return: a log photoreceptor does not clip, while the 8-bit flare rendering
   saturates at the core and leaves a hole there.
4. **Scattered background activity to keep.** Uniform random events at a rate
   log-uniform in ``noise_rate`` (events per pixel per second) join the input
   and the target: real scenes hold scattered events far from any light (noise,
   flicker on texture), which a de-flarer must not learn to delete.
5. **Ghosts are sensed at their own rate** (off unless ``ghost_survival`` is above
   ``(0, 0)`` and the sequence's ghosts are given): a flare event inside one of the
   reflective ghosts' discs (centre ``c + k (L - c)`` through the image centre ``c``,
   the source's centre ``L`` interpolated in time between steps) survives with
   probability ``q_ghost``, log-uniform in ``ghost_survival`` per sequence, in place
   of step 1's, whatever its distance from the source. A ghost is an image of the
   source, lit by it and not by light that thins out with distance: real recordings
   show ghost rings of sparse events hundreds of pixels from the source
   (``../shared/reference/real_flare_example.png``), where step 1 would leave almost
   none.
6. **Hot pixels to remove** (off unless ``hot_pixels`` is above ``(0, 0)``): a
   number of pixels uniform in ``hot_pixels`` each fire at a rate log-uniform in
   ``hot_rate`` (events per second), almost all of one polarity (ON for three in
   four pixels), as the Prophesee Gen3 recording's seven hot pixels do (5-66 k
   events/s, all ON). They join the input, not the target: a sensor defect, which
   every denoiser removes and which the real recordings' halos sweep over.

The target ``gt`` becomes *keep-only*: the input's events that are true (scene,
source, glow, background activity), a subset of the input, which is what a
de-flarer that deletes events (the ``mask`` presets) can reach; the simulator's own
ground truth is kept as ``gt_full``.

Examples
--------
>>> from edeflare.events import make_events
>>> light = make_events([0, 0, 0], [10, 11, 10], [10, 10, 11], [1, 1, 1])
>>> flare = make_events([5, 6], [12, 40], [10, 40], [1, 0])   # 1 px and 42 px from the light
>>> gt = make_events([7], [60], [5], [0])
>>> inp = make_events([5, 6, 7], [12, 40, 60], [10, 40, 5], [1, 0, 0])
>>> out = sparse_sensing({"input": inp, "gt": gt, "flare": flare, "light": light}, (64, 48),
...                      0, SensingConfig(survival=(1e-9, 1e-9), noise_rate=(0.0, 0.0)), rng=0)
>>> out["input"]["x"].tolist()   # far flare gone, light restored, glow and scene kept
[10, 11, 10, 12, 60]
>>> out["gt"]["x"].tolist()      # the target: everything left but nothing to remove here
[10, 11, 10, 12, 60]
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import ndimage

from ..errors import ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_sensor_size, event_keys, isin_keys
from .flare import GhostSpec

__all__ = ["SensingConfig", "in_ghosts", "source_track", "sparse_sensing"]


@dataclasses.dataclass(frozen=True)
class SensingConfig:
    """Parameters of :func:`sparse_sensing` (``enabled=False``: the stage is off).

    Examples
    --------
    >>> SensingConfig.from_dict({"enabled": True}).survival
    (0.003, 0.2)
    """

    enabled: bool = False
    near_px: int = 2
    survival: tuple[float, float] = (0.003, 0.2)
    falloff: float = 2.0
    noise_rate: tuple[float, float] = (0.3, 20.0)
    step_us: int = 10_000
    hot_pixels: tuple[int, int] = (0, 0)
    hot_rate: tuple[float, float] = (1_000.0, 50_000.0)
    ghost_survival: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "survival", tuple(float(v) for v in self.survival))
        object.__setattr__(self, "ghost_survival", tuple(float(v) for v in self.ghost_survival))
        lo, hi = self.ghost_survival
        if not ((lo == hi == 0.0) or 0 < lo <= hi <= 1):
            raise ParameterError(
                "ghost_survival must be (0, 0) (off) or 0 < low <= high <= 1, "
                f"got {self.ghost_survival}"
            )
        object.__setattr__(self, "noise_rate", tuple(float(v) for v in self.noise_rate))
        object.__setattr__(self, "hot_rate", tuple(float(v) for v in self.hot_rate))
        try:
            lo, hi = (int(v) for v in self.hot_pixels)
        except (TypeError, ValueError):
            msg = f"hot_pixels must be (low, high), got {self.hot_pixels!r}"
            raise ParameterError(msg) from None
        if not 0 <= lo <= hi:
            raise ParameterError(f"hot_pixels must satisfy 0 <= low <= high, got {(lo, hi)}")
        object.__setattr__(self, "hot_pixels", (lo, hi))
        lo_r, hi_r = self.hot_rate
        if not (0 < lo_r <= hi_r and math.isfinite(hi_r)):
            raise ParameterError(f"hot_rate must satisfy 0 < low <= high, got {self.hot_rate}")
        lo, hi = self.survival
        if not 0 < lo <= hi <= 1:
            raise ParameterError(f"survival must satisfy 0 < low <= high <= 1, got {self.survival}")
        lo, hi = self.noise_rate
        if not (0 <= lo <= hi and math.isfinite(hi)) or (lo == 0 < hi):
            raise ParameterError(
                f"noise_rate must be (0, 0) or 0 < low <= high (log-uniform), got {self.noise_rate}"
            )
        if isinstance(self.near_px, bool) or not isinstance(self.near_px, int) or self.near_px < 0:
            raise ParameterError(f"near_px must be an int >= 0, got {self.near_px!r}")
        if not (math.isfinite(self.falloff) and self.falloff >= 0):
            raise ParameterError(f"falloff must be >= 0, got {self.falloff!r}")
        if isinstance(self.step_us, bool) or not isinstance(self.step_us, int) or self.step_us < 1:
            raise ParameterError(f"step_us must be a positive int, got {self.step_us!r}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SensingConfig:
        """Build from a mapping; unknown keys are an error."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ParameterError(f"unknown sensing key(s) {unknown}; valid keys: {sorted(names)}")
        return cls(**dict(data))

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (without the hot-pixel and ghost keys while those steps are
        off, so recipes keep the dicts and digests they had before they existed)."""
        d = {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}
        if self.hot_pixels == (0, 0):
            del d["hot_pixels"], d["hot_rate"]
        if self.ghost_survival == (0.0, 0.0):
            del d["ghost_survival"]
        return d


def _log_uniform(gen: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(gen.uniform(np.log(lo), np.log(hi)))) if hi > lo else float(lo)


def _hot_pixel_events(
    gen: np.random.Generator, config: SensingConfig, size: SensorSize, t0: int, t1: int
) -> np.ndarray:
    """Step 6: the hot pixels' events (none, and no draws, while the step is off)."""
    lo, hi = config.hot_pixels
    if hi == 0:
        return np.empty(0, dtype=EVENT_DTYPE)
    width, height = size
    n_pixels = int(gen.integers(lo, hi + 1))
    parts = []
    for _ in range(n_pixels):
        rate = _log_uniform(gen, *config.hot_rate)
        n = int(gen.poisson(rate * max(t1 - t0, 0) / 1e6))
        ev = np.empty(n, dtype=EVENT_DTYPE)
        ev["t"] = np.sort(gen.integers(t0, max(t1, t0 + 1), n))
        ev["x"], ev["y"] = gen.integers(0, width), gen.integers(0, height)
        polarity = int(gen.random() < 0.75)
        ev["p"] = np.where(gen.random(n) < 0.97, polarity, 1 - polarity)
        parts.append(ev)
    return np.concatenate(parts) if parts else np.empty(0, dtype=EVENT_DTYPE)


def source_track(
    light: np.ndarray, step_us: int = 10_000, t_start_us: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The light source's centre per time step, as :func:`sparse_sensing` finds it.

    Parameters
    ----------
    light : numpy.ndarray
        The ``light`` stream (the source's own events).
    step_us : int
        Step length; steps with fewer than 20 events are left out.
    t_start_us : int
        Where the steps start.

    Returns
    -------
    (t_us, x, y)
        Float arrays: each kept step's middle and the mean position of its events, the
        ``track`` of :func:`in_ghosts`.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> t = list(range(0, 40_000, 250))                        # 40 events per 10 ms
    >>> light = make_events(t, [10] * 80 + [30] * 80, [5] * 160, [1] * 160)
    >>> [v.tolist() for v in source_track(light)]
    [[5000.0, 15000.0, 25000.0, 35000.0], [10.0, 10.0, 30.0, 30.0], [5.0, 5.0, 5.0, 5.0]]
    """
    step = (light["t"].astype(np.int64) - int(t_start_us)) // int(step_us)
    t, x, y = [], [], []
    for k in np.unique(step):
        sel = light[step == k]
        if sel.size >= 20:
            t.append(int(t_start_us) + (k + 0.5) * step_us)
            x.append(sel["x"].mean())
            y.append(sel["y"].mean())
    return np.array(t, np.float64), np.array(x, np.float64), np.array(y, np.float64)


def in_ghosts(
    events: np.ndarray,
    track: tuple[np.ndarray, np.ndarray, np.ndarray],
    ghosts: Sequence[GhostSpec],
    sensor_size: SensorSize,
) -> np.ndarray:
    """Which events lie inside a reflective ghost's disc of a moving source.

    Ghost ``g`` of a source at ``L`` is centred at ``c + g.k (L - c)`` (``c`` the image
    centre, as :func:`edeflare.sim.flare.render_ghosts` draws it); its reach is its
    radius widened by its colour fringe and soft edge, plus one pixel.

    Parameters
    ----------
    events : numpy.ndarray
        Structured events.
    track : (t_us, x, y)
        The source's centre at increasing times (:func:`source_track`); linearly
        interpolated at each event's time (held at the ends).
    ghosts : sequence of GhostSpec
    sensor_size : (width, height)

    Returns
    -------
    numpy.ndarray
        Boolean mask over ``events`` (all False without ghosts or track).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> from edeflare.sim.flare import GhostSpec
    >>> ev = make_events([0, 0], [20, 60], [10, 10], [1, 1])
    >>> track = (np.array([0.0]), np.array([60.0]), np.array([29.5]))   # source right of centre
    >>> in_ghosts(ev, track, [GhostSpec(k=-1.0, radius_px=4, level=1)], (80, 60)).tolist()
    [False, False]
    >>> track = (np.array([0.0]), np.array([59.0]), np.array([49.0]))   # its mirror is (20, 10)
    >>> in_ghosts(ev, track, [GhostSpec(k=-1.0, radius_px=4, level=1)], (80, 60)).tolist()
    [True, False]
    """
    width, height = check_sensor_size(sensor_size)
    t_track, x_track, y_track = (np.asarray(v, dtype=np.float64) for v in track)
    inside = np.zeros(events.size, dtype=bool)
    if not events.size or not t_track.size or not ghosts:
        return inside
    t = events["t"].astype(np.float64)
    lx, ly = np.interp(t, t_track, x_track), np.interp(t, t_track, y_track)
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    ex, ey = events["x"].astype(np.float64), events["y"].astype(np.float64)
    for g in ghosts:
        reach = g.radius_px * (1.0 + 0.5 * g.fringe + g.softness) + 1.0
        gx, gy = cx + g.k * (lx - cx), cy + g.k * (ly - cy)
        inside |= np.hypot(ex - gx, ey - gy) <= reach
    return inside


def sparse_sensing(
    streams: Mapping[str, np.ndarray],
    sensor_size: SensorSize,
    t_start_us: int,
    config: SensingConfig,
    rng: np.random.Generator | int | tuple[int, ...],
    *,
    t_end_us: int | None = None,
    ghosts: Sequence[GhostSpec] = (),
) -> dict[str, np.ndarray]:
    """Apply the sparse-sensing stage to one simulated sequence (see the module docstring).

    Parameters
    ----------
    streams : mapping
        ``input``, ``gt``, ``flare`` and ``light`` event streams of one sequence.
    sensor_size : (width, height)
    t_start_us : int
        Start of the sequence (the steps of the source's position count from it).
    config : SensingConfig
    rng : numpy.random.Generator or seed
    t_end_us : int, optional
        End of the sequence, for the background activity (default: the input's last event).
    ghosts : sequence of GhostSpec
        The sequence's reflective ghosts (its script's), for step 5.

    Returns
    -------
    dict
        ``input`` and ``gt`` replaced (``gt`` keep-only), ``gt_full`` the original
        ``gt``, and the other streams as given.
    """
    size = check_sensor_size(sensor_size)
    width, height = size
    missing = [g for g in ("input", "gt", "flare", "light") if g not in streams]
    if missing:
        raise ParameterError(f"sparse sensing needs the streams {missing} too")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    inp, light = streams["input"], streams["light"]
    q = _log_uniform(gen, *config.survival)
    ghosts_on = config.ghost_survival[1] > 0 and len(ghosts) > 0
    q_ghost = _log_uniform(gen, *config.ghost_survival) if ghosts_on else 0.0
    is_flare = isin_keys(event_keys(inp, size), event_keys(streams["flare"], size))
    step = (inp["t"].astype(np.int64) - int(t_start_us)) // config.step_us
    light_step = (light["t"].astype(np.int64) - int(t_start_us)) // config.step_us
    near = np.zeros(inp.size, dtype=bool)
    n_steps = int(max(step.max(initial=-1), light_step.max(initial=-1))) + 1
    cx = np.full(max(n_steps, 1), np.nan)
    cy, radius = cx.copy(), cx.copy()
    for k in np.unique(light_step[light_step >= 0]):
        sel = light[light_step == k]
        here = np.zeros((height, width), dtype=bool)
        here[sel["y"], sel["x"]] = True
        if sel.size >= 20:
            cx[k], cy[k] = float(sel["x"].mean()), float(sel["y"].mean())
            radius[k] = max(math.sqrt(np.count_nonzero(here) / math.pi), 2.0)
        if config.near_px:
            here = ndimage.binary_dilation(here, iterations=config.near_px)
        idx = np.flatnonzero(step == k)
        near[idx] = here[inp["y"][idx], inp["x"][idx]]
    survival = np.full(inp.size, q)
    known = np.isfinite(cx)
    if config.falloff > 0 and known.any() and inp.size:
        # steps without the source take the nearest step's position
        steps = np.arange(cx.size)
        at = steps[known][np.clip(np.searchsorted(steps[known], steps), 0, known.sum() - 1)]
        s = np.clip(step, 0, cx.size - 1)
        d = np.hypot(inp["x"] - cx[at][s], inp["y"] - cy[at][s])
        survival *= np.minimum(1.0, (2 * radius[at][s] / np.maximum(d, 1e-6)) ** config.falloff)
    if ghosts_on and known.any():
        t_mid = int(t_start_us) + (np.flatnonzero(known) + 0.5) * config.step_us
        track = (t_mid, cx[known], cy[known])
        survival[is_flare & in_ghosts(inp, track, ghosts, size)] = q_ghost
    drop = is_flare & ~near & (gen.random(inp.size) >= survival)
    kept = inp[~drop]
    restored = light[~isin_keys(event_keys(light, size), event_keys(kept, size))]
    t_end = int(inp["t"][-1]) + 1 if t_end_us is None and inp.size else int(t_end_us or t_start_us)
    rate = _log_uniform(gen, *config.noise_rate) if config.noise_rate[1] > 0 else 0.0
    n_noise = int(gen.poisson(rate * width * height * max(t_end - int(t_start_us), 0) / 1e6))
    noise = np.empty(n_noise, dtype=EVENT_DTYPE)
    noise["t"] = np.sort(gen.integers(int(t_start_us), max(t_end, int(t_start_us) + 1), n_noise))
    noise["x"] = gen.integers(0, width, n_noise)
    noise["y"] = gen.integers(0, height, n_noise)
    noise["p"] = gen.integers(0, 2, n_noise)
    hot = _hot_pixel_events(gen, config, size, int(t_start_us), t_end)
    new_input = np.concatenate([kept, restored, noise, hot])
    new_input = new_input[np.argsort(new_input["t"], kind="stable")]
    true = np.concatenate([streams["gt"], light, inp[is_flare & near], noise])
    target = new_input[isin_keys(event_keys(new_input, size), event_keys(true, size))]
    out = dict(streams)
    out.update(input=new_input, gt=target, gt_full=streams["gt"])
    return out
