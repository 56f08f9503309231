r"""Where a window's reflective ghosts can be: a parameter-free prior from lens geometry.

A lens ghost of a bright source at :math:`L` is an image of it reflected between lens
surfaces; it lies on the line through the optical centre :math:`c`, at
:math:`c + k (L - c)` for a factor :math:`k` set by the lens (negative: across the
centre; the simulator's ghosts, :class:`edeflare.sim.flare.GhostSpec`, use the same
geometry). Far from its source a ghost is a ring or disc of sparse events that looks
like scene texture to a network that sees it without the light, so a mask model finds
it hard to drop (``benchmarks/ghost_removal.py``). The prior marks the cells a ghost of
a window's lights can reach: the dense cells (the lights) are reflected through the
sensor's centre at every factor of :data:`GHOST_FACTORS`, the result widened by
``widen`` cells, and the lights themselves (and the cells next to them) left out.
:class:`~edeflare.models.infer.ModelDeflarer` lowers the keep logit of the events in
it by the card's ``ghost_shift``: an event there is dropped only where the network
already leaned towards dropping it, not wherever the prior says. Within the cells, the
prior covers only sparse events (:data:`GHOST_MAX_NEIGHBOURS`): a ghost reaches a real
sensor as scattered specks, while the scene its cells also cover (a lit bench across
the centre from two lamps) fires along connected edges.

It needs no learning and no calibration beyond what counts as a light: a cell of
``cell x cell`` pixels firing at least :data:`LIGHT_RATE` events per pixel and
millisecond (320 events in an 8x8 cell in 20 ms).
"""

from __future__ import annotations

import dataclasses
import functools

import numba
import numpy as np
from scipy import ndimage

from ..events import SensorSize, check_sensor_size
from ..lights.cells import light_cells
from . import Rule, knob
from .context import WindowContext

__all__ = [
    "GHOST_FACTORS",
    "GHOST_MAX_NEIGHBOURS",
    "GHOST_RULE",
    "GhostParams",
    "ghost_cells",
    "in_ghost_prior",
    "light_cells",
]

GHOST_FACTORS: tuple[float, ...] = (
    -0.5, -1.0, -1.5, -2.0, -2.5, -3.0, -3.5, -4.0, -4.5, -5.0, 0.4, 0.6,
)  # fmt: skip
"""Ghost position factors ``k`` (ghost at ``c + k (L - c)``): across the centre from half
to five times the source's distance, and 0.4-0.6 of the way towards it."""

GHOST_MAX_NEIGHBOURS = 4
"""The prior covers an event in its cells only where the event's 3x3 neighbourhood holds
at most this many events of the window, the event itself included. Chosen on the ghost
benchmark's set and the real recordings (the study ``ghosts``, ``docs/studies.md``): with a
shift of 1 it keeps all of the simulated ghosts the ungated prior drops (0.873 against
0.874) and two thirds of the DAVIS lamps' background it cost (63.5 % kept against 61.0 %;
65.1 % without the prior)."""


def ghost_cells(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    widen: int = 2,
    factors: tuple[float, ...] = GHOST_FACTORS,
    lights: np.ndarray | None = None,
) -> np.ndarray:
    """The cells (``cell`` x ``cell`` pixels) of a window where a ghost of its lights can be.

    Parameters
    ----------
    events : structured array
        One window's events.
    sensor_size : (width, height)
    window_us : int
        The window's length (what :data:`LIGHT_RATE` is counted over).
    cell : int
        Cell size in pixels.
    widen : int
        Cells added around the reflected lights (ghosts are wider than their
        source, and the factors are a sampling).
    factors : tuple of float
        Ghost position factors.
    lights : numpy.ndarray, optional
        The window's :func:`light_cells` when already counted (the halo prior
        counts them too); computed here otherwise.

    Returns
    -------
    numpy.ndarray
        bool, shape ``(ceil(height / cell), ceil(width / cell))``.

    Examples
    --------
    A light in the top-left corner of a 64x64 sensor: its ghosts fall towards the
    bottom-right, across the centre.

    >>> from edeflare.events import make_events
    >>> n = 400
    >>> ev = make_events(np.arange(n) * 50, np.arange(n) % 8, np.arange(n) // 8 % 8,
    ...                  np.ones(n))
    >>> g = ghost_cells(ev, (64, 64), 20_000)
    >>> g.shape, bool(g[0, 0]), bool(g[7, 7]), bool(g[4, 4])
    ((8, 8), False, True, True)
    """
    width, height = check_sensor_size(sensor_size)
    if widen < 0:
        raise ValueError(f"widen must be >= 0, got {widen}")
    if lights is None:
        lights = light_cells(events, sensor_size, window_us, cell=cell)
    h, w = lights.shape
    if (h, w) != (-(-height // cell), -(-width // cell)):
        raise ValueError(
            f"lights has shape {lights.shape}, not the {width}x{height} sensor's cells"
        )
    prior = np.zeros((h, w), dtype=bool)
    if not lights.any():
        return prior
    back_from, back_to, forth = _ghost_maps(width, height, cell, tuple(factors))
    flat, lit = prior.ravel(), lights.ravel()
    flat[back_to[lit[back_from]]] = True
    ghosts = forth[:, np.flatnonzero(lit)]
    flat[ghosts[ghosts >= 0]] = True
    if widen:
        prior = ndimage.binary_dilation(prior, iterations=widen)
    return prior & ~ndimage.binary_dilation(lights, iterations=1)


@functools.lru_cache(maxsize=16)
def _ghost_maps(
    width: int, height: int, cell: int, factors: tuple[float, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where ghosts fall, per sensor: the same for every window, so computed once.

    For every factor ``k``, a cell holds a ghost if the point it maps back to is a light
    (this fills the ghosts larger than their source, ``|k| > 1``): the pairs (cell it
    maps back to, cell) as ``back_from``, ``back_to`` (flat cell indices, on the grid
    only). And every light marks the cell of its ghost (those smaller, ``|k| < 1``):
    ``forth[j, c]``, the flat cell of the ghost of cell ``c`` at factor ``j``, -1 off
    the grid."""
    h, w = -(-height // cell), -(-width // cell)
    cy, cx = height / 2 / cell, width / 2 / cell  # the centre, in cells
    yy, xx = np.mgrid[0:h, 0:w] + 0.5  # cell centres
    ids = np.arange(h * w).reshape(h, w)
    back_from, back_to, forth = [], [], []
    for k in factors:
        sy = np.floor(cy + (yy - cy) / k).astype(np.int64)
        sx = np.floor(cx + (xx - cx) / k).astype(np.int64)
        ok = (sy >= 0) & (sy < h) & (sx >= 0) & (sx < w)
        back_from.append(sy[ok] * w + sx[ok])
        back_to.append(ids[ok])
        gy = np.floor(cy + k * (yy - cy)).astype(np.int64)
        gx = np.floor(cx + k * (xx - cx)).astype(np.int64)
        ok = (gy >= 0) & (gy < h) & (gx >= 0) & (gx < w)
        forth.append(np.where(ok, gy * w + gx, -1).ravel())
    maps = np.concatenate(back_from), np.concatenate(back_to), np.stack(forth)
    for a in maps:
        a.setflags(write=False)  # shared by every caller
    return maps


def in_ghost_prior(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    lights: np.ndarray | None = None,
    max_neighbours: int | None = GHOST_MAX_NEIGHBOURS,
    cells: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each event of a window lies in its :func:`ghost_cells` and is sparse there.

    ``lights`` is the window's :func:`light_cells`, when already counted, and ``cells``
    its :func:`ghost_cells`, when already computed (from the same lights). An event
    counts as sparse where its 3x3 neighbourhood holds at most ``max_neighbours``
    events of the window, itself included (None: every event in the cells).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> n = 400
    >>> ev = make_events(np.arange(n) * 50, np.arange(n) % 8, np.arange(n) // 8 % 8,
    ...                  np.ones(n))
    >>> far = make_events([10, 20], [60, 4], [60, 4], [1, 0])
    >>> in_ghost_prior(np.concatenate([ev, far]), (64, 64), 20_000)[-2:].tolist()
    [True, False]
    """
    if cells is None:
        cells = ghost_cells(events, sensor_size, window_us, cell=cell, lights=lights)
    inside = cells[events["y"] // cell, events["x"] // cell]
    if max_neighbours is None or not inside.any():
        return inside
    return inside & (_neighbourhood_counts(events["x"], events["y"], inside) <= max_neighbours)


@numba.njit(cache=True, nogil=True)
def _neighbourhood_counts(x, y, where):  # pragma: no cover - compiled
    """Per event (pixel ``x``, ``y``), the window's events in its 3x3 neighbourhood
    (itself included); counted for the events of ``where`` only (0 elsewhere), on their
    bounding box plus one pixel. Two compiled passes: numpy needed a dozen temporaries
    and nine gathers over the gated events, ten times the time."""
    x0 = y0 = np.iinfo(np.int64).max
    x1 = y1 = -1
    for i in range(x.size):
        if where[i]:
            x0, x1 = min(x0, np.int64(x[i])), max(x1, np.int64(x[i]))
            y0, y1 = min(y0, np.int64(y[i])), max(y1, np.int64(y[i]))
    out = np.zeros(x.size, np.int64)
    if x1 < 0:
        return out
    x0, y0 = x0 - 1, y0 - 1  # the box, one pixel around
    bw, bh = x1 + 2 - x0, y1 + 2 - y0
    counts = np.zeros((bh, bw), np.int32)
    for i in range(x.size):
        cx, cy = np.int64(x[i]) - x0, np.int64(y[i]) - y0
        if 0 <= cx < bw and 0 <= cy < bh:
            counts[cy, cx] += 1
    for i in range(x.size):
        if where[i]:
            cx, cy = np.int64(x[i]) - x0, np.int64(y[i]) - y0
            total = 0
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    total += counts[cy + dy, cx + dx]
            out[i] = total
    return out


@dataclasses.dataclass(frozen=True)
class GhostParams:
    """The ghost rule's knob."""

    ghost_shift: float = knob(
        0.0,
        "--ghost-shift",
        "lower the keep logit by this much for the sparse events where a reflective ghost "
        "of the window's lights can be (the lights reflected through the sensor's centre; "
        "0: off)",
    )


def _ghost_shift(params: GhostParams, ctx: WindowContext) -> np.ndarray:
    inside = in_ghost_prior(
        ctx.events, ctx.sensor_size, ctx.span_us, lights=ctx.lights, cells=ctx.ghost_cells
    )
    return -(params.ghost_shift * inside)


GHOST_RULE = Rule(
    "ghost", GhostParams, _ghost_shift, lambda p: bool(p.ghost_shift), "lights",
    "where a reflective ghost of the lights can be",
)  # fmt: skip
