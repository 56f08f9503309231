r"""Where a window's scattered-light halos are: a parameter-free prior from the lights.

Scattered light falls off with distance from its source. Measured on real recordings
(``benchmarks/flare_stats.py``; :mod:`edeflare.sim.sensing`), a sensor fires the pixels
of a bright light's scattered light from just outside its disc to about
:data:`HALO_EXTENT` source radii out, sparsely; beyond that, events are the scene's. A
mask model decides per event from what its cells show, and a sparse scattered event 50
px from a lamp looks like a sparse scene event; it cannot know that the lamp makes
events there more likely to be flare than the same event elsewhere. This prior says so.

Each light of a window (the same test as the ghost prior's,
:func:`~edeflare.lights.cells.light_cells`:
``cell x cell`` pixels firing at least :data:`~edeflare.lights.cells.LIGHT_RATE`
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

import numba
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..events import SensorSize, check_sensor_size
from ..lights.cells import (
    _MARGIN_PX,
    _SQUARE,
    _CellIndex,
    _edge_pixels,
    _lights,
    window_lights,
)
from . import Rule, knob
from .context import WindowContext

__all__ = [
    "FAR_RADII",
    "FAR_REACH",
    "HALO_EXTENT",
    "HALO_MAX_REACH",
    "HALO_RULE",
    "HaloParams",
    "far_from_lights",
    "halo_pixels",
    "in_halo_prior",
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
    window's :func:`~edeflare.lights.cells.light_cells`, when already counted).

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
