"""How far a light's flare reaches, measured from the recording itself.

Scattered light falls off with distance from its source until it drowns in the
scene's own events. :func:`flare_reach` measures the event rate in rings around a
source (events per pixel and second, each event's distance taken from the source's
centre at its own time) and finds where it comes down to the background rate: that
radius is the outer edge of the source's halo. The ghost lies where the source
reflects through the optical centre, ``(W - 1 - cx, H - 1 - cy)``; its radius is where
the rate around that point comes down to the background in the same way. Where the
recording shows no excess (too few events, a ghost too faint to see), the scorer's
fixed factors of the source radius remain (:class:`~edeflare.lights.Lights`).

Examples
--------
>>> rng = np.random.default_rng(0)
>>> ev = synthetic_flare(rng, (320, 240), (160, 120), radius=6, reach=60, strength=200)
>>> found = flare_reach(ev, (320, 240), LightSource.circle(160, 120, 6))
>>> 0.85 * 60 <= found.halo_outer_px <= 1.15 * 60
True
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..events import EVENT_DTYPE, SensorSize, check_sensor_size, sort_events
from .rings import centred, ring_pixels
from .source import Lights, LightSource

__all__ = ["FlareReach", "flare_reach", "measure_regions", "synthetic_flare"]

EXCESS = 0.5
"""A ring is flare while its rate exceeds the background's by this share of it (and by
three Poisson standard deviations of the ring's own count)."""


@dataclasses.dataclass(frozen=True)
class FlareReach:
    """What :func:`flare_reach` found around one source.

    ``halo_outer_px`` is the radius (from the source's centre) where the rate meets
    the background, None where no ring exceeds it; ``ghost_radius_px`` likewise
    around ``ghost_centre``; ``background_rate`` in events per pixel and second.
    """

    halo_outer_px: float | None
    ghost_centre: tuple[float, float]
    ghost_radius_px: float | None
    background_rate: float
    radius_px: float


def _meets_background(
    counts: np.ndarray, area: np.ndarray, seconds: float, background: float, start: int
) -> int | None:
    """The first ring from ``start`` on whose rate is background: three rings smoothed
    within :data:`EXCESS` of it, or the ring alone at or below it."""
    smooth_c = np.convolve(counts, np.ones(3), mode="same")
    smooth_a = np.convolve(area, np.ones(3), mode="same")
    expected = background * smooth_a * seconds
    excess = smooth_c - expected
    flare = (excess > EXCESS * expected) & (excess > 3.0 * np.sqrt(np.maximum(expected, 1.0)))
    # and above the background in the ring itself: the smoothing must not bridge a gap of
    # background between the halo and a ghost beyond it
    flare &= (smooth_a > 0) & (counts > background * area * seconds)
    if start >= flare.size or not flare[start]:
        return None
    below = np.flatnonzero(~flare[start:])
    return start + int(below[0]) if below.size else flare.size


def flare_reach(
    events: np.ndarray,
    sensor_size: SensorSize,
    source: LightSource,
    *,
    bin_px: float | None = None,
) -> FlareReach:
    """Measure how far one source's halo reaches, and its ghost's radius.

    Parameters
    ----------
    events : numpy.ndarray
        The recording's events (sorted).
    sensor_size : (width, height)
    source : LightSource
        Its centre and radius at each event's time (a detected source is ``steps``).
    bin_px : float, optional
        Ring width; default half the source's median radius, at least 2 px.

    Returns
    -------
    FlareReach

    Raises
    ------
    ParameterError
        No events while the source is present.
    """
    width, height = check_sensor_size(sensor_size)
    at = centred(events, source)
    x, y, t, cx, cy, r = at.x, at.y, at.t, at.cx, at.cy, at.r
    seconds = max(float(t[-1] - t[0]), 1.0) * 1e-6
    (mx, my), mr = at.median_centre(), float(np.median(r))
    step = max(2.0, mr / 2) if bin_px is None else float(bin_px)
    far = math.hypot(max(mx, width - 1 - mx), max(my, height - 1 - my))
    edges = np.arange(0.0, far + step, step)
    area = ring_pixels(mx, my, (width, height), edges)
    counts = np.histogram(at.distances(), bins=edges)[0].astype(np.float64)
    # the background: the median rate of the rings in the outer half of the frame's reach
    outer = (edges[:-1] >= far / 2) & (area > 0)
    rates = counts[outer] / (area[outer] * seconds)
    background = float(np.median(rates)) if rates.size else 0.0
    first = int(np.searchsorted(edges, mr + 2.0, side="right")) - 1  # just outside the rim
    ring = _meets_background(counts, area, seconds, background, max(first, 0))
    halo = None if ring is None else float(edges[min(ring, edges.size - 1)])
    gx, gy = width - 1 - mx, height - 1 - my
    g_area = ring_pixels(gx, gy, (width, height), edges)
    g_counts = np.histogram(np.hypot(x - (width - 1 - cx), y - (height - 1 - cy)), bins=edges)
    g_ring = _meets_background(g_counts[0].astype(np.float64), g_area, seconds, background, 0)
    ghost = None if g_ring is None else float(edges[min(g_ring, edges.size - 1)])
    if ghost is not None and halo is not None and math.hypot(gx - mx, gy - my) < halo:
        ghost = None  # the ghost lies in the halo: no ring of its own to measure
    return FlareReach(halo, (gx, gy), ghost, background, mr)


def measure_regions(events: np.ndarray, sensor_size: SensorSize, lights: Lights) -> Lights:
    """``lights`` with each source's halo and ghost sizes measured from ``events``.

    A source keeps the fixed factors of ``lights`` where nothing was measured
    (:func:`flare_reach` found no excess), and a halo never ends inside the source's
    rim (``margin_px``).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> ev = synthetic_flare(rng, (320, 240), (100, 80), radius=5, reach=50, strength=300)
    >>> lights = measure_regions(ev, (320, 240), Lights((LightSource.circle(100, 80, 5),)))
    >>> 40 <= lights.sources[0].halo_outer_px <= 60
    True
    """
    sources = []
    for s in lights.sources:
        found = flare_reach(events, sensor_size, s)
        changes: dict[str, float] = {}
        if found.halo_outer_px is not None:
            changes["halo_outer_px"] = max(found.halo_outer_px, found.radius_px + lights.margin_px)
        if found.ghost_radius_px is not None:
            changes["ghost_radius_px"] = found.ghost_radius_px
        sources.append(dataclasses.replace(s, **changes))
    note = (lights.note + "; " if lights.note else "") + "regions measured from the recording"
    return dataclasses.replace(lights, sources=tuple(sources), note=note)


def synthetic_flare(
    rng: np.random.Generator,
    sensor_size: SensorSize,
    centre: tuple[float, float],
    *,
    radius: float,
    reach: float,
    strength: float,
    background_hz: float = 2.0,
    ghost_radius: float = 0.0,
    duration_us: int = 100_000,
) -> np.ndarray:
    """A recording with a known flare: a light, its halo out to ``reach``, a ghost, noise.

    The background fires ``background_hz`` events per pixel and second everywhere; the
    light fills its disc; the halo's rate falls as ``(radius / d) ** 2`` times
    ``strength`` times the background's, out to ``reach`` px from the centre (and no
    farther); a ghost of ``ghost_radius`` fires at the halo's rate at its inner edge,
    reflected through the centre. For testing the measurement.
    """
    width, height = check_sensor_size(sensor_size)
    seconds = duration_us * 1e-6
    yy, xx = np.mgrid[:height, :width]
    d = np.hypot(xx - centre[0], yy - centre[1])
    rate = np.full(d.shape, background_hz)
    halo = (d > radius) & (d <= reach)
    rate[halo] += background_hz * strength * (radius / d[halo]) ** 2
    rate[d <= radius] += background_hz * strength * 4.0
    if ghost_radius > 0:
        g = np.hypot(xx - (width - 1 - centre[0]), yy - (height - 1 - centre[1]))
        rate[g <= ghost_radius] += background_hz * strength * 0.25
    n = rng.poisson(rate * seconds)
    px = np.repeat(np.arange(n.size), n.ravel())
    ev = np.zeros(px.size, dtype=EVENT_DTYPE)
    ev["x"], ev["y"] = px % width, px // width
    ev["t"] = rng.integers(0, duration_us, px.size)
    ev["p"] = rng.integers(0, 2, px.size)
    return sort_events(ev)
