"""What every rule of one window reads: its events, span, lights, and what they share.

The rules of a window ask the same questions (where are the lights, where can their
ghosts be, which events lie on their diffraction spikes); a :class:`WindowContext`
answers each once, on first use, and gives the same answer to every rule after.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..events import SensorSize

__all__ = ["WindowContext"]


class WindowContext:
    """One window of events, as the rules see it.

    Parameters
    ----------
    events : numpy.ndarray
        The window's events (sorted).
    sensor_size : (width, height)
    span_us : int
        The part of the window the stream covers (µs): the lights' rates are counted
        over it (:func:`edeflare.lights.cells.covered_us`).
    support : numpy.ndarray or None
        Each event's count of other events in its 5x5 square, where the network's
        per-event refinement counted it (:func:`~edeflare.models.mask_kernels.event_support`).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ctx = WindowContext(make_events([0, 5], [1, 2], [1, 1], [1, 0]), (8, 8), 20_000)
    >>> ctx.has_lights
    False
    """

    def __init__(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        span_us: int,
        support: np.ndarray | None = None,
    ) -> None:
        self.events = events
        self.sensor_size = sensor_size
        self.span_us = span_us
        self.support = support

    @cached_property
    def lights(self) -> np.ndarray:
        """The window's light cells (:func:`edeflare.lights.window_lights`)."""
        from ..lights.cells import window_lights

        return window_lights(self.events, self.sensor_size, self.span_us)

    @property
    def has_lights(self) -> bool:
        """Whether the window holds a light."""
        return bool(self.lights.any())

    @cached_property
    def ghost_cells(self) -> np.ndarray:
        """Where the lights' ghosts can be (:func:`~edeflare.rules.ghost.ghost_cells`)."""
        from .ghost import ghost_cells

        return ghost_cells(self.events, self.sensor_size, self.span_us, lights=self.lights)

    @cached_property
    def on_spikes(self) -> np.ndarray:
        """Per event: on a light's spike (:func:`~edeflare.rules.streak.in_streak_prior`)."""
        from .streak import in_streak_prior

        return in_streak_prior(self.events, self.sensor_size, self.span_us, lights=self.lights)
