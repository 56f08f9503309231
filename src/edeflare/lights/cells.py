r"""Which cells of a window hold a light: the cheap test a mask model's rules make per window.

A cell (``cell`` x ``cell`` pixels) is a light when it fires at least
:data:`LIGHT_RATE` events per pixel and millisecond (:func:`light_cells`); a
window's lights (:func:`window_lights`) are those groups of cells whose bright
pixels fire at :data:`LIGHT_CORE_RATE` in the median and form a light at least
:data:`MIN_LIGHT_RADIUS` wide. The rules (:mod:`edeflare.rules`) ask for them in
every window; the recording-level detector is :func:`edeflare.lights.detect_light_source`.
"""

from __future__ import annotations

import functools
import threading

import numba
import numpy as np
from scipy import ndimage

from ..events import SensorSize, check_sensor_size

__all__ = [
    "LIGHT_CORE_RATE",
    "LIGHT_RATE",
    "MIN_LIGHT_RADIUS",
    "covered_us",
    "light_cells",
    "light_pixels",
    "window_lights",
]

LIGHT_RATE = 0.25
"""Events per pixel and millisecond from which a cell counts as a light."""

LIGHT_CORE_RATE = 0.55
"""Events per pixel and millisecond at which a light's bright pixels fire, in the median
(:func:`window_lights`). Real lamps fire faster: the DAVIS lamps 0.60-0.84, the Gen3
blob 1.15-1.83. Dense scene that passes the cell rate fires slower: a daytime street
(Prophesee Gen4.1, 25 M events/s) 0.27-0.54, where 15-16 small "lights" a window
had turned every prior on and the light-free shift off. In the simulator's night streets
at three sensor sizes, all but a few of the 2,399 groups under this rate hold none of
the light source's events (the study ``halo-prior``, ``docs/studies.md``). The margin
below the DAVIS lamps is small: a lamp dimmer than theirs would lose its priors. A steady
lamp fires far slower: the night recording's (faery's ``evt3.raw``) 0.065, found in none
of its windows (the study ``light-test``)."""

MIN_LIGHT_RADIUS = 2.0
"""The thinnest light, in its radius: a solid 3x3 block. A hot pixel firing tens of
kHz passes the cell rate on its own (Prophesee Gen3's do) but is no light."""

_SQUARE = np.ones((3, 3), dtype=bool)
_MARGIN_PX = 2.0  # pixels next to a light left out of its halo: its rim belongs to it


class _Coords:
    """The events per pixel (``counts``, ``(height, width)``), and the events' pixel
    coordinates, flat pixel and cell indices, each made once per window for every prior
    and only when one asks (a window whose candidate cells hold no light needs only the
    counts)."""

    def __init__(self, events: np.ndarray, sensor_size: tuple[int, int], cell: int) -> None:
        width, height = sensor_size
        self.events, self.width = events, width
        self.cell, self.w = cell, -(-width // cell)
        self.counts = _pixel_counts(events["x"], events["y"], width, height)

    @functools.cached_property
    def x(self) -> np.ndarray:
        return self.events["x"].astype(np.int64)

    @functools.cached_property
    def y(self) -> np.ndarray:
        return self.events["y"].astype(np.int64)

    @functools.cached_property
    def cid(self) -> np.ndarray:
        return (self.y // self.cell) * self.w + self.x // self.cell

    @functools.cached_property
    def pixel(self) -> np.ndarray:
        return self.y * self.width + self.x


@numba.njit(cache=True, nogil=True)
def _pixel_counts(x, y, width, height):  # pragma: no cover - compiled
    """The events per pixel ``(height, width) int64``: ``np.bincount`` of the flat
    pixels, without its temporaries and with the GIL released (the two views of a
    stream run on two threads)."""
    counts = np.zeros((height, width), np.int64)
    for i in range(x.size):
        counts[y[i], x[i]] += 1
    return counts


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

    The :func:`~edeflare.lights.cells.light_cells` (the cell rate) whose connected group
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


def covered_us(events: np.ndarray, start_us: int, window_us: int) -> int:
    """How much of a window its events cover: the time the lights' rates are counted over.

    A window at a stream's start or end (or one of the second windowing, which starts
    before the stream) holds only part of its span: over the whole window, a light that
    fired through the part would seem dim and go unseen, and with it every prior. The
    covered part runs from the later of the window's start and its first event to the
    earlier of its end and its last event; at least a quarter of the window, so that a
    burst of a few events is not a light.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([1_000, 4_999], [0, 1], [0, 0], [1, 1])  # a stream ending at 5 ms
    >>> covered_us(ev, 0, 20_000), covered_us(ev[:1], 0, 20_000), covered_us(ev[:0], 0, 20_000)
    (5000, 5000, 20000)
    >>> covered_us(make_events([0, 19_999], [0, 1], [0, 0], [1, 1]), 0, 20_000)
    20000
    """
    if events.size == 0:
        return int(window_us)
    lo = max(int(start_us), int(events["t"][0]))
    hi = min(int(start_us) + int(window_us), int(events["t"][-1]) + 1)
    return int(min(window_us, max(hi - lo, window_us // 4)))


def light_cells(
    events: np.ndarray, sensor_size: SensorSize, window_us: int, *, cell: int = 8
) -> np.ndarray:
    """The cells (``cell`` x ``cell`` pixels) of a window that are lights.

    A cell is a light when it fires at least :data:`LIGHT_RATE` events per pixel
    and millisecond over ``window_us`` (the window, or the part of it the events cover:
    :func:`covered_us`).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> n = 400   # 400 events in the top-left 8x8 cell in 20 ms: 0.31 per px and ms
    >>> ev = make_events(np.arange(n) * 50, np.arange(n) % 8, np.arange(n) // 8 % 8,
    ...                  np.ones(n))
    >>> light_cells(ev, (32, 16), 20_000).astype(int).tolist()
    [[1, 0, 0, 0], [0, 0, 0, 0]]
    """
    width, height = check_sensor_size(sensor_size)
    if window_us <= 0:
        raise ValueError(f"window_us must be positive, got {window_us}")
    if cell < 1:
        raise ValueError(f"cell must be >= 1, got {cell}")
    if events.size and (int(events["x"].max()) >= width or int(events["y"].max()) >= height):
        raise ValueError(f"events lie outside the {width}x{height} sensor")
    h, w = -(-height // cell), -(-width // cell)
    # the compiled counts (and the pixel counts of the lights after) index unchecked
    counts = _cell_event_counts(events["x"], events["y"], cell, h, w)
    return counts >= LIGHT_RATE * cell * cell * window_us / 1000.0


@numba.njit(cache=True, nogil=True)
def _cell_event_counts(x, y, cell, h, w):  # pragma: no cover - compiled
    """The events per cell ``(h, w) int64``: a bincount of the cells, without its
    temporaries and with the GIL released."""
    counts = np.zeros((h, w), np.int64)
    for i in range(x.size):
        counts[y[i] // cell, x[i] // cell] += 1
    return counts
