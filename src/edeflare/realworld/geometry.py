"""Glare zones around light sources and the cleaning of a reference pass."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, check_events, check_sensor_size
from ..lights.shapes import Shape, _window, light_mask
from ._common import _pixel_mask_of

__all__ = ["clean_reference", "glare_mask"]


def glare_mask(
    lights: Sequence[Shape], sensor_size: SensorSize, glare_radius_px: float
) -> np.ndarray:
    """``(H, W)`` bool: the glare zone, within ``glare_radius_px`` of a source but inside none.

    A pixel is in the zone when the Euclidean distance from its centre to the
    nearest light source's area (disc or polygon) is at most
    ``glare_radius_px``, and its centre is inside no source. For a circle
    ``(cx, cy, r)`` this is the ring ``r < d <= r + glare_radius_px`` around
    the centre. A radius of 0 gives an empty zone.

    Examples
    --------
    >>> from edeflare.lights import Circle
    >>> m = glare_mask([Circle(3, 3, 1)], (7, 7), 1)
    >>> for row in m.astype(int)[1:6]:
    ...     print(*row)
    0 0 0 1 0 0 0
    0 0 1 0 1 0 0
    0 1 0 0 0 1 0
    0 0 1 0 1 0 0
    0 0 0 1 0 0 0
    """
    width, height = check_sensor_size(sensor_size)
    radius = float(glare_radius_px)
    if not math.isfinite(radius) or radius < 0:
        raise ParameterError(f"glare_radius_px must be a finite number >= 0, got {glare_radius_px}")
    zone = np.zeros((height, width), dtype=bool)
    if radius == 0:
        return zone
    for shape in lights:
        win = _window(shape, radius, (width, height))
        if win is not None:
            rows, cols, xx, yy = win
            zone[rows, cols] |= shape.distance(xx, yy) <= radius
    return zone & ~light_mask(lights, (width, height))


def clean_reference(
    events: np.ndarray,
    sensor_size: SensorSize,
    lights: Sequence[Shape],
    *,
    glare_radius_px: float = 40.0,
) -> np.ndarray:
    """Remove residual glare from a reference stream, keeping the light sources themselves.

    Events on pixels of the glare zone (:func:`glare_mask`) are removed;
    every other event is kept, in particular those on the sources' own
    pixels (the light is part of the scene) and those farther than
    ``glare_radius_px`` from every source.

    Parameters
    ----------
    events : numpy.ndarray
        The reference stream (not modified).
    sensor_size : (width, height)
    lights : sequence of Circle or Polygon
        Light sources in sensor pixel coordinates.
    glare_radius_px : float
        Width of the glare zone around each source (pixels).

    Returns
    -------
    numpy.ndarray
        A new stream without the glare zone's events.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2], [5, 7, 9], [5, 5, 5], [1, 1, 1])
    >>> from edeflare.lights import Circle
    >>> clean_reference(ev, (12, 12), [Circle(5, 5, 1)], glare_radius_px=2)["x"].tolist()
    [5, 9]
    """
    size = check_sensor_size(sensor_size)
    check_events(events, size)
    zone = glare_mask(lights, size, glare_radius_px)
    return events[~_pixel_mask_of(events, zone)]
