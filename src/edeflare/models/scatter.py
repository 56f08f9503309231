"""Where a window's isolated events crowd: scattered light, not background activity.

A night lamp too slow for the light test (:func:`~edeflare.models.halos.window_lights`)
still scatters its light into isolated events, along its streaks and rings, around it.
A sensor's background activity fires isolated events too, but evenly over the sensor.
:func:`crowded_isolated` tells the two apart by place: an isolated event crowds where
more isolated events of its window lie around it than the window's typical (median)
density of them allows. The light-free shift
(:class:`~edeflare.models.infer.ModelDeflarer`) leaves the crowded ones to the network
and raises the rest as it raises the scene.

Measured on isolated events (fewer than 2 others in their 5x5 square) of light-free
windows, at 3 Poisson standard deviations
(``experiments/reference-window/README.md``, section 4): 88 % of the streak and ghost
events of issue 13's digitised real window crowd, 3 % of ``eflare-r-sim``'s background
activity, and a quarter to a half of the few isolated events of the real scenes
without a light.
"""

from __future__ import annotations

import numpy as np

from ..events import SensorSize, check_sensor_size

__all__ = ["SCATTER_CELL", "SCATTER_REACH", "crowded_isolated", "scatter_reach"]

SCATTER_CELL = 16
"""Pixels per side of the cells the isolated events are counted in."""

SCATTER_REACH = 1 / 6
"""How far from an event's cell its square reaches, as a share of the sensor's smaller
side (:func:`scatter_reach`): 120 px at 1280x720, 80 px at 640x480, 43 px at 346x260.
Scattered light reaches a few times a light's radius. The square must also stay well
inside the sensor: where it covers most of it, every square holds about the same events
and nothing stands out against their median."""


def scatter_reach(sensor_size: SensorSize, share: float = SCATTER_REACH) -> int:
    """:data:`SCATTER_REACH` of the sensor's smaller side, in pixels.

    Examples
    --------
    >>> scatter_reach((1280, 720)), scatter_reach((640, 480)), scatter_reach((346, 260))
    (120, 80, 43)
    """
    width, height = check_sensor_size(sensor_size)
    return int(min(width, height) * share)


def crowded_isolated(
    events: np.ndarray,
    sensor_size: SensorSize,
    isolated: np.ndarray,
    *,
    z: float,
    cell: int = SCATTER_CELL,
    reach: int | None = None,
) -> np.ndarray:
    """Which isolated events crowd: more isolated events around them than an even spread.

    For each ``isolated`` event, ``n`` is the number of other isolated events in the
    square of cells within ``reach`` pixels of its cell (cut at the sensor's edge) and
    ``lam`` what the window's median density of isolated events (the median over every
    cell's square) puts in that square. The event crowds where ``n - lam > z sqrt(lam +
    1)``. The median, not the mean: where the scattered light of one lamp holds most of
    a window's isolated events, their mean density is its own and nothing would stand
    out.

    Parameters
    ----------
    events : numpy.ndarray
        One window's events (:data:`~edeflare.events.EVENT_DTYPE`), on the sensor.
    sensor_size : (width, height)
    isolated : numpy.ndarray
        bool, one per event: the events judged (the others are never crowded).
    z : float
        Poisson standard deviations over the median density; at least 0.
    cell : int
        Cell side in pixels (:data:`SCATTER_CELL`).
    reach : int, optional
        Pixels from an event's cell to the edge of its square (default
        :func:`scatter_reach`: a sixth of the sensor's smaller side).

    Returns
    -------
    numpy.ndarray
        bool, one per event.

    Examples
    --------
    48 isolated events spread evenly over a 640x480 sensor (one per 80 px) crowd
    nowhere; 16 more within 24 px of each other crowd, and so do the 4 even ones whose
    square holds them.

    >>> from edeflare.events import make_events
    >>> gy, gx = np.mgrid[0:6, 0:8] * 80 + 40
    >>> cy, cx = np.mgrid[0:4, 0:4] * 8 + 300
    >>> x = np.concatenate([gx.ravel(), cx.ravel()])
    >>> y = np.concatenate([gy.ravel(), cy.ravel()])
    >>> ev = make_events(np.arange(x.size), x, y, np.ones(x.size))
    >>> int(crowded_isolated(ev[:48], (640, 480), np.ones(48, bool), z=3.0).sum())
    0
    >>> hit = crowded_isolated(ev, (640, 480), np.ones(64, bool), z=3.0)
    >>> int(hit[48:].sum()), int(hit[:48].sum())
    (16, 4)
    """
    width, height = check_sensor_size(sensor_size)
    isolated = np.asarray(isolated, dtype=bool)
    if isolated.shape != (events.size,):
        raise ValueError(f"isolated must hold one bool per event ({events.size}), got "
                         f"shape {isolated.shape}")  # fmt: skip
    if not z >= 0:
        raise ValueError(f"z must be >= 0, got {z!r}")
    if reach is None:
        reach = scatter_reach((width, height))
    if cell < 1 or reach < 0:
        raise ValueError(f"need cell >= 1 and reach >= 0, got cell={cell}, reach={reach}")
    out = np.zeros(events.size, dtype=bool)
    which = np.flatnonzero(isolated)
    if which.size < 2:
        return out
    gw, gh = -(-width // cell), -(-height // cell)
    cx = events["x"][which].astype(np.int64) // cell
    cy = events["y"][which].astype(np.int64) // cell
    # summed-area table of the isolated events per cell, a zero row and column first
    table = np.zeros((gh + 1, gw + 1), dtype=np.int64)
    np.add.at(table, (cy + 1, cx + 1), 1)
    table = table.cumsum(axis=0).cumsum(axis=1)
    k = reach // cell

    def square(ry: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Isolated events and cells in the square of cells within k of (ry, rx)."""
        y0, y1 = np.clip(ry - k, 0, gh), np.clip(ry + k + 1, 0, gh)
        x0, x1 = np.clip(rx - k, 0, gw), np.clip(rx + k + 1, 0, gw)
        count = table[y1, x1] - table[y0, x1] - table[y1, x0] + table[y0, x0]
        return count, (y1 - y0) * (x1 - x0)

    every_y, every_x = np.mgrid[0:gh, 0:gw]
    count, cells = square(every_y.ravel(), every_x.ravel())
    density = float(np.median(count / cells))  # isolated events per cell, typically
    count, cells = square(cy, cx)
    lam = density * cells
    out[which] = (count - 1 - lam) > z * np.sqrt(lam + 1.0)
    return out
