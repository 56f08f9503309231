"""How far a light's flare reaches, measured from the recording itself.

Scattered light falls off with distance from its source until it drowns in the
scene's own events. :func:`flare_reach` measures the event rate in rings around a
source (events per pixel and second, each event's distance taken from the source's
centre at its own time) and finds where it comes down to the background rate: that
radius is the outer edge of the source's halo. The ghost lies where the source
reflects through the optical centre, ``(W - 1 - cx, H - 1 - cy)``; its radius is where
the rate around that point comes down to the background in the same way, and it is a
ghost only if its events spread evenly round that point (:data:`GHOST_SPREAD`): a
reflection of the light is a smooth disc or ring, while scene that happens to lie there
(a lit table's edges) is not. :func:`measure_regions` makes the scorer's regions from
it: the fixed factors of the source radius (:class:`~edeflare.lights.Lights`) are the
least halo (a rate test cannot see flare that only replaces scene events near a light,
such as a lamp's flicker on the wall under it) and the ghost where none can be measured
apart from the halo; where a ghost is measured to be absent, there is no ghost region.

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

__all__ = ["FlareReach", "flare_reach", "ghost_spread", "measure_regions", "synthetic_flare"]

EXCESS = 0.5
"""A ring is flare while its rate exceeds the background's by this share of it (and by
three Poisson standard deviations of the ring's own count)."""

GHOST_SPREAD = 0.25
"""A ghost's events are spread evenly round the light's reflection: over
:data:`GHOST_SECTORS` sectors of its disc, the relative spread of their rates, beyond
what Poisson counts alone give, is at most this (drawn ghosts: below 0.1; the lit scene
under the DAVIS346 lamps' reflections: 0.36-1.0)."""

GHOST_SECTORS = 8


@dataclasses.dataclass(frozen=True)
class FlareReach:
    """What :func:`flare_reach` found around one source.

    ``halo_outer_px`` is the radius (from the source's centre) where the rate meets
    the background, None where no ring exceeds it; ``ghost_radius_px`` likewise
    around ``ghost_centre``, None where no ghost shows (``ghost_spread`` says whether
    an excess there was uneven: scene, not a ghost) or where the reflection lies in
    the halo (``ghost_in_halo``: not measurable apart from it); ``background_rate``
    in events per pixel and second.
    """

    halo_outer_px: float | None
    ghost_centre: tuple[float, float]
    ghost_radius_px: float | None
    background_rate: float
    radius_px: float
    ghost_spread: float | None = None
    ghost_in_halo: bool = False


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
    # a moving source's reflection moves too: how far apart the two are, in the median
    apart = float(np.median(np.hypot(2 * cx - (width - 1), 2 * cy - (height - 1))))
    in_halo = halo is not None and apart < halo
    spread = None
    if ghost is not None and in_halo:
        ghost = None  # the ghost lies in the halo: no ring of its own to measure
    elif ghost is not None:
        spread = ghost_spread(x - (width - 1 - cx), y - (height - 1 - cy), (gx, gy),
                              (width, height), ghost)  # fmt: skip
        if spread > GHOST_SPREAD:
            ghost = None  # an uneven excess: scene that lies there, not the light's image
    return FlareReach(halo, (gx, gy), ghost, background, mr, spread, in_halo)


def ghost_spread(
    dx: np.ndarray,
    dy: np.ndarray,
    centre: tuple[float, float],
    sensor_size: SensorSize,
    radius: float,
    sectors: int = GHOST_SECTORS,
) -> float:
    """How unevenly events lie round a point: the relative spread of their rates over
    ``sectors`` sectors of the disc of ``radius``, less what Poisson counts give.

    ``dx, dy`` are the events' offsets from the point (each at its own time for a
    moving point); ``centre`` is where it lies in the median, to count each sector's
    pixels on the sensor (sectors cut to under a third of the fullest by the frame's
    edge are left out). 0 for an even disc; 1 (at most) for rates as spread as
    their mean.

    Examples
    --------
    >>> yy, xx = np.mgrid[:41, :41]
    >>> inside = np.hypot(xx - 20, yy - 20) <= 15
    >>> dx, dy = (xx[inside] - 20.0), (yy[inside] - 20.0)
    >>> ghost_spread(np.repeat(dx, 20), np.repeat(dy, 20), (20, 20), (41, 41), 15) < 0.05
    True
    >>> half = dx > 0  # only one side lit: an edge, not a ghost
    >>> ghost_spread(np.repeat(dx[half], 20), np.repeat(dy[half], 20), (20, 20), (41, 41), 15) > 0.5
    True
    """
    width, height = check_sensor_size(sensor_size)
    yy, xx = np.mgrid[:height, :width]
    px, py = xx - centre[0], yy - centre[1]
    disc = np.hypot(px, py) <= radius

    def sector(ax: np.ndarray, ay: np.ndarray) -> np.ndarray:
        return ((np.arctan2(ay, ax) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors

    pixels = np.bincount(sector(px[disc], py[disc]), minlength=sectors).astype(np.float64)
    inside = np.hypot(dx, dy) <= radius
    counts = np.bincount(sector(dx[inside], dy[inside]), minlength=sectors).astype(np.float64)
    use = pixels >= pixels.max() / 3
    rates = counts[use] / pixels[use]
    mean = float(rates.mean()) if rates.size else 0.0
    if mean <= 0:
        return 1.0
    cv2 = float(rates.var()) / mean**2
    # what Poisson counts alone give: each sector's CV^2 at the mean rate, 1 / expected count
    poisson = float(np.mean(1.0 / (mean * pixels[use])))
    return min(1.0, math.sqrt(max(cv2 - poisson, 0.0)))


def measure_regions(events: np.ndarray, sensor_size: SensorSize, lights: Lights) -> Lights:
    """``lights`` with each source's halo and ghost sizes measured from ``events``.

    A halo ends where :func:`flare_reach` finds the rate meets the background, but
    never inside the fixed factor's reach (``halo_factor`` source radii): the factor is
    the least halo. A ghost is the measured disc; where the reflection lies in the halo
    the factor's ghost stays; where no ghost shows, the source gets no ghost region.

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
        changes: dict[str, float | bool] = {}
        least = lights.halo_factor * found.radius_px
        if found.halo_outer_px is not None and found.halo_outer_px > least:
            changes["halo_outer_px"] = found.halo_outer_px
        if found.ghost_radius_px is not None:
            changes["ghost_radius_px"] = found.ghost_radius_px
        elif not found.ghost_in_halo:
            changes["ghost"] = False
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
