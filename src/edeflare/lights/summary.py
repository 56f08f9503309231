"""How a recording fares with the light test: in how many windows it finds a light.

Every light feature of a learned keep head and every prior of a rule-based model read
the per-window light test (:func:`~edeflare.lights.cells.window_lights`). A light that
fires too slowly for it (a steady lamp under a still camera) leaves every window
light-free, and the model then judges its flare as flare without a light.
:func:`light_test_summary` says so before de-flaring (``edeflare info --lights``): the
share of windows with a light, and how fast the brightest compact region of each window
fires against the rate the test asks of a light.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, check_sensor_size
from .cells import LIGHT_CORE_RATE, covered_us, window_lights
from .detect import detect_light_source

__all__ = ["LightTestSummary", "light_test_summary"]


@dataclasses.dataclass(frozen=True)
class LightTestSummary:
    """What the light test found over a recording's windows.

    Attributes
    ----------
    windows : int
        Windows holding events.
    with_light : int
        Those in which the test found a light.
    brightest_rate : float or None
        The median over those windows of the rate of each one's brightest compact region
        (:func:`~edeflare.lights.detect_light_source`): its events over its firing pixels
        and the window's covered milliseconds; None where no window holds one.
    """

    windows: int
    with_light: int
    brightest_rate: float | None

    @property
    def share(self) -> float:
        """The share of windows with a light (NaN without windows)."""
        return self.with_light / self.windows if self.windows else float("nan")

    def lines(self, window_us: int) -> list[str]:
        """The summary as ``edeflare info`` prints it."""
        out = [f"light test  a light in {self.with_light:,} of {self.windows:,} windows of "
               f"{window_us / 1000:g} ms"]  # fmt: skip
        if self.brightest_rate is not None:
            out.append(
                f"brightest   {self.brightest_rate:.3g} events per firing pixel and ms "
                f"(median over windows; a light's bright pixels fire at {LIGHT_CORE_RATE:g})"
            )
        return out


def light_test_summary(
    windows: Iterable[tuple[int, np.ndarray]],
    sensor_size: SensorSize,
    window_us: int = 20_000,
) -> LightTestSummary:
    """Run the light test on each ``(start_us, events)`` window and summarise it.

    Examples
    --------
    A 16x16 block firing 20 events per pixel in 20 ms (1 per pixel and ms) is a light;
    the same block firing 4 (0.2 per pixel and ms) is not, though it is the brightest
    region of its window:

    >>> from edeflare.events import make_events, iter_time_windows
    >>> yy, xx = np.mgrid[16:32, 40:56]
    >>> def block(per_pixel, t0):
    ...     n = per_pixel * xx.size
    ...     return make_events(t0 + np.arange(n) * 20_000 // n, np.tile(xx.ravel(), per_pixel),
    ...                        np.tile(yy.ravel(), per_pixel), np.ones(n))
    >>> ev = np.concatenate([block(20, 0), block(4, 20_000)])
    >>> s = light_test_summary(iter_time_windows(ev, 20_000), (96, 64))
    >>> s.windows, s.with_light, round(s.brightest_rate, 2)
    (2, 1, 0.6)
    """
    size = check_sensor_size(sensor_size)
    window_us = int(window_us)
    if window_us <= 0:
        raise ParameterError(f"window_us must be positive, got {window_us}")
    n = lit = 0
    rates: list[float] = []
    for start, events in windows:
        if not events.size:
            continue
        n += 1
        span = covered_us(events, start, window_us)
        lit += bool(window_lights(events, size, span).any())
        rate = _brightest_rate(events, size, span)
        if rate is not None:
            rates.append(rate)
    return LightTestSummary(n, lit, float(np.median(rates)) if rates else None)


def _brightest_rate(events: np.ndarray, size: SensorSize, span_us: int) -> float | None:
    """Events per firing pixel and millisecond of the window's brightest compact region."""
    try:
        (circle,) = detect_light_source(events, size)
    except ParameterError:  # no compact region: nothing to rate
        return None
    x, y = events["x"].astype(np.float64), events["y"].astype(np.float64)
    inside = np.hypot(x - circle.cx, y - circle.cy) <= circle.r
    pixels = np.unique(events["y"][inside].astype(np.int64) * size[0] + events["x"][inside])
    return int(inside.sum()) / pixels.size / (span_us / 1000.0) if pixels.size else None
