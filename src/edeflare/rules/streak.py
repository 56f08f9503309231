r"""Where a window's diffraction spikes are: a parameter-free prior from the lights.

A lens's aperture blades diffract a bright point into a star: thin straight spikes
through the source, in pairs opposite each other (an aperture of ``n`` blades gives
``n`` spikes for even ``n`` and ``2n`` for odd ``n``; each spike's partner is at
180 degrees). Where the source is bright enough the spikes saturate: solid radial
runs of pixels that fire again and again in a window, tens of source radii long.
A mask model trained on sparse scattered light keeps them, because dense and
connected is what a scene edge looks like to a cell.

This prior finds them from the geometry alone. Around each light of the window (the
test of :func:`~edeflare.lights.cells.light_pixels`: its centre, the farthest of its
pixels from the centre, its radius ``R``) the saturated pixels (:data:`MIN_PIXEL_EVENTS`
events or more) out to :data:`STREAK_EXTENT` radii are binned by angle
(:data:`ANGLE_BINS` around) and by distance (rings of ``RADIAL_BIN_PX``), starting
``SKIP_RADII`` radii beyond the light's edge (the light's rim and its near halo belong
to the other priors). A bin is *filled* where saturated pixels cover at least
:data:`FILL_SHARE` of its area. An angle's *run* is how far its filled bins go out from
the start, across gaps of at most ``MAX_GAP_BINS`` rings. An angle is a spike where

- its run is at least ``max(MIN_LENGTH_RADII R, MIN_LENGTH_PX)`` plus
  ``FLANK_FACTOR`` times the median run on its busier flank (the angles
  ``FLANK_GAP_BINS`` to ``LOCAL_HALF_BINS`` away on one side): a spike is narrow,
  and a dense object beside the light (the next ball of a Newton's cradle) or a
  dense scene around it has long runs at the neighbouring angles too;
- the opposite angle (within ``PAIR_TOLERANCE_BINS`` bins) is a spike too, unless
  the sensor's border cuts the opposite direction off before a spike could be seen.

Where the spikes are bright enough to pass the light test themselves, the light's own
pixels are a star, its edge is a spike's tip, and nothing lies beyond it to search. So
for a light that is not round (more than ``ROUND_AREA`` discs of its radius) the same
runs are also made of its own pixels, from ``ARM_ROOT_RADII`` radii out from its core
(the centre of its largest inscribed disc). Its *arms* are the runs of adjacent angles
that reach ``ARM_LENGTH_RADII`` radii further, are at most ``ARM_MAX_DEG`` wide, stand
out of their flanks as a spike does (``FLANK_FACTOR`` times the saturated runs there: a
lit facade's grid of windows around a light fills them), and have a saturated run as
long within ``ARM_PAIR_DEG`` of the opposite direction. A star has at least
``ARM_MIN`` arms; a lamp's tube or a moving light's stroke has two ends at most, and
keeps them. (On ``eflare-r-sim`` a third of the flare the default kept lay in its
lights' own pixels, mostly such stars: the study ``rsim-gap``, ``docs/studies.md``.)

The prior is the events in the pixels of each spike angle (and arm) up to the end of
its run.
:class:`~edeflare.models.infer.ModelDeflarer` lowers their keep logit by the card's
``streak_shift``. The measurements behind the constants: the study ``streaks``
(``docs/studies.md``).
"""

from __future__ import annotations

import dataclasses
import math

import numba
import numpy as np
from scipy import ndimage

from ..events import SensorSize, check_sensor_size
from ..lights.cells import _lights
from . import Rule, knob
from .context import WindowContext

__all__ = [
    "ANGLE_BINS",
    "FILL_SHARE",
    "MIN_PIXEL_EVENTS",
    "STREAK_EXTENT",
    "STREAK_RULE",
    "StreakParams",
    "in_streak_prior",
]

STREAK_EXTENT = 25.0
"""How far out spikes are looked for, in source radii from the source's centre."""

ANGLE_BINS = 240
"""Angle bins around a light (1.5 degrees each: 5 px wide at 200 px out)."""

MIN_PIXEL_EVENTS = 2
"""Events in the window that make a pixel saturated: spikes fire their pixels again and
again; the single scattered events along real streaks are the network's and the halo
prior's to judge."""

FILL_SHARE = 0.2
"""The share of a bin's area that saturated pixels must cover for it to be filled. A
share, not a count: rings far from the light have large bins, and a dense scene would
fill a count there at any angle."""

RADIAL_BIN_PX = 4.0
SKIP_RADII = 2.0
MIN_LENGTH_RADII = 4.0
MIN_LENGTH_PX = 32.0
MAX_GAP_BINS = 2
LOCAL_HALF_BINS = 15
FLANK_GAP_BINS = 3
FLANK_FACTOR = 2.0
PAIR_TOLERANCE_BINS = 2
ROUND_AREA = 2.0  # a round light's area is at most this many discs of its radius
ARM_ROOT_RADII = 1.5  # a light's arms are its pixels beyond this many radii from its core
ARM_MIN = 4  # a star has at least this many arms
ARM_MAX_DEG = 60.0  # an arm is at most this wide, seen from the light's centre
ARM_LENGTH_RADII = 1.5  # an arm reaches at least this many radii out from its root
ARM_PAIR_DEG = 15.0  # an arm's partner points within this many degrees of opposite


@numba.njit(cache=True, nogil=True)
def _runs(filled, max_gap):  # pragma: no cover - compiled
    """Per row of ``filled`` (angle, ring), how many rings its run covers: up to and
    including the last filled ring before the first gap longer than ``max_gap``.

    A loop (numba) rather than numpy: the rows are short and a light has one call, so
    numpy's per-call overhead was most of the time."""
    n_angles, n_rings = filled.shape
    out = np.zeros(n_angles, np.int64)
    for a in range(n_angles):
        gap = 0
        for r in range(n_rings):
            if filled[a, r]:
                out[a] = r + 1
                gap = 0
            else:
                gap += 1
                if gap > max_gap:
                    break
    return out


@numba.njit(cache=True, nogil=True)
def _flank_medians(run, half, gap):  # pragma: no cover - compiled
    """Per angle, the median run on its left and on its right flank (the angles
    ``gap`` to ``half`` bins away on that side, around the circle)."""
    n = run.size
    width = half - gap + 1
    left = np.empty(n, np.float64)
    right = np.empty(n, np.float64)
    buf = np.empty(width, np.int64)
    for i in range(n):
        for side in range(2):
            for j in range(width):
                d = j + gap if side else j - half
                buf[j] = run[(i + d) % n]
            buf.sort()
            m = buf[width // 2] if width % 2 else 0.5 * (buf[width // 2 - 1] + buf[width // 2])
            if side:
                right[i] = m
            else:
                left[i] = m
    return left, right


def _spikes(run: np.ndarray, need: float, room: np.ndarray) -> np.ndarray:
    """The spike angles among runs ``run`` (rings), ``room``: rings before the border."""
    # the median run on each flank (the bins FLANK_GAP_BINS to h away on that side): a
    # spike stands above both; the edge of a wide object has its body on one flank
    left, right = _flank_medians(run, LOCAL_HALF_BINS, FLANK_GAP_BINS)
    spike = run >= need + FLANK_FACTOR * np.maximum(left, right)
    half = run.size // 2
    partner = np.zeros_like(spike)
    for d in range(-PAIR_TOLERANCE_BINS, PAIR_TOLERANCE_BINS + 1):
        partner |= np.roll(spike, half + d)
    unseen = np.roll(room < need, half)
    return spike & (partner | unseen)


@numba.njit(cache=True, nogil=True)
def _centre(own, y0, x0):  # pragma: no cover - compiled
    """A light's centre (the mean of its pixels ``own``, its box at ``(y0, x0)``) and its
    farthest pixel's distance from it."""
    sy = sx = n = 0  # integer sums: the mean is exact, in any order
    for y in range(own.shape[0]):
        for x in range(own.shape[1]):
            if own[y, x]:
                sy += y
                sx += x
                n += 1
    cy, cx = sy / n + y0, sx / n + x0
    edge = 0.0
    for y in range(own.shape[0]):
        for x in range(own.shape[1]):
            if own[y, x]:
                edge = max(edge, math.hypot(y + y0 - cy, x + x0 - cx))
    return cy, cx, edge


@numba.njit(cache=True, nogil=True)
def _angle_runs(sat_y, sat_x, lo, hi, cy, cx, reach, start, n_rings, need):  # pragma: no cover
    """Each angle's run (rings) from the saturated pixels ``sat_y[lo:hi]`` (those in the
    rows within ``reach`` of the centre ``(cy, cx)``): the polar bins, their filling and
    the runs in one pass (numpy's temporaries per light were most of a street of lamps'
    time). All zero when too few saturated pixels fall in the rings for a run of
    ``need`` rings: a spike's run fills at least one ring in ``MAX_GAP_BINS + 1``, each
    with a saturated pixel, but for the first two, which can be under a pixel's area (a
    lamp over a dark scene has none)."""
    hot = np.zeros((ANGLE_BINS, n_rings), np.int64)
    n = 0
    for i in range(lo, hi):
        dy, dx = sat_y[i] - cy, sat_x[i] - cx
        if abs(dx) > reach:
            continue
        ring = math.floor((math.hypot(dx, dy) - start) / RADIAL_BIN_PX)
        if ring < 0 or ring >= n_rings:
            continue
        theta = math.atan2(dy, dx)
        tb = np.int64((theta + math.pi) * (ANGLE_BINS / (2 * math.pi))) % ANGLE_BINS
        hot[tb, ring] += 1
        n += 1
    if n < math.ceil(need / (MAX_GAP_BINS + 1)) - 2:
        return np.zeros(ANGLE_BINS, np.int64)
    # a bin is filled where saturated pixels cover at least FILL_SHARE of its area (the
    # annulus sector's); a bin under a pixel's area (next to a small light) neither
    # fills nor breaks a run
    filled = np.empty((ANGLE_BINS, n_rings), np.bool_)
    sector = 2 * math.pi / ANGLE_BINS * RADIAL_BIN_PX
    for r in range(n_rings):
        area = sector * (start + RADIAL_BIN_PX * (r + 0.5))
        for a in range(ANGLE_BINS):
            filled[a, r] = hot[a, r] >= FILL_SHARE * area or area < 1.0
    return _runs(filled, MAX_GAP_BINS)


def _polar_bins(
    dx: np.ndarray, dy: np.ndarray, start: float, n_rings: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of points at ``(dx, dy)`` from a light's centre: which fall in a ring, and those
    points' rings and angle bins."""
    ring = np.floor((np.hypot(dx, dy) - start) / RADIAL_BIN_PX).astype(np.int64)
    ok = (ring >= 0) & (ring < n_rings)
    theta = np.arctan2(dy[ok], dx[ok])
    tb = ((theta + math.pi) * (ANGLE_BINS / (2 * math.pi))).astype(np.int64) % ANGLE_BINS
    return ok, ring[ok], tb


def _arms(run: np.ndarray, sat_run: np.ndarray, need: float) -> np.ndarray:
    """The arm angles of a light that is not round, from its own pixels' runs ``run``
    and the saturated pixels' ``sat_run`` (rings, from ``ARM_ROOT_RADII`` radii out):
    its own runs of at least ``need`` rings at adjacent angles make one arm, at most
    ``ARM_MAX_DEG`` wide, with a saturated run as long within ``ARM_PAIR_DEG`` of the
    opposite direction (a spike's partner can be a light of its own). A star has at
    least ``ARM_MIN`` arms; a lamp's tube or a moving light's stroke has two ends at
    most, and keeps them. All False otherwise."""
    nb = run.size
    far = run >= need
    # an arm along a row or column can leave its middle angle bin empty at small radii
    # (pixels sit on one side of the bin's edge): gaps of up to three bins are bridged
    far |= (np.roll(far, 1) | np.roll(far, 2)) & (np.roll(far, -1) | np.roll(far, -2))
    if far.all() or far.sum() < ARM_MIN:
        return np.zeros(nb, dtype=bool)
    # label the runs of far angles around the circle, starting after a near one
    order = (int(np.argmin(far)) + np.arange(nb)) % nb
    f = far[order]
    begins = f & ~np.r_[False, f[:-1]]
    label = np.where(f, np.cumsum(begins), 0)
    n = int(label.max())
    widths = np.bincount(label, minlength=n + 1)[1:]
    firsts = order[np.flatnonzero(begins)]  # each run's first angle
    centres = (firsts + (widths - 1) / 2.0) % nb
    tol = round(ARM_PAIR_DEG * nb / 360.0)
    opposite = np.round(centres + nb / 2.0).astype(np.int64)
    sat_far = sat_run >= need
    partner = sat_far[(opposite[:, None] + np.arange(-tol, tol + 1)[None, :]) % nb].any(axis=1)
    # a spike stands out of the dark between spikes: the saturated runs on each flank
    # (FLANK_GAP_BINS to LOCAL_HALF_BINS angles beyond its own) are short against it; a
    # dense scene around a light (a lit facade's grid of windows) has long runs there too
    side = np.arange(FLANK_GAP_BINS, LOCAL_HALF_BINS + 1)
    left = np.median(sat_run[(firsts[:, None] - side[None, :]) % nb], axis=1)
    right = np.median(sat_run[(firsts[:, None] + widths[:, None] - 1 + side[None, :]) % nb], axis=1)
    length = np.zeros(n + 1)
    np.maximum.at(length, label, run[order])
    stands = length[1:] >= need + FLANK_FACTOR * np.maximum(left, right)
    arm = (widths * 360.0 / nb <= ARM_MAX_DEG) & partner & stands
    if arm.sum() < ARM_MIN:
        return np.zeros(nb, dtype=bool)
    out = np.zeros(nb, dtype=bool)
    out[order] = np.r_[False, arm][label]
    return out


def _core(own: np.ndarray) -> tuple[float, float]:
    """The centre of a light's largest inscribed disc (the mean of the pixels deepest in
    ``own``, within half a pixel), in its box."""
    depth = ndimage.distance_transform_edt(np.pad(own, 1))[1:-1, 1:-1]
    py, px = np.nonzero(depth >= depth.max() - 0.5)
    return float(py.mean()), float(px.mean())


def _mark(
    on: np.ndarray,
    width: int,
    pixels: tuple[np.ndarray, np.ndarray],
    centre: tuple[float, float],
    start: float,
    n_rings: int,
    angles: np.ndarray,
    run: np.ndarray,
) -> None:
    """Set ``on`` (flat, the sensor's pixels) at the ``pixels`` (``(ys, xs)`` with events,
    sorted by row) in the ``angles`` around ``centre``, out to each angle's ``run``
    (rings from ``start``)."""
    cy, cx = centre
    far = start + RADIAL_BIN_PX * float(run[angles].max())
    near_y, near_x = _near(*pixels, cy, cx, far)
    ok, ring, tb = _polar_bins(near_x - cx, near_y - cy, start, n_rings)
    hit = angles[tb] & (ring < run[tb])
    on[near_y[ok][hit] * width + near_x[ok][hit]] = True


def _rows(ys: np.ndarray, cy: float, reach: float) -> tuple[int, int]:
    """The slice of ``ys`` (sorted) within ``reach`` rows of ``cy``."""
    lo, hi = np.searchsorted(ys, [cy - reach, cy + reach + 1])
    return int(lo), int(hi)


def _near(
    ys: np.ndarray, xs: np.ndarray, cy: float, cx: float, reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """The pixels ``(ys, xs)`` (sorted by row) in the square of half-side ``reach``
    around ``(cy, cx)``."""
    lo, hi = _rows(ys, cy, reach)
    keep = np.abs(xs[lo:hi] - cx) <= reach
    return ys[lo:hi][keep], xs[lo:hi][keep]


def in_streak_prior(
    events: np.ndarray,
    sensor_size: SensorSize,
    window_us: int,
    *,
    cell: int = 8,
    lights: np.ndarray | None = None,
) -> np.ndarray:
    """Whether each event of a window lies on a diffraction spike of one of its lights
    (``lights``: the window's :func:`~edeflare.lights.cells.light_cells`, when
    already counted).

    Examples
    --------
    A light of radius 5 with two opposite saturated spikes along its row, 60 px each
    (4 events per pixel), and an event off the spikes:

    >>> from edeflare.events import make_events
    >>> yy, xx = np.mgrid[55:65, 95:105]
    >>> light = np.tile(np.stack([xx.ravel(), yy.ravel()]), 20)
    >>> sx = np.r_[np.arange(106, 166), np.arange(34, 94)].repeat(4)
    >>> x = np.r_[light[0], sx, 100]
    >>> y = np.r_[light[1], np.full(sx.size, 60), 100]
    >>> ev = make_events(np.arange(x.size), x, y, np.ones(x.size))
    >>> on = in_streak_prior(ev, (200, 120), 20_000)
    >>> n = light.shape[1]
    >>> bool(on[n:-1][np.abs(sx - 100) > 30].all()), bool(on[:n].any()), bool(on[-1])
    (True, False, False)
    """
    width, height = check_sensor_size(sensor_size)
    _, found, at = _lights(events, sensor_size, window_us, cell, lights)
    if not found or at is None:
        return np.zeros(events.size, dtype=bool)
    # per pixel, once: a spike is found from the saturated pixels alone, and the
    # pixels with events are judged (not each event) where one is found
    pixel, n_px = at.pixel, at.counts.ravel()
    sat_y, sat_x = np.divmod(np.flatnonzero(n_px >= MIN_PIXEL_EVENTS), width)
    pixels = None  # the pixels with events: wanted only once a spike is found
    on_spike = np.zeros(width * height, dtype=bool)
    angle = (np.arange(ANGLE_BINS) + 0.5) / ANGLE_BINS * 2 * math.pi - math.pi
    cos, sin = np.cos(angle), np.sin(angle)
    for ys, xs, own, radius in found:
        cy, cx, edge = _centre(own, ys.start, xs.start)
        reach = STREAK_EXTENT * radius
        rows = _rows(sat_y, cy, reach)
        if own.sum() > ROUND_AREA * math.pi * radius**2:
            # a star: spikes bright enough to be part of the light, measured from its
            # core (the mean of its pixels leans towards its longer arms)
            ay, ax = _core(own)
            ay, ax = ay + ys.start, ax + xs.start
            start = ARM_ROOT_RADII * radius
            n_rings = math.ceil((reach - start) / RADIAL_BIN_PX)
            need = ARM_LENGTH_RADII * radius / RADIAL_BIN_PX
            own_y, own_x = np.nonzero(own)
            own_y, own_x = own_y + ys.start, own_x + xs.start
            run = _angle_runs(own_y, own_x, 0, own_y.size, ay, ax, reach, start, n_rings, need)
            arm_rows = _rows(sat_y, ay, reach)
            sat_run = _angle_runs(sat_y, sat_x, *arm_rows, ay, ax, reach, start, n_rings, need)
            arms = _arms(run, sat_run, need)
            if arms.any():
                run = np.maximum(run, sat_run)  # out to the spike's end, past the light
                if pixels is None:
                    pixels = np.divmod(np.flatnonzero(n_px), width)
                _mark(on_spike, width, pixels, (ay, ax), start, n_rings, arms, run)
        start = edge + 2.0 + SKIP_RADII * radius
        n_rings = math.ceil((reach - start) / RADIAL_BIN_PX)
        if n_rings < 2:
            continue
        need = max(MIN_LENGTH_RADII * radius, MIN_LENGTH_PX) / RADIAL_BIN_PX
        run = _angle_runs(sat_y, sat_x, *rows, cy, cx, reach, start, n_rings, need)
        if run.max() < need:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(cos > 0, (width - 1 - cx) / cos, np.where(cos < 0, -cx / cos, np.inf))
            ty = np.where(sin > 0, (height - 1 - cy) / sin, np.where(sin < 0, -cy / sin, np.inf))
        room = (np.minimum(tx, ty) - start) / RADIAL_BIN_PX
        spike = _spikes(run, need, room)
        if not spike.any():
            continue
        if pixels is None:
            pixels = np.divmod(np.flatnonzero(n_px), width)
        _mark(on_spike, width, pixels, (cy, cx), start, n_rings, spike, run)
    # no round light is on a spike: a spike runs on through the lights in its way
    # (another lamp of a row, or its own source seen from a segment of the spike
    # that passes the light test itself); those segments are long, not round
    if on_spike.any():
        frame = on_spike.reshape(height, width)
        for ys, xs, own, radius in found:
            if own.sum() <= ROUND_AREA * math.pi * radius**2:
                frame[ys, xs] &= ~own
    return on_spike[pixel]


@dataclasses.dataclass(frozen=True)
class StreakParams:
    """The streak rule's knob."""

    streak_shift: float = knob(
        0.0,
        "--streak-shift",
        "lower the keep logit by this much on the diffraction spikes of the window's "
        "lights (saturated radial runs in opposite pairs; 0: off)",
    )


def _streak_shift(params: StreakParams, ctx: WindowContext) -> np.ndarray:
    return -(params.streak_shift * ctx.on_spikes)


STREAK_RULE = Rule(
    "streak", StreakParams, _streak_shift, lambda p: bool(p.streak_shift), "lights",
    "the lights' saturated diffraction spikes",
)  # fmt: skip
