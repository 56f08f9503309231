"""Rings around a light source: its events' distances and the sensor's pixels per ring.

The two measurements of a light from its recording, its radius
(:func:`~edeflare.lights.detect.light_radius`) and its flare's reach
(:func:`~edeflare.lights.reach.flare_reach`), both compare event counts in rings
around the source with the ring's pixels on the sensor.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize
from .source import LightSource

__all__ = ["Centred", "centred", "ring_pixels"]


class Centred:
    """The events of a recording while ``source`` is present, with its disc at each
    event's time: ``x, y, t`` and ``cx, cy, r`` (float arrays of one length)."""

    def __init__(self, events: np.ndarray, source: LightSource) -> None:
        cx, cy, r = source.at(events["t"])
        present = np.isfinite(cx)
        if not present.any():
            raise ParameterError("no events while the light source is present")
        self.x = events["x"][present].astype(np.float64)
        self.y = events["y"][present].astype(np.float64)
        self.t = events["t"][present]
        self.cx, self.cy, self.r = cx[present], cy[present], r[present]

    def distances(self) -> np.ndarray:
        """Each event's distance from the source's centre at its time."""
        return np.hypot(self.x - self.cx, self.y - self.cy)

    def median_centre(self) -> tuple[float, float]:
        """Where the source is in the median (the rings' centre on the sensor)."""
        return float(np.median(self.cx)), float(np.median(self.cy))


def centred(events: np.ndarray, source: LightSource) -> Centred:
    """:class:`Centred` of ``events`` around ``source`` (ParameterError if it is never there).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 10], [3, 6], [4, 4], [1, 1])
    >>> centred(ev, LightSource.circle(3, 4, 1)).distances().tolist()
    [0.0, 3.0]
    """
    return Centred(events, source)


def ring_pixels(cx: float, cy: float, sensor_size: SensorSize, edges: np.ndarray) -> np.ndarray:
    """How many pixel centres of the sensor lie in each ring ``edges[i] <= d < edges[i+1]``
    around ``(cx, cy)``: a ring cut by the frame's edge counts only its pixels on it.

    Examples
    --------
    >>> ring_pixels(0.0, 0.0, (3, 1), np.array([0.0, 1.0, 3.0])).tolist()
    [1.0, 2.0]
    """
    width, height = sensor_size
    yy, xx = np.mgrid[:height, :width]
    d = np.hypot(xx - cx, yy - cy).ravel()
    return np.histogram(d, bins=edges)[0].astype(np.float64)
