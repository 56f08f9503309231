r"""Where a window's scattered-light halos are: a parameter-free prior from the lights.

Scattered light falls off with distance from its source. Measured on real recordings
(``benchmarks/flare_stats.py``; :mod:`edeflare.sim.sensing`), a sensor fires the pixels
of a bright light's scattered light from just outside its disc to about
:data:`HALO_EXTENT` source radii out, sparsely; beyond that, events are the scene's. A
mask model decides per event from what its cells show, and a sparse scattered event 50
px from a lamp looks like a sparse scene event; it cannot know that the lamp makes
events there more likely to be flare than the same event elsewhere. This prior says so.

Each light of a window (the same test as the ghost prior's,
:func:`~edeflare.rules.ghost.light_cells`:
``cell x cell`` pixels firing at least :data:`~edeflare.rules.ghost.LIGHT_RATE`
events per pixel and millisecond) is the set of its bright pixels (those firing at
that rate themselves), and its radius is that of the largest disc inside it: for a
still light, the disc's radius; for a light that moves during the window and sweeps a
stroke, half the stroke's width, the radius of the light itself. The prior is the
band from ``margin_px`` outside the light's pixels to ``(extent - 1)`` radii beyond
them (for a disc: out to ``extent`` radii from its centre), but never farther than
:data:`HALO_MAX_REACH` of the sensor's width beyond them, leaving out the light's own
cells and the eight around each.
:class:`~edeflare.models.infer.ModelDeflarer` lowers the keep logit of the events in
it by the card's ``halo_shift``: an event there is dropped only where the network
already leaned towards dropping it (the shift is a prior odds ratio, not a verdict).
A window without a light is left alone.
"""

from __future__ import annotations

import dataclasses
import math
import threading

import numba
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..events import SensorSize, check_sensor_size
from . import Rule, knob
from .context import WindowContext
from .ghost import LIGHT_RATE, light_cells

__all__ = [
    "FAR_RADII",
    "FAR_REACH",
    "HALO_EXTENT",
    "HALO_MAX_REACH",
    "HALO_RULE",
    "LIGHT_CORE_RATE",
    "MIN_LIGHT_RADIUS",
    "HaloParams",
    "far_from_lights",
    "halo_pixels",
    "in_halo_prior",
    "light_pixels",
    "window_lights",
]

HALO_EXTENT = 6.0
"""How far a halo reaches, in source radii from the source's centre: real sensors fire
scattered-light pixels 2-6 radii out (:mod:`edeflare.sim.sensing`)."""

HALO_MAX_REACH = 0.2
"""The farthest a halo reaches beyond its light's pixels, as a share of the sensor's
width, however large the light (a 40 px lamp at 346x260 would otherwise reach 200 px,
the whole frame)."""

FAR_REACH = 0.3
"""Beyond this share of the sensor's width from every light of a window, an event is far
from the lights (:func:`far_from_lights`): past the farthest halo the prior marks
(:data:`HALO_MAX_REACH`), and past the halos of the annotated real recordings (the DAVIS
lamps' annotated halo ends 60 px from their centres, 0.17 of the width) and the
simulator's largest (about 250 px at 1280x720, 0.2)."""

FAR_RADII = 8.0
"""A large light's scattered light reaches farther than :data:`FAR_REACH`: an event is far
from a light only beyond this many of its radii too. The simulator's 29 px light at
346x260 (``edeflare demo``) scatters to 207 px from its centre (95th percentile); the
real lamps are smaller (DAVIS346 7-8 px, Gen3 18 px at 640x480), so the share of the
width decides for them."""

LIGHT_CORE_RATE = 0.55
"""Events per pixel and millisecond at which a light's bright pixels fire, in the median
(:func:`window_lights`). Real lamps fire faster: the DAVIS lamps 0.60-0.84, the Gen3
blob 1.15-1.83. Dense scene that passes the cell rate fires slower: a daytime street
(Prophesee Gen4.1, 25 M events/s) 0.27-0.54, where 15-16 small "lights" a window
had turned every prior on and the light-free shift off. In the simulator's night streets
at three sensor sizes, all but a few of the 2,399 groups under this rate hold none of
the light source's events (``experiments/halo-prior/false_lights.py``). The margin
below the DAVIS lamps is small: a lamp dimmer than theirs would lose its priors."""

MIN_LIGHT_RADIUS = 2.0
"""The thinnest light, in its radius: a solid 3x3 block. A hot pixel firing tens of
kHz passes the cell rate on its own (Prophesee Gen3's do) but is no light."""

_SQUARE = np.ones((3, 3), dtype=bool)
_MARGIN_PX = 2.0  # pixels next to a light left out of its halo: its rim belongs to it


class _Coords:
    """The events' pixel coordinates, flat pixel and cell indices and the events per
    pixel (``counts``, ``(height, width)``), computed once per window for every prior."""

    def __init__(self, events: np.ndarray, sensor_size: tuple[int, int], cell: int) -> None:
        width, height = sensor_size
        self.x, self.y = events["x"].astype(np.int64), events["y"].astype(np.int64)
        self.cell, self.w = cell, -(-width // cell)
        self.cid = (self.y // cell) * self.w + self.x // cell
        self.pixel = self.y * width + self.x
        self.counts = np.bincount(self.pixel, minlength=width * height).reshape(height, width)


class _CellIndex:
    """Some events of a window (``which``, indices into ``at``'s) grouped by cell,
    to take those of a pixel box without a pass over all of them: a window with many
    lights (a street of lamps) costs its candidate events once, sorted, and each light
    only the events around it."""

    def __init__(self, at: _Coords, which: np.ndarray) -> None:
        self.at = at
        ids = at.cid[which]
        self.n_cells = int(ids.max()) + 1 if ids.size else 1
        # a stable sort of small ints is a radix sort in numpy: cheap
        small = ids.astype(np.uint16) if self.n_cells <= np.iinfo(np.uint16).max else ids
        order = np.argsort(small, kind="stable")
        self.which = which[order]
        self.starts = np.searchsorted(ids[order], np.arange(self.n_cells + 1))

    def box(self, ys: slice, xs: slice) -> np.ndarray:
        """Indices of the events with ``ys.start <= y < ys.stop`` and the same in x."""
        at = self.at
        c0, c1 = xs.start // at.cell, (xs.stop - 1) // at.cell + 1
        parts = [
            self.which[self.starts[a] : self.starts[min(a + c1 - c0, self.n_cells)]]
            for a in (
                r * at.w + c0 for r in range(ys.start // at.cell, (ys.stop - 1) // at.cell + 1)
            )
            if a < self.n_cells
        ]
        if not parts:
            return np.zeros(0, dtype=np.int64)
        i = np.concatenate(parts)
        x, y = at.x[i], at.y[i]
        return i[(x >= xs.start) & (x < xs.stop) & (y >= ys.start) & (y < ys.stop)]


_LightsFound = tuple[np.ndarray, list[tuple[slice, slice, np.ndarray, float]], "_Coords | None"]
_last = threading.local()  # per thread: the last window's lights, for the next prior


def _lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    cell: int,
    lights: np.ndarray | None = None,
) -> _LightsFound:
    """The light cells; per light its box (pixel slices), its pixels in the box and its
    radius; the events' coordinates (None without a light). Only the lights'
    neighbourhoods are looked at, never the whole frame.

    The priors of one window ask in turn with the same arrays, its light cells counted
    once (:meth:`~edeflare.models.infer.ModelDeflarer.window_logits`): the answer for
    the same ``events`` and ``lights`` objects and arguments is kept (one per thread)
    and given again, instead of finding the lights once per prior. Without ``lights``
    nothing is kept."""
    if lights is None:
        return _find_lights(events, sensor_size, window_us, cell, None)
    key = (sensor_size, window_us, cell)
    memo = getattr(_last, "memo", None)
    if memo is not None and memo[0] is events and memo[1] is lights and memo[2] == key:
        return memo[3]
    found = _find_lights(events, sensor_size, window_us, cell, lights)
    _last.memo = (events, lights, key, found)
    return found


# A light's shape (its holes filled, its largest inscribed disc, its edge) is made on a
# box of a few hundred pixels, once per light and window: scipy's calls cost a fixed
# 0.1-0.3 ms each there, more than the work, and a street of lamps has dozens of lights
# per window. These loops (numba) give the same pixels and the same radius.


@numba.njit(cache=True, nogil=True)
def _fill_holes(mask):  # pragma: no cover - compiled
    """``scipy.ndimage.binary_fill_holes(mask)``: the background pixels that no
    4-connected path of background pixels joins to the border are filled."""
    h, w = mask.shape
    out = np.ones((h, w), np.bool_)  # filled until reached from the border
    stack = np.empty((h * w, 2), np.int64)
    top = 0
    for y in range(h):
        for x in range(w):
            if (y == 0 or y == h - 1 or x == 0 or x == w - 1) and not mask[y, x] and out[y, x]:
                out[y, x] = False
                stack[top, 0], stack[top, 1] = y, x
                top += 1
                while top:
                    top -= 1
                    cy, cx = stack[top, 0], stack[top, 1]
                    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                        ny, nx = cy + dy, cx + dx
                        if 0 <= ny < h and 0 <= nx < w and not mask[ny, nx] and out[ny, nx]:
                            out[ny, nx] = False
                            stack[top, 0], stack[top, 1] = ny, nx
                            top += 1
    return out


@numba.njit(cache=True, nogil=True)
def _inscribed_radius(own):  # pragma: no cover - compiled
    """The largest Euclidean distance from a pixel of ``own`` to a pixel outside it (the
    box's surroundings are outside): ``distance_transform_edt(np.pad(own, 1)).max()``,
    by the exact two-pass squared distance transform (Felzenszwalb and Huttenlocher,
    2012), columns then rows."""
    h, w = own.shape
    col = np.empty((h, w), np.int64)  # squared distance to the nearest outside pixel in the column
    for x in range(w):
        d = 0
        for y in range(h):
            d = d + 1 if own[y, x] else 0
            col[y, x] = d
        d = 0
        for y in range(h - 1, -1, -1):
            d = d + 1 if own[y, x] else 0
            col[y, x] = min(col[y, x], d) ** 2
    best = 0
    n = w + 2  # the row with one outside pixel at each end
    f = np.empty(n, np.int64)
    v = np.empty(n, np.int64)
    z = np.empty(n + 1, np.float64)
    for y in range(h):
        f[0] = 0
        f[n - 1] = 0
        for x in range(w):
            f[x + 1] = col[y, x] if own[y, x] else 0
        # the lower envelope of the parabolas (q - v)^2 + f(v)
        k = 0
        v[0] = 0
        z[0] = -np.inf
        z[1] = np.inf
        for q in range(1, n):
            s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0 * (q - v[k]))
            while s <= z[k]:  # never past k = 0: z[0] is -inf
                k -= 1
                s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0 * (q - v[k]))
            k += 1
            v[k] = q
            z[k] = s
            z[k + 1] = np.inf
        k = 0
        for q in range(1, n - 1):
            while z[k + 1] < q:
                k += 1
            d = (q - v[k]) ** 2 + f[v[k]]
            if d > best and own[y, q - 1]:
                best = d
    return np.sqrt(np.float64(best))


@numba.njit(cache=True, nogil=True)
def _edge_pixels(own):  # pragma: no cover - compiled
    """The ``(row, column)`` of the pixels of ``own`` with a 4-neighbour outside it or
    on the box's border: ``np.argwhere(own & ~binary_erosion(own, border_value=0))``."""
    h, w = own.shape
    out = np.empty((h * w, 2), np.int64)
    n = 0
    for y in range(h):
        for x in range(w):
            if own[y, x] and (
                y == 0
                or y == h - 1
                or x == 0
                or x == w - 1
                or not (own[y - 1, x] and own[y + 1, x] and own[y, x - 1] and own[y, x + 1])
            ):
                out[n, 0], out[n, 1] = y, x
                n += 1
    return out[:n].copy()


def _find_lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    cell: int,
    lights: np.ndarray | None,
) -> _LightsFound:
    """:func:`_lights`, computed."""
    width, height = check_sensor_size(sensor_size)
    if lights is None:
        lights = light_cells(events, sensor_size, window_us, cell=cell)
    found: list[tuple[slice, slice, np.ndarray, float]] = []
    if not lights.any():
        return lights, found, None
    at = _Coords(events, (width, height), cell)
    cells, _ = ndimage.label(lights, structure=_SQUARE)
    # a light's edge pixels can sit in the cells next to its own, below the cells' rate
    grown = ndimage.grey_dilation(cells, size=(3, 3))
    rate = LIGHT_RATE * window_us / 1000.0
    for k, (cy, cx) in enumerate(ndimage.find_objects(grown), start=1):
        ys = slice(cy.start * cell, min(cy.stop * cell, height))
        xs = slice(cx.start * cell, min(cx.stop * cell, width))
        h, w = ys.stop - ys.start, xs.stop - xs.start
        mine = np.repeat(np.repeat(grown[cy, cx] == k, cell, axis=0), cell, axis=1)[:h, :w]
        own = _fill_holes((at.counts[ys, xs] >= rate) & mine)
        radius = float(_inscribed_radius(own))
        if radius >= MIN_LIGHT_RADIUS:
            found.append((ys, xs, own, radius))
    return lights, found, at


def light_pixels(
    events: np.ndarray, sensor_size: SensorSize, window_us: int, *, cell: int = 8
) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of a window's lights, labelled, and each light's radius.

    A light is a connected group (8-neighbourhood) of :func:`light_cells`. Its pixels
    are the bright ones (firing at :data:`LIGHT_RATE` themselves) in those cells and
    the cells next to them, with their holes filled; its radius is the largest
    distance from one of them to a pixel outside, at least :data:`MIN_LIGHT_RADIUS`
    (thinner groups, such as a lone hot pixel, are no light).

    Returns
    -------
    labels : numpy.ndarray
        int, ``(height, width)``: 0 off the lights, ``k`` on the ``k``-th.
    radii : numpy.ndarray
        float, one per light (``radii[k - 1]`` is light ``k``'s).

    Examples
    --------
    A 10x10 block firing 20 events per pixel in 20 ms: its centre pixels are 5 px
    from the nearest pixel outside it.

    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[20:30, 40:50]
    >>> n = 20 * xx.size
    >>> ev = make_events(np.arange(n), np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20),
    ...                  np.ones(n))
    >>> labels, radii = light_pixels(ev, (64, 48), 20_000)
    >>> int((labels == 1).sum()), radii.tolist()
    (100, [5.0])
    """
    width, height = check_sensor_size(sensor_size)
    labels = np.zeros((height, width), dtype=np.int64)
    _, found, _ = _lights(events, sensor_size, window_us, cell)
    for k, (ys, xs, own, _) in enumerate(found, start=1):
        labels[ys, xs][own] = k
    return labels, np.array([r for *_, r in found])


def window_lights(
    events: np.ndarray, sensor_size: SensorSize, window_us: int, *, cell: int = 8
) -> np.ndarray:
    """The cells of a window's lights: what the priors and the light-free shift act on.

    The :func:`~edeflare.rules.ghost.light_cells` (the cell rate) whose connected group
    holds a light of :func:`light_pixels` (a solid disc of radius at least
    :data:`MIN_LIGHT_RADIUS`) whose bright pixels fire at :data:`LIGHT_CORE_RATE` in the
    median. The other groups are dense scene or hot pixels, not sources of flare.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[16:32, 40:56]
    >>> def block(per_pixel, span_us):   # a 16x16 block (4 cells), per_pixel events each
    ...     n = per_pixel * xx.size
    ...     return make_events(np.arange(n) * span_us // n, np.tile(xx.ravel(), per_pixel),
    ...                        np.tile(yy.ravel(), per_pixel), np.ones(n))
    >>> int(window_lights(block(20, 20_000), (96, 64), 20_000).sum())  # 1 per px and ms
    4
    >>> int(window_lights(block(8, 20_000), (96, 64), 20_000).sum())  # 0.4: dense scene
    0
    """
    cells = light_cells(events, sensor_size, window_us, cell=cell)
    if not cells.any():
        return cells
    _, found, at = _lights(events, sensor_size, window_us, cell, cells)
    core = LIGHT_CORE_RATE * window_us / 1000.0
    bright = [f for f in found if np.median(at.counts[f[0], f[1]][f[2]]) >= core]  # type: ignore[index]
    groups, n = ndimage.label(cells, structure=_SQUARE)
    if len(bright) == len(found) == n:
        return cells  # every group is a light: the priors reuse what _lights found
    keep = np.zeros(n + 1, dtype=bool)
    for ys, xs, own, _ in bright:
        py, px = np.nonzero(own)
        keep[groups[(py + ys.start) // cell, (px + xs.start) // cell]] = True
    keep[0] = False
    return keep[groups]


def far_from_lights(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    lights: np.ndarray | None = None,
    reach: float = FAR_REACH,
    radii: float = FAR_RADII,
    exclude: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each event of a window is far from all of its lights.

    An event is far from a light when its cell's centre is more than ``reach`` of the
    sensor's width, and more than ``radii`` of the light's radius (:func:`light_pixels`),
    from the centre of every cell of the light's group of light cells. Distances are
    measured between cell centres, so they are exact to a cell. Without a light every
    event is far.

    ``lights`` is the window's :func:`window_lights`, when already counted; ``exclude``,
    cells (the same shape) whose events are never far, such as where the lights' ghosts
    can be (:func:`~edeflare.rules.ghost.ghost_cells`).

    Examples
    --------
    A 16x16 lamp in the cells x 1-2, y 0-1 of a 256x64 sensor: 0.3 x 256 = 76.8 px.

    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[0:16, 8:24]
    >>> n = 20 * xx.size
    >>> lamp = make_events(np.arange(n) * 20_000 // n, np.tile(xx.ravel(), 20),
    ...                    np.tile(yy.ravel(), 20), np.ones(n))
    >>> ev = np.concatenate([lamp, make_events([19_998, 19_999], [92, 100], [4, 4], [1, 1])])
    >>> far_from_lights(ev, (256, 64), 20_000)[-2:].tolist()   # 72 px, 80 px
    [False, True]
    """
    width, height = check_sensor_size(sensor_size)
    if lights is None:
        lights = window_lights(events, sensor_size, window_us, cell=cell)
    if lights.shape != (-(-height // cell), -(-width // cell)):
        raise ValueError(
            f"lights has shape {lights.shape}, not the {width}x{height} sensor's cells"
        )
    near = np.zeros(lights.shape, dtype=bool) if exclude is None else exclude.copy()
    if near.shape != lights.shape:
        raise ValueError(f"exclude has shape {near.shape}, not the lights' {lights.shape}")
    at = None
    if lights.any():
        _, found, at = _lights(events, sensor_size, window_us, cell, lights)
        groups, n = ndimage.label(lights, structure=_SQUARE)
        # each group's farthest reach: the share of the width, or its largest light's radii
        reach_px = np.full(n + 1, reach * width)
        for ys, xs, own, radius in found:
            py, px = np.nonzero(own)
            ids = groups[(py + ys.start) // cell, (px + xs.start) // cell]
            reach_px[ids] = np.maximum(reach_px[ids], radii * radius)
        for k in np.unique(reach_px[1:]):
            # every cell's distance to the nearest cell of the groups reaching k pixels
            # (scipy's exact Euclidean distance transform on the grid of cells)
            mine = (reach_px[groups] == k) & lights
            near |= ndimage.distance_transform_edt(~mine) * cell <= k
    if at is not None:  # the events' cells, already counted for the lights
        return ~near.ravel()[at.cid]
    return ~near[events["y"] // cell, events["x"] // cell]


def _reach(radius: float, extent: float, width: int) -> float:
    """How far a light's halo band reaches beyond its pixels: ``(extent - 1)`` of its
    radii, at most :data:`HALO_MAX_REACH` of the sensor's width."""
    return min((extent - 1.0) * radius, HALO_MAX_REACH * width)


def _bands(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    cell: int,
    extent: float,
    margin_px: float,
) -> tuple[np.ndarray, list[tuple[slice, slice, np.ndarray]]]:
    """The light cells, and per light the box around it and its halo band in the box."""
    width, height = check_sensor_size(sensor_size)
    if not extent > 1.0 or not margin_px >= 0.0:
        raise ValueError(f"extent must be > 1 and margin_px >= 0, got {extent} and {margin_px}")
    lights, found, _ = _lights(events, sensor_size, window_us, cell)
    bands = []
    for ys, xs, own, radius in found:
        reach = _reach(radius, extent, width)
        pad = math.ceil(reach) + 1
        by = slice(max(ys.start - pad, 0), min(ys.stop + pad, height))
        bx = slice(max(xs.start - pad, 0), min(xs.stop + pad, width))
        off = np.ones((by.stop - by.start, bx.stop - bx.start), dtype=bool)
        oy, ox = ys.start - by.start, xs.start - bx.start
        off[oy : oy + own.shape[0], ox : ox + own.shape[1]] = ~own
        # each pixel's distance to the light's nearest pixel (scipy's exact Euclidean
        # distance transform, on the light's neighbourhood only)
        d = ndimage.distance_transform_edt(off)
        bands.append((by, bx, (d > margin_px) & (d <= reach)))
    return lights, bands


def halo_pixels(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    extent: float = HALO_EXTENT,
    margin_px: float = _MARGIN_PX,
) -> np.ndarray:
    """The pixels of a window's halo prior: ``(height, width)`` bool.

    Parameters
    ----------
    events : structured array
        One window's events.
    sensor_size : (width, height)
    window_us : int
        The window's length (what the light rate is counted over).
    cell : int
        Cell size of the light test, in pixels.
    extent : float
        How far each halo reaches, in its light's radii from a still light's centre
        (> 1): ``(extent - 1)`` radii beyond the light's pixels, at most
        :data:`HALO_MAX_REACH` of the sensor's width.
    margin_px : float
        Pixels next to each light left out (its rim belongs to it).

    Returns
    -------
    numpy.ndarray
        True where an event would be in a halo and in no light.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[20:30, 40:50]
    >>> n = 20 * xx.size
    >>> ev = make_events(np.arange(n), np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20),
    ...                  np.ones(n))
    >>> p = halo_pixels(ev, (128, 64), 20_000)   # radius 5: out to 25 px beyond the block
    >>> bool(p[24, 44]), bool(p[24, 60]), bool(p[24, 74]), bool(p[24, 75])
    (False, True, True, False)
    """
    width, height = check_sensor_size(sensor_size)
    lights, bands = _bands(events, sensor_size, window_us, cell, extent, margin_px)
    prior = np.zeros((height, width), dtype=bool)
    for by, bx, band in bands:
        prior[by, bx] |= band
    near = ndimage.binary_dilation(lights, structure=_SQUARE)  # with the 8 cells around
    return prior & ~np.repeat(np.repeat(near, cell, axis=0), cell, axis=1)[:height, :width]


_BRUTE_PAIRS = 1 << 18
"""Up to this many (open pixel, edge pixel) pairs a light's undecided pixels are measured
against every edge pixel in a loop; above it (a long stroke, a large light) by a k-d
tree, whose set-up costs more than the loop for the lamps of a street."""


@numba.njit(cache=True, nogil=True)
def _band_bounds(own, edge, py, px, reach, margin):  # pragma: no cover - compiled
    """:func:`_in_band`'s answers where the bounds decide them (``out``), the pixels
    they leave open (``undecided``), each open pixel's squared distance to the light when
    there are few enough pairs (-1 otherwise)."""
    h, w = own.shape
    # the light's pixel nearest its centroid
    sy = sx = 0.0
    n = 0
    for y in range(h):
        for x in range(w):
            if own[y, x]:
                sy += y
                sx += x
                n += 1
    my, mx = sy / n, sx / n
    cy = cx = 0
    best = np.inf
    for y in range(h):
        for x in range(w):
            if own[y, x] and (y - my) ** 2 + (x - mx) ** 2 < best:
                best = (y - my) ** 2 + (x - mx) ** 2
                cy, cx = y, x
    far = 0
    for j in range(edge.shape[0]):
        far = max(far, (edge[j, 0] - cy) ** 2 + (edge[j, 1] - cx) ** 2)
    spread = np.sqrt(np.float64(far))
    out = np.zeros(py.size, np.bool_)
    undecided = np.zeros(py.size, np.bool_)
    n_open = 0
    for i in range(py.size):
        y, x = py[i], px[i]
        if 0 <= y < h and 0 <= x < w and own[y, x]:
            continue  # on the light (in a hole of its bright pixels, filled): no band
        # integer squares, then sqrt: the k-d tree's own arithmetic, so ties agree
        upper = np.sqrt(np.float64((y - cy) ** 2 + (x - cx) ** 2))
        lower = upper - spread - 1e-9
        if upper <= reach and lower > margin:
            out[i] = True
        elif lower <= reach and upper > margin:
            undecided[i] = True
            n_open += 1
    d2 = np.full(py.size, -1, np.int64)
    if n_open * edge.shape[0] <= _BRUTE_PAIRS:
        for i in range(py.size):
            if undecided[i]:
                m = (py[i] - edge[0, 0]) ** 2 + (px[i] - edge[0, 1]) ** 2
                for j in range(1, edge.shape[0]):
                    m = min(m, (py[i] - edge[j, 0]) ** 2 + (px[i] - edge[j, 1]) ** 2)
                d2[i] = m
    return out, undecided, d2


def _in_band(
    own: np.ndarray, edge: np.ndarray, py: np.ndarray, px: np.ndarray, reach: float
) -> np.ndarray:
    """Whether pixels ``(py, px)`` (in ``own``'s box) are more than the margin and at
    most ``reach`` from the nearest pixel of the light ``own`` (its ``edge`` pixels
    given), and not on it.

    The distance to the light's pixel ``c`` nearest its centroid bounds the distance d
    to the light from above, and that minus the light's farthest pixel from ``c`` from
    below: most pixels are decided by the bounds (all but a shell one light wide, for a
    round light), the rest by their distance to every edge pixel (the nearest light
    pixel of a point outside is on the edge), in a loop or a k-d tree, with the same
    answers."""
    out, undecided, d2 = _band_bounds(own, edge, py, px, float(reach), _MARGIN_PX)
    if undecided.any():
        d = d2[undecided]
        if d[0] >= 0:  # measured in the loop
            d = np.sqrt(d.astype(np.float64))
        else:
            d, _ = cKDTree(edge).query(
                np.stack([py[undecided], px[undecided]], axis=1),
                distance_upper_bound=reach + 1.0,
            )
        out[undecided] = (d > _MARGIN_PX) & (d <= reach)
    return out


def in_halo_prior(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    lights: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each event of a window lies in its :func:`halo_pixels` (``lights``: the
    window's :func:`~edeflare.rules.ghost.light_cells`, when already counted).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[20:30, 40:50]
    >>> n = 20 * xx.size
    >>> ev = make_events(np.arange(n), np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20),
    ...                  np.ones(n))
    >>> far = make_events([n, n + 1], [60, 90], [24, 60], [1, 0])  # 11 px and 50 px out
    >>> in_halo_prior(np.concatenate([ev, far]), (96, 64), 20_000)[-3:].tolist()
    [False, True, False]
    """
    width, height = check_sensor_size(sensor_size)
    lights, found, at = _lights(events, sensor_size, window_us, cell, lights)
    inside = np.zeros(events.size, dtype=bool)
    if not found or at is None:
        return inside
    x, y = at.x, at.y
    near = ndimage.binary_dilation(lights, structure=_SQUARE)  # with the 8 cells around
    boxes = []
    around = np.zeros_like(lights)  # the cells of every light's box, its band's reach added
    for ys, xs, _, radius in found:
        reach = _reach(radius, HALO_EXTENT, width)
        pad = math.ceil(reach) + 1
        by = slice(max(ys.start - pad, 0), min(ys.stop + pad, height))
        bx = slice(max(xs.start - pad, 0), min(xs.stop + pad, width))
        around[
            by.start // cell : (by.stop - 1) // cell + 1,
            bx.start // cell : (bx.stop - 1) // cell + 1,
        ] = True
        boxes.append((by, bx, reach))
    index = _CellIndex(at, np.flatnonzero((around & ~near).ravel()[at.cid]))
    for (ys, xs, own, _), (by, bx, reach) in zip(found, boxes, strict=True):
        # the same band as halo_pixels', measured at the events instead of on a pixel
        # map: a k-d tree of the light's edge pixels (the nearest light pixel of a point
        # outside is on the edge) answers for the few events around a light in a
        # fraction of a distance transform's time over the light's whole neighbourhood
        sel = index.box(by, bx)
        if sel.size == 0:
            continue
        edge = _edge_pixels(own)
        # each pixel asked once: a pixel map of the box, its marked pixels in order
        w = bx.stop - bx.start
        pid = (y[sel] - by.start) * w + (x[sel] - bx.start)
        marked = np.zeros((by.stop - by.start) * w, dtype=bool)
        marked[pid] = True
        pixels = np.flatnonzero(marked)
        py, px = np.divmod(pixels, w)
        py += by.start - ys.start  # in the light's box
        px += bx.start - xs.start
        band = np.zeros(marked.size, dtype=bool)
        band[pixels] = _in_band(own, edge, py, px, reach)
        inside[sel[band[pid]]] = True
    return inside


@dataclasses.dataclass(frozen=True)
class HaloParams:
    """The halo rule's knob."""

    halo_shift: float = knob(
        0.0,
        "--halo-shift",
        "lower the keep logit by this much in the halo of the window's lights (from just "
        "outside each light to six of its radii, at most a fifth of the sensor's width; "
        "0: off)",
    )


def _halo_shift(params: HaloParams, ctx: WindowContext) -> np.ndarray:
    inside = in_halo_prior(ctx.events, ctx.sensor_size, ctx.span_us, lights=ctx.lights)
    return -(params.halo_shift * inside)


HALO_RULE = Rule(
    "halo", HaloParams, _halo_shift, lambda p: bool(p.halo_shift), "lights",
    "the band of scattered light around each light",
)  # fmt: skip
