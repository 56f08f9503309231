"""Finding light sources in events: the brightest compact regions of the event density.

:func:`detect_light_source` finds them in a count map or a stream (a reference
pass of a paired capture, one window of a recording); :func:`detect_lights`
runs it window by window over a recording and makes the :class:`Lights` a
scorer needs where no annotation exists.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from typing import Any

import numpy as np
from scipy import ndimage

from ..errors import ParameterError
from ..events import (
    EVENT_DTYPE,
    SensorSize,
    check_events,
    check_sensor_size,
    count_map,
    window_start_for,
)
from .response import light_response
from .rings import centred, ring_pixels
from .shapes import Circle
from .source import Lights, LightSource

__all__ = [
    "CORE_SHARE",
    "count_map_of",
    "detect_light_source",
    "detect_lights",
    "gaussian_on_support",
    "light_radius",
    "median3",
    "track_lights",
]


def count_map_of(data: np.ndarray, sensor_size: SensorSize | None) -> np.ndarray:
    """``(H, W)`` float64 counts from events (needs ``sensor_size``) or a 2-D map."""
    if isinstance(data, np.ndarray) and data.dtype == EVENT_DTYPE:
        if sensor_size is None:
            raise ParameterError("sensor_size is required with events")
        return count_map(data, sensor_size).astype(float)
    counts = np.asarray(data, dtype=np.float64)
    if counts.ndim != 2:
        raise ParameterError(f"expected events or an (H, W) count map, got shape {counts.shape}")
    if sensor_size is not None and check_sensor_size(sensor_size) != counts.shape[::-1]:
        raise ParameterError(f"count map {counts.shape} (H, W) does not match sensor {sensor_size}")
    if not np.isfinite(counts).all() or (counts < 0).any():
        raise ParameterError("count map must hold finite non-negative values")
    return counts


_DENSE_SHARE = 0.25  # above this share of non-zero pixels the plain filters are faster


def median3(counts: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.median_filter(counts, size=3, mode="nearest")`` of a map of counts
    (``>= 0``), the same numbers computed only where they can differ from 0.

    The median of nine non-negative values is 0 unless at least five of them are positive,
    so a sparse map (a few ms of a recording, isolated events everywhere) needs the
    median at a few pixels only: a 1280x720 window of a night recording costs ~100 ms in
    the plain filter, a few here. Dense maps go to the plain filter.

    Examples
    --------
    >>> c = np.zeros((5, 6)); c[1:4, 1:4] = [[1, 2, 3], [4, 5, 6], [7, 8, 9]]; c[0, 5] = 50
    >>> bool((median3(c) == ndimage.median_filter(c, size=3, mode="nearest")).all())
    True
    >>> float(median3(c)[2, 2]), float(median3(c)[0, 5])   # the centre; a lone hot pixel
    (5.0, 0.0)
    """
    counts = np.asarray(counts, dtype=np.float64)
    if (
        counts.ndim != 2
        or min(counts.shape) < 3
        or np.count_nonzero(counts) > _DENSE_SHARE * counts.size
        or bool((counts < 0).any())  # not counts: the shortcut's premise fails
    ):
        return ndimage.median_filter(counts, size=3, mode="nearest")
    h, w = counts.shape
    padded = np.pad(counts, 1, mode="edge")
    positive = (padded > 0).view(np.uint8)
    around = np.zeros((h, w), np.uint8)
    for dy in range(3):
        for dx in range(3):
            around += positive[dy : dy + h, dx : dx + w]
    out = np.zeros((h, w), np.float64)
    ys, xs = np.nonzero(around >= 5)
    if ys.size:
        block = np.stack([padded[ys + dy, xs + dx] for dy in range(3) for dx in range(3)], 1)
        out[ys, xs] = np.partition(block, 4, axis=1)[:, 4]
    return out


def gaussian_on_support(values: np.ndarray, sigma_px: float) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(values, sigma_px, mode="nearest")`` of a map that is
    0 outside a small region (a median-filtered window: its dense parts), computed on the
    region's box and the kernel's reach around it: the same sums in the same order, so the
    same numbers; the rest of the map stays 0, as the full filter leaves it.

    Examples
    --------
    >>> v = np.zeros((60, 80)); v[30:33, 40:44] = 3.0; v[0, 0] = 1.0
    >>> full = ndimage.gaussian_filter(v, 2.0, mode="nearest")
    >>> bool((gaussian_on_support(v, 2.0) == full).all())
    True
    """
    values = np.asarray(values, dtype=np.float64)
    reach = int(4.0 * float(sigma_px) + 0.5)  # scipy's kernel radius at its truncate=4.0
    rows, cols = np.nonzero(values.any(axis=1))[0], np.nonzero(values.any(axis=0))[0]
    if not rows.size:
        return np.zeros_like(values)
    h, w = values.shape
    y0, y1 = max(rows[0] - 2 * reach, 0), min(rows[-1] + 2 * reach + 1, h)
    x0, x1 = max(cols[0] - 2 * reach, 0), min(cols[-1] + 2 * reach + 1, w)
    if (y1 - y0) * (x1 - x0) > 0.5 * values.size:
        return ndimage.gaussian_filter(values, float(sigma_px), mode="nearest")
    out = np.zeros_like(values)
    out[y0:y1, x0:x1] = ndimage.gaussian_filter(
        values[y0:y1, x0:x1], float(sigma_px), mode="nearest"
    )
    return out


def detect_light_source(
    data: np.ndarray,
    sensor_size: SensorSize | None = None,
    *,
    sigma_px: float = 2.0,
    level: float = 0.5,
    max_sources: int = 1,
    min_area_px: int = 4,
    margin_px: float = 1.0,
) -> list[Circle]:
    """Find the brightest compact region(s) of the event density: the light source(s).

    The per-pixel event counts are median-filtered (3x3, removing isolated hot
    pixels), smoothed with a Gaussian of ``sigma_px``, and thresholded at
    ``level`` times their maximum. Connected regions (8-connectivity) of at
    least ``min_area_px`` pixels are ranked by their peak density, and the
    first ``max_sources`` become circles: centre at the density-weighted
    centroid, radius ``sqrt(area / pi) + margin_px`` (the smoothing pulls the
    threshold contour inside the source's rim; the margin keeps the rim a
    source pixel rather than glare). Run it on the reference pass, where
    the source is not spread by the filter; sources need a radius of at least
    about 2 pixels to survive the median filter.

    Parameters
    ----------
    data : numpy.ndarray
        Events (with ``sensor_size``) or an ``(H, W)`` count map.
    sensor_size : (width, height), optional
    sigma_px : float
        Gaussian smoothing (pixels).
    level : float
        Threshold as a fraction of the smoothed maximum.
    max_sources : int
        How many regions to return at most.
    min_area_px : int
        Smallest region kept (pixels above the threshold).
    margin_px : float
        Added to each circle's equivalent radius.

    Returns
    -------
    list of Circle
        Brightest first.

    Raises
    ------
    ParameterError
        No events, or no region large enough.

    Examples
    --------
    >>> counts = np.zeros((40, 60)); yy, xx = np.mgrid[:40, :60]
    >>> counts[(xx - 30) ** 2 + (yy - 20) ** 2 <= 25] = 100.0
    >>> counts[3, 3] = 1e4  # a hot pixel
    >>> (c,) = detect_light_source(counts)
    >>> round(c.cx), round(c.cy), round(c.r)
    (30, 20, 6)
    """
    counts = count_map_of(data, sensor_size)
    if not 0 < level < 1:
        raise ParameterError(f"level must lie in (0, 1), got {level}")
    if int(max_sources) < 1:
        raise ParameterError(f"max_sources must be >= 1, got {max_sources}")
    smooth = median3(counts)
    if sigma_px > 0:
        smooth = gaussian_on_support(smooth, float(sigma_px))
    peak = float(smooth.max()) if smooth.size else 0.0
    if peak <= 0:
        raise ParameterError("no events (after removing isolated pixels): no light source found")
    labels, n = ndimage.label(smooth >= level * peak, structure=np.ones((3, 3), dtype=bool))
    # each region's pixels and peak, from its labelled pixels alone (ndimage.maximum sorts
    # the whole frame: most of a sparse window's time); counts and maxima are exact
    inside = labels > 0
    lab, val = labels[inside], smooth[inside]
    area = np.bincount(lab, minlength=n + 1)[1:].astype(np.float64)
    peaks = np.full(n + 1, -np.inf)
    np.maximum.at(peaks, lab, val)
    peaks = peaks[1:]
    order = [int(i) for i in np.argsort(-peaks, kind="stable") if area[i] >= min_area_px]
    if not order:
        raise ParameterError(
            f"no bright region of at least {min_area_px} pixels; give the light as circle:CX,CY,R"
        )
    lights = []
    for i in order[: int(max_sources)]:
        cy, cx = ndimage.center_of_mass(smooth, labels, i + 1)
        radius = math.sqrt(area[i] / math.pi) + max(0.0, float(margin_px))
        lights.append(Circle(float(cx), float(cy), radius))
    return lights


def detect_lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int = 20_000,
    *,
    max_sources: int = 1,
    **options: Any,
) -> Lights:
    """Detect the light sources window by window: the brightest compact regions.

    Each aligned window of ``window_us`` goes through
    :func:`detect_light_source` (``max_sources`` regions,
    brightest first); the ``k``-th detection of each window makes the
    ``k``-th source, constant within the window (:meth:`LightSource.steps`).
    ``options`` go to :class:`Lights` (``margin_px``, ``halo_factor``,
    ``ghost_factor``).

    Raises
    ------
    ParameterError
        No events, or no light found in any window.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[:5, :5]
    >>> n = xx.size * 10
    >>> ev = make_events(np.arange(n) * 10, np.tile(xx.ravel() + 20, 10),
    ...                  np.tile(yy.ravel() + 30, 10), np.ones(n, int))
    >>> src = detect_lights(ev, (64, 48), 1_000).sources[0]
    >>> src.kind, [round(float(v)) for v in src.table[0, 1:3]]
    ('steps', [22, 32])
    """
    check_events(events, sensor_size)
    size = check_sensor_size(sensor_size)
    if events.size == 0:
        raise ParameterError("no events: no light source to detect")
    t = events["t"]
    start = window_start_for(int(t[0]), window_us)
    n_windows = (int(t[-1]) - start) // window_us + 1
    edges = np.searchsorted(t, start + window_us * np.arange(n_windows + 1), side="left")
    rows = np.full((max_sources, n_windows, 4), np.nan)
    rows[:, :, 0] = start + window_us * np.arange(n_windows)
    found = 0
    for w in range(n_windows):
        chunk = events[edges[w] : edges[w + 1]]
        if chunk.size == 0:
            continue
        try:
            circles = detect_light_source(chunk, size, max_sources=max_sources)
        except ParameterError:
            continue
        for k, c in enumerate(circles):
            rows[k, w, 1:] = (c.cx, c.cy, c.r)
            found += 1
    if not found:
        raise ParameterError(
            "no light source detected in any window; annotate the lights (--lights JSON)"
        )
    sources = tuple(
        LightSource.steps(rows[k], name=f"detected-{k}")
        for k in range(max_sources)
        if np.isfinite(rows[k, :, 1]).any()
    )
    return Lights(sources, note=f"detected per {window_us} us window", **options)


CORE_SHARE = 0.05
"""A light ends where the event rate in a ring around it falls below this share of its
core's rate (:func:`light_radius`): on the annotated recordings the annotated edges lie
there (Gen3 blob 36 px against 38 found, DAVIS346 lamps 10 and 9 against 10 and 10)."""


def light_radius(
    events: np.ndarray,
    sensor_size: SensorSize,
    source: LightSource,
    *,
    share: float = CORE_SHARE,
    step_px: float = 2.0,
) -> float:
    """A source's radius from the rate of events in rings around its centre.

    The core's rate is the mean over the rings within half the detected radius; the
    radius is the inner edge of the first ring beyond that whose rate is below
    ``share`` of it (the detected median radius if none is).

    Examples
    --------
    >>> yy, xx = np.mgrid[:64, :64]
    >>> disc = np.hypot(xx - 32, yy - 32) < 10
    >>> n = int(disc.sum())
    >>> from edeflare.events import make_events
    >>> ev = make_events(np.arange(5 * n), np.tile(xx[disc], 5), np.tile(yy[disc], 5),
    ...                  np.ones(5 * n, int))
    >>> light_radius(ev, (64, 64), LightSource.circle(32, 32, 4))
    10.0
    """
    at = centred(events, source)
    detected = float(np.median(at.r))
    edges = np.arange(0.0, 6 * detected + 2 * step_px, step_px)
    area = ring_pixels(*at.median_centre(), sensor_size, edges)  # cut by the frame's edge
    count = np.histogram(at.distances(), edges)[0]
    rate = np.divide(count, area, out=np.zeros(area.shape), where=area > 0)
    inner = edges[1:] <= max(detected / 2, step_px)
    core = float(rate[inner].mean())
    below = np.flatnonzero((rate < share * core) & (edges[:-1] >= detected / 2))
    return float(edges[below[0]]) if below.size and core > 0 else detected


def _follow(rows: np.ndarray) -> np.ndarray:
    """Detections of each window (``(k, windows, 4)``, brightest first) reordered so that
    the ``k``-th row follows one source: each window's detections go to the sources
    whose last positions are nearest (all assignments tried; a few sources)."""
    k = rows.shape[0]
    out = rows.copy()
    last = np.full((k, 2), np.nan)
    for w in range(rows.shape[1]):
        here = [i for i in range(k) if np.isfinite(rows[i, w, 1])]
        if not here:
            continue
        best, best_cost = None, np.inf
        for perm in itertools.permutations(range(k), len(here)):
            cost = 0.0
            for i, j in zip(here, perm, strict=True):
                if np.isfinite(last[j, 0]):
                    cost += math.hypot(*(rows[i, w, 1:3] - last[j]))
            if cost < best_cost:
                best, best_cost = perm, cost
        out[:, w, 1:] = np.nan
        for i, j in zip(here, best, strict=True):  # type: ignore[arg-type]
            out[j, w, 1:] = rows[i, w, 1:]
            last[j] = rows[i, w, 1:3]
    return out


def track_lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    *,
    max_sources: int = 1,
    window_us: int = 2_000,
    **options: Any,
) -> Lights:
    """Detect and follow the light sources: a moving disc each, its radius from its rings.

    The brightest compact regions of each ``window_us`` window (:func:`detect_lights`)
    are followed from window to window (each detection to the nearest source's last
    place), each source becomes a ``track`` through its windows' centres (linear in
    time: a light that moves 13 px a millisecond is where it is, not where it was on
    average over a window), its radius is measured from the rate of events in rings
    around it (:func:`light_radius`), and its pixels count as its own for as long as
    they keep firing after it has passed (``response_us``: a moving light's pixels
    settle; measured by :func:`~edeflare.lights.light_response`, one window where the
    light stays put or nothing can be measured).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[:5, :5]
    >>> n = xx.size * 10
    >>> ev = make_events(np.arange(n) * 10, np.tile(xx.ravel() + 20, 10),
    ...                  np.tile(yy.ravel() + 30, 10), np.ones(n, int))
    >>> src = track_lights(ev, (64, 48), window_us=1_000).sources[0]
    >>> src.kind, [round(float(v[0])) for v in src.at(np.array([100]))[:2]]
    ('track', [22, 32])
    """
    found = detect_lights(events, sensor_size, window_us, max_sources=max_sources)
    blank = np.full_like(found.sources[0].table, np.nan)
    rows = np.stack([s.table for s in found.sources] + [blank] * (max_sources - len(found.sources)))
    rows[:, :, 0] = found.sources[0].table[:, 0]
    rows = _follow(rows)
    sources = []
    for k in range(max_sources):
        table = rows[k][np.isfinite(rows[k, :, 1])]
        if not table.size:
            continue
        steps = LightSource.steps(rows[k])
        table[:, 3] = light_radius(events, check_sensor_size(sensor_size), steps)
        table[:, 0] += window_us / 2  # the window's middle
        name = f"detected-{k}"
        if len(table) > 1:
            source = LightSource.track(table.tolist(), name=name, response_us=float(window_us))
            measured = light_response(events, source).response_us
            if measured is not None:
                source = dataclasses.replace(source, response_us=measured)
        else:
            source = LightSource.circle(*table[0, 1:], name=name)
        sources.append(source)
    note = f"detected per {window_us} us window and followed"
    return Lights(tuple(sources), note=note, **options)
