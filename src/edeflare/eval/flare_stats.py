"""Statistics of flare around a light source, the same for real and simulated recordings.

To calibrate the simulator on real recordings, both are
measured with one yardstick, around a known light source (an annotation
:class:`~edeflare.lights.Lights` for a real recording,
:func:`lights_from_events` of the simulator's own ``light`` stream for a
simulated one). Distances are in units of the source's radius ``r`` at each
event's time, so a 36 px blob at 640x480 and a 10 px lamp at 346x260 compare.

- ``radial``: the event rate per pixel in rings around the source, relative to
  the rate inside it (the light disc = 1). Rings are clipped to the sensor.
- ``streak_contrast``: in the halo (2r to 6r), the events per angular sector
  (36 sectors of 10 degrees): the mean of the 4 fullest sectors over the median
  sector. Near 1 for an even glow, large for streaks (and for a trail behind a
  moving source).
- ``on_fraction``: the ON share of the light's, the halo's and the background's events.
- ``interval_ms``: the median time between consecutive events of one pixel, in
  the light and in the halo (a pixel of a bright flickering source fires every
  few ms; scattered flare fires a pixel rarely).
- ``light_rate``, ``halo_rate``, ``background_rate``: events per pixel per second.
- ``ghost_contrast``: the rate in the ghost disc (``ghost_factor`` r around the
  source's reflection through the image centre) over the background's.

Examples
--------
>>> from edeflare.events import make_events
>>> from edeflare.lights import LightSource, Lights
>>> t, x, y = [0, 10, 20, 30, 1000], [10, 10, 11, 16, 40], [10, 10, 10, 10, 30]
>>> ev = make_events(t, x, y, [1, 1, 0, 1, 1])
>>> st = flare_statistics(ev, Lights((LightSource.circle(10, 10, 2),)), (64, 48))
>>> st.on_fraction["light"], st.interval_ms["light"]    # pixel (10, 10) fired at 0 and 10 us
(0.6666666666666666, 0.01)
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..events import SensorSize, check_events, check_sensor_size
from ..lights import Lights, LightSource
from .score import classify_events

__all__ = ["RING_EDGES", "FlareStatistics", "flare_statistics", "lights_from_events"]

RING_EDGES = (0.0, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 10.0)
"""Ring edges of the radial profile, in units of the source's radius."""

_SECTORS = 36
_TOP_SECTORS = 4


@dataclasses.dataclass(frozen=True)
class FlareStatistics:
    """What :func:`flare_statistics` measured (see the module docstring)."""

    events: int
    span_s: float
    radius_px: float
    radial: tuple[float, ...]
    streak_contrast: float
    on_fraction: dict[str, float]
    interval_ms: dict[str, float]
    light_rate: float
    halo_rate: float
    background_rate: float
    ghost_contrast: float

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (NaN as None)."""

        def plain(v: Any) -> Any:
            if isinstance(v, dict):
                return {k: plain(x) for k, x in v.items()}
            if isinstance(v, (tuple, list)):
                return [plain(x) for x in v]
            return None if isinstance(v, float) and math.isnan(v) else v

        return {f.name: plain(getattr(self, f.name)) for f in dataclasses.fields(self)}


def lights_from_events(light: np.ndarray, step_us: int = 5_000, min_events: int = 20) -> Lights:
    """A light-source track from a simulator's ``light`` stream: per ``step_us``,
    the centroid of the light's events and the radius of a disc as large as
    the pixels they cover (absent in steps with fewer than ``min_events``).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> xs, ys = np.meshgrid(np.arange(8, 13), np.arange(8, 13))
    >>> ev = make_events(np.arange(25), xs.ravel(), ys.ravel(), np.ones(25, int))
    >>> src = lights_from_events(ev).sources[0]
    >>> [round(float(v[0]), 2) for v in src.at(np.array([10]))]   # 25 pixels: r = sqrt(25 / pi)
    [10.0, 10.0, 2.82]
    """
    if light.size == 0:
        raise ValueError("the light stream holds no events")
    t0 = int(light["t"][0])
    step = (light["t"] - t0) // step_us
    rows = []
    for k in np.unique(step):
        sel = light[step == k]
        if sel.size < min_events:
            rows.append([t0 + int(k) * step_us, np.nan, np.nan, np.nan])
            continue
        pixels = np.unique(sel["y"].astype(np.int64) * 65536 + sel["x"])
        r = math.sqrt(pixels.size / math.pi)
        rows.append([t0 + int(k) * step_us, float(sel["x"].mean()), float(sel["y"].mean()), r])
    return Lights((LightSource.steps(rows),), ghost_factor=2.0)


def _ring_pixels(
    source: LightSource, times: np.ndarray, sensor_size: SensorSize, edges: np.ndarray
) -> np.ndarray:
    """Mean on-sensor pixel count of each ring, over sample times."""
    width, height = sensor_size
    yy, xx = np.mgrid[0:height, 0:width]
    totals = np.zeros(len(edges) - 1)
    n = 0
    for cx, cy, r in zip(*source.at(times), strict=True):
        if not np.isfinite(cx):
            continue
        d = np.hypot(xx - cx, yy - cy) / r
        totals += np.histogram(d, bins=edges)[0]
        n += 1
    return totals / max(n, 1)


def _median_interval_ms(events: np.ndarray, mask: np.ndarray, width: int) -> float:
    ev = events[mask]
    if ev.size < 2:
        return math.nan
    pixel = ev["y"].astype(np.int64) * width + ev["x"]
    order = np.lexsort((ev["t"], pixel))
    p, t = pixel[order], ev["t"][order].astype(np.int64)
    same = p[1:] == p[:-1]
    if not same.any():
        return math.nan
    return float(np.median(np.diff(t)[same])) / 1e3


def flare_statistics(
    events: np.ndarray,
    lights: Lights,
    sensor_size: SensorSize,
    *,
    samples: int = 16,
) -> FlareStatistics:
    """Measure the flare around the first light source of ``lights`` (see the module docstring).

    Parameters
    ----------
    events : numpy.ndarray
        Sorted events.
    lights : Lights
        Its first source is measured; the regions are :func:`classify_events`'.
    sensor_size : (width, height)
    samples : int
        Times at which the rings' on-sensor areas are averaged (a moving source).
    """
    size = check_sensor_size(sensor_size)
    check_events(events, size)
    width, height = size
    source = lights.sources[0]
    t = events["t"]
    span_s = max(int(t[-1]) - int(t[0]), 1) / 1e6 if events.size else math.nan
    regions = classify_events(events, lights, size)
    cx, cy, r = source.at(t)
    present = np.isfinite(cx)
    x = events["x"].astype(np.float64)
    y = events["y"].astype(np.float64)
    d = np.where(present, np.hypot(x - cx, y - cy) / np.where(present, r, 1.0), np.inf)
    edges = np.asarray(RING_EDGES)
    counts = np.histogram(d[present], bins=edges)[0]
    times = np.linspace(int(t[0]), int(t[-1]), samples) if events.size else np.zeros(0)
    area = _ring_pixels(source, times, size, edges)
    rate = np.where(area > 0, counts / np.maximum(area, 1e-9), np.nan)
    radial = tuple(float(v) for v in rate / rate[0]) if rate[0] > 0 else (math.nan,) * len(rate)
    halo = present & (d > 2.0) & (d <= 6.0)
    if halo.sum() >= _SECTORS:
        angle = np.arctan2(y[halo] - cy[halo], x[halo] - cx[halo])
        sectors = np.histogram(angle, bins=_SECTORS, range=(-math.pi, math.pi))[0]
        top = np.sort(sectors)[-_TOP_SECTORS:].mean()
        streak = float(top / max(np.median(sectors), 1.0))
    else:
        streak = math.nan

    def share_on(mask: np.ndarray) -> float:
        return float(events["p"][mask].mean()) if mask.any() else math.nan

    px_s = float(np.nanmean(area[0])) * span_s if rate[0] > 0 else math.nan
    light_rate = counts[0] / px_s if px_s and px_s > 0 else math.nan
    halo_area = float(area[(edges[:-1] >= 2.0) & (edges[1:] <= 6.0)].sum())
    halo_rate = halo.sum() / (halo_area * span_s) if halo_area > 0 else math.nan
    background_area = max(width * height - float(area[:6].sum()), 1.0)
    background_rate = regions.background.sum() / (background_area * span_s)
    ghost_contrast = math.nan
    if source.ghost:
        gr = lights.ghost_factor * r
        in_ghost = present & (np.hypot(x - (width - 1 - cx), y - (height - 1 - cy)) <= gr)
        in_ghost &= ~regions.light
        ghost_area = float(np.nanmean(math.pi * (lights.ghost_factor * r[present]) ** 2))
        if ghost_area > 0 and background_rate > 0:
            ghost_contrast = in_ghost.sum() / (ghost_area * span_s) / background_rate
    return FlareStatistics(
        events=int(events.size),
        span_s=span_s,
        radius_px=float(np.nanmedian(r[present])) if present.any() else math.nan,
        radial=radial,
        streak_contrast=streak,
        on_fraction={
            "light": share_on(regions.light),
            "halo": share_on(halo),
            "background": share_on(regions.background),
        },
        interval_ms={
            "light": _median_interval_ms(events, regions.light, width),
            "halo": _median_interval_ms(events, halo, width),
        },
        light_rate=float(light_rate),
        halo_rate=float(halo_rate),
        background_rate=float(background_rate),
        ghost_contrast=float(ghost_contrast),
    )
