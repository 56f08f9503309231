"""Where a window's isolated events crowd: scattered light, not background activity.

A night lamp too slow for the light test (:func:`~edeflare.lights.cells.window_lights`)
still scatters its light into isolated events, along its streaks and rings, around it.
A sensor's background activity fires isolated events too, but evenly over the sensor.
:func:`crowded_isolated` tells the two apart by place: an isolated event crowds where
more isolated events of its window lie around it than the window's typical (median)
density of them allows. :func:`scatter_field` marks where the crowded ones are a share
of all the events: around the slow lamp, not among a scene's edges.
:func:`light_free_shifts` is what the model adds to the keep logits of a window without
a light (:class:`~edeflare.models.infer.ModelDeflarer`): the light-free shift for the
scene, none for the crowded isolated events, and in the field a lower logit for them,
none for the bloom next to the lamp and a higher one for the lamp's dense events.

Measured on the isolated events (fewer than 2 others in their 5x5 square) of light-free
windows, at 3 Poisson standard deviations (the study ``reference-window``, ``docs/studies.md``):
99.8 % of the streak and ghost events of the digitised real reference window crowd, 8 % of
``eflare-r-sim``'s (background activity), and about half of the few isolated events of
the real scenes without a light. Crowded isolated events are a third of the digitised
window's events (a fifth to three fifths, by the lamp's rate) and 0.1-7 % of the
others' (median over windows).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..events import SensorSize, check_sensor_size
from . import Rule, check_support, knob
from .context import WindowContext

__all__ = [
    "FIELD_MAX_RATE",
    "FIELD_MIN_EVENTS",
    "FIELD_MIN_SHARE",
    "LIGHT_FREE_RULE",
    "SCATTER_CELL",
    "SCATTER_REACH",
    "SOURCE_SUPPORT",
    "LightFreeParams",
    "crowded_isolated",
    "light_free_shifts",
    "needs_support",
    "scatter_field",
    "scatter_reach",
]

SCATTER_CELL = 16
"""Pixels per side of the cells the isolated events are counted in."""

SCATTER_REACH = 1 / 6
"""How far from an event's cell its square reaches, as a share of the sensor's smaller
side (:func:`scatter_reach`): 120 px at 1280x720, 80 px at 640x480, 43 px at 346x260.
Scattered light reaches a few times a light's radius. The square must also stay well
inside the sensor: where it covers most of it, every square holds about the same events
and nothing stands out against their median."""


FIELD_MIN_EVENTS = 5
"""A scattered-light field needs at least this many crowded isolated events in a square."""

FIELD_MIN_SHARE = 0.1
"""... and they must be at least this share of the square's events."""

FIELD_MAX_RATE = 5.0
"""... and the square's events fire at most this many times per pixel and second, over
its area: scattered light is weak, so its field is a dark part of the sensor. A lit
scene's texture (foliage, a road's surface by day) also holds crowded isolated events,
but among far more events: 5.4-31 per pixel and second (median 13.8) in the Prophesee
Gen4.1 daytime street's squares where the field would lie, 2.4 at most in the digitised
digitised night reference window (1.5 at its calibrated lamp rate), 3.7 at the 95th percentile
in ``eflare-r-sim``'s and the real DAVIS346 scenes' few fields
(the study ``reference-window``). :func:`light_free_shifts` holds
crowding itself to the same darkness."""

SOURCE_SUPPORT = 6
"""In a field, an event with at least this many others of its window in its 5x5 square
is dense, the source's own (:func:`light_free_shifts`); one with fewer, and some
support, is the scattered light's denser part near the source."""


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
    isolated = _judged(events, isolated, "isolated")
    if not z >= 0:
        raise ValueError(f"z must be >= 0, got {z!r}")
    return _crowded(_Squares((width, height), cell, reach, events), isolated, z)


def _crowded(squares: _Squares, isolated: np.ndarray, z: float) -> np.ndarray:
    """:func:`crowded_isolated` on a window's counted squares (checked arguments)."""
    out = np.zeros(isolated.size, dtype=bool)
    which = np.flatnonzero(isolated)
    if which.size < 2:
        return out
    count = squares.counts(isolated)
    density = float(np.median(count / squares.cells))  # isolated events per cell, typically
    at = squares.flat[which]
    count, lam = count.ravel()[at], density * squares.cells.ravel()[at]
    out[which] = (count - 1 - lam) > z * np.sqrt(lam + 1.0)
    return out


def scatter_field(
    events: np.ndarray,
    sensor_size: SensorSize,
    crowded: np.ndarray,
    *,
    span_us: int | None = None,
    cell: int = SCATTER_CELL,
    reach: int | None = None,
) -> np.ndarray:
    """Which events lie in scattered light: where crowded isolated events are a share of all.

    An event is in the field where the square of cells within ``reach`` of its cell
    holds at least :data:`FIELD_MIN_EVENTS` ``crowded`` events
    (:func:`crowded_isolated`), they are at least :data:`FIELD_MIN_SHARE` of the
    square's events, and those fire at most :data:`FIELD_MAX_RATE` times per pixel and
    second over ``span_us``. Around a lamp too slow for the light test its scattered
    light is a large share of the few events of a dark part of the sensor; in a scene,
    crowded isolated events sit among many more of its edges, and in a lit scene's
    texture among far more events.

    Parameters
    ----------
    events : numpy.ndarray
        One window's events, on the sensor.
    sensor_size : (width, height)
    crowded : numpy.ndarray
        bool, one per event: :func:`crowded_isolated`'s answer.
    span_us : int, optional
        The time the window's events cover, in µs (default: from its first event to its
        last; :func:`~edeflare.lights.cells.covered_us` is what the model passes).
    cell, reach : int
        As for :func:`crowded_isolated`.

    Returns
    -------
    numpy.ndarray
        bool, one per event.

    Examples
    --------
    Ten crowded events among 40 others in one corner of a 640x480 sensor: the events
    whose square (80 px each way, at cell precision) holds them are in the field.

    >>> from edeflare.events import make_events
    >>> x = np.r_[np.arange(10) * 3 + 20, np.arange(40) % 20 + 20, 600]
    >>> y = np.r_[np.full(10, 20), np.arange(40) // 20 + 40, 460]
    >>> ev = make_events(np.arange(51), x, y, np.ones(51))
    >>> crowded = np.r_[np.ones(10, bool), np.zeros(41, bool)]
    >>> field = scatter_field(ev, (640, 480), crowded, span_us=20_000)
    >>> bool(field[:50].all()), bool(field[50])
    (True, False)
    >>> bool(scatter_field(ev, (640, 480), crowded & (np.arange(51) < 4), span_us=20_000).any())
    False

    The same events within 51 µs fire over 50 times per pixel and second over their
    squares (7x7 to 9x7 cells): a lit texture, not scattered light.

    >>> bool(scatter_field(ev, (640, 480), crowded).any())
    False
    """
    squares = _Squares(check_sensor_size(sensor_size), cell, reach, events)
    crowded = _judged(events, crowded, "crowded")
    return _field(squares, crowded, _dark(squares, _span(events, span_us)))


def _span(events: np.ndarray, span_us: int | None) -> int:
    """The window's time its events cover (µs): given, or their own extent."""
    if span_us is None:
        return int(events["t"][-1] - events["t"][0]) + 1 if events.size else 1
    if not span_us >= 1:
        raise ValueError(f"span_us must be >= 1, got {span_us!r}")
    return int(span_us)


def _field(squares: _Squares, crowded: np.ndarray, dark: np.ndarray) -> np.ndarray:
    """:func:`scatter_field` on a window's counted squares (checked arguments), its
    squares' darkness given (:func:`_dark`)."""
    if crowded.sum() < FIELD_MIN_EVENTS:
        return np.zeros(crowded.size, dtype=bool)
    # decided per cell's square, then read at each event's cell: one gather
    mine, every = squares.counts(crowded), squares.every
    field = (mine >= FIELD_MIN_EVENTS) & (mine >= FIELD_MIN_SHARE * every) & dark
    return field.ravel()[squares.flat]


def _dark(squares: _Squares, span_us: int) -> np.ndarray:
    """Which cells' squares, ``(gh, gw)``, fire at most :data:`FIELD_MAX_RATE` times per
    pixel and second over ``span_us``: scattered light is weak."""
    pixels = squares.cells * squares.cell**2
    return squares.every <= FIELD_MAX_RATE * 1e-6 * span_us * pixels


def _judged(events: np.ndarray, mask: np.ndarray, name: str) -> np.ndarray:
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != (events.size,):
        raise ValueError(
            f"{name} must hold one bool per event ({events.size}), got shape {mask.shape}"
        )
    return mask


class _Squares:
    """A window's events counted per cell, and in each cell's square: the cells within
    ``reach`` pixels (at cell precision), cut at the sensor's edge. ``flat`` is each
    event's cell, ``cells`` each square's number of cells ``(gh, gw)``."""

    def __init__(
        self, sensor_size: tuple[int, int], cell: int, reach: int | None, events: np.ndarray
    ) -> None:
        if reach is None:
            reach = scatter_reach(sensor_size)
        if cell < 1 or reach < 0:
            raise ValueError(f"need cell >= 1 and reach >= 0, got cell={cell}, reach={reach}")
        self.cell, self.k = int(cell), int(reach) // int(cell)
        self.gw, self.gh = -(-sensor_size[0] // cell), -(-sensor_size[1] // cell)
        self.flat = (events["y"] // cell).astype(np.int64) * self.gw + events["x"] // cell
        self._corners, self.cells = _square_corners(self.gw, self.gh, self.k)

    @functools.cached_property
    def every(self) -> np.ndarray:
        """All the events in each cell's square, ``(gh, gw)``."""
        return self.counts()

    def counts(self, mask: np.ndarray | None = None) -> np.ndarray:
        """The (masked) events in each cell's square, ``(gh, gw)``."""
        flat = self.flat if mask is None else self.flat[mask]
        per_cell = np.bincount(flat, minlength=self.gh * self.gw).reshape(self.gh, self.gw)
        return _box_sums(per_cell, self._corners)


def _box_sums(per_cell: np.ndarray, corners: tuple[np.ndarray, ...]) -> np.ndarray:
    """Each cell's square sum of ``per_cell``: a summed-area table with a zero row and
    column first, read at the squares' four corners (:func:`_square_corners`)."""
    gh, gw = per_cell.shape
    table = np.zeros((gh + 1, gw + 1), dtype=np.int64)
    table[1:, 1:] = per_cell.cumsum(axis=0).cumsum(axis=1)
    t = table.ravel()
    c11, c01, c10, c00 = corners
    return (t[c11] - t[c01] - t[c10] + t[c00]).reshape(gh, gw)


@functools.lru_cache(maxsize=16)
def _square_corners(gw: int, gh: int, k: int) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """Where each cell's square's corners lie in the summed-area table of a ``(gh, gw)``
    grid (flat indices), and each square's number of cells: the same for every window
    of a sensor, so made once."""
    ry, rx = np.arange(gh), np.arange(gw)
    y0, y1 = np.clip(ry - k, 0, gh), np.clip(ry + k + 1, 0, gh)
    x0, x1 = np.clip(rx - k, 0, gw), np.clip(rx + k + 1, 0, gw)

    def at(ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        return (ys[:, None] * (gw + 1) + xs[None, :]).ravel()

    corners = (at(y1, x1), at(y0, x1), at(y1, x0), at(y0, x0))
    cells = ((y1 - y0)[:, None] * (x1 - x0)[None, :]).astype(np.int64)
    for a in (*corners, cells):
        a.flags.writeable = False  # shared by every window
    return corners, cells


def light_free_shifts(
    events: np.ndarray,
    sensor_size: SensorSize,
    support: np.ndarray,
    *,
    shift: float,
    gate: int = 0,
    crowding: float = 0.0,
    scatter_shift: float = 0.0,
    span_us: int | None = None,
) -> np.ndarray:
    """How much each event's keep logit rises in a window without a light (float64).

    Flare needs a bright source; without one in view, what the network would drop is
    more likely scene. So every event rises by ``shift``, except:

    - with ``gate``, the isolated ones (fewer than ``gate`` others in their 5x5 square:
      ``support``, :func:`~edeflare.models.mask_kernels.event_support`): a lamp too slow
      for the light test scatters its light into such events;
    - with ``crowding`` too, only the isolated ones that crowd
      (:func:`crowded_isolated` at ``z = crowding``) in a dark part of the sensor (their
      square's events firing at most :data:`FIELD_MAX_RATE` times per pixel and second
      over ``span_us``): background activity is even, and crowding among a lit
      texture's many events is the texture's;
    - with ``scatter_shift`` too, in the :func:`scatter_field` of the crowded ones
      (around the slow lamp) the events with support under :data:`SOURCE_SUPPORT` do
      not rise either (the dense bloom next to the lamp), the denser ones (the lamp's
      own) rise by ``scatter_shift`` more, and the crowded isolated ones fall by it.

    Parameters
    ----------
    events : numpy.ndarray
        One window's events, on the sensor, with no light in view.
    sensor_size : (width, height)
    support : numpy.ndarray
        int, one per event: others of the window in the event's 5x5 square.
    shift, scatter_shift : float
        Keep-logit units, at least 0.
    gate : int
        Support from which an event is not isolated (0: none is).
    crowding : float
        Poisson standard deviations (0: every isolated event is left to the network).
    span_us : int, optional
        The time the window's events cover (:func:`scatter_field`; default: from the
        first event to the last).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2], [5, 6, 40], [5, 5, 40], [1, 1, 1])
    >>> support = np.array([1, 1, 0])
    >>> light_free_shifts(ev, (64, 64), support, shift=4.0).tolist()
    [4.0, 4.0, 4.0]
    >>> light_free_shifts(ev, (64, 64), support, shift=4.0, gate=1).tolist()
    [4.0, 4.0, 0.0]
    """
    support = np.asarray(support)
    if support.shape != (events.size,):
        raise ValueError(f"support must hold one count per event ({events.size}), got "
                         f"shape {support.shape}")  # fmt: skip
    if not gate:
        return np.full(events.size, float(shift))
    isolated = support < gate
    if not crowding:
        return float(shift) * ~isolated
    if not crowding >= 0 or not scatter_shift >= 0:
        raise ValueError(f"crowding and scatter_shift must be >= 0, got {crowding!r} "
                         f"and {scatter_shift!r}")  # fmt: skip
    # one count of the window's cells serves both the crowding and the field
    squares = _Squares(check_sensor_size(sensor_size), SCATTER_CELL, None, events)
    # crowding in a lit texture is the texture's: only in the dark is it scattered light
    dark = _dark(squares, _span(events, span_us))
    crowded = _crowded(squares, isolated, crowding) & dark.ravel()[squares.flat]
    raised = ~crowded
    if not scatter_shift:
        return float(shift) * raised
    field = _field(squares, crowded, dark)
    dense = support >= SOURCE_SUPPORT
    raised &= ~(field & ~isolated & ~dense)  # the bloom next to the slow lamp
    out = float(shift) * raised
    out += float(scatter_shift) * (field & dense)  # the lamp itself
    out -= float(scatter_shift) * (field & crowded)  # its scattered light
    return out


@dataclasses.dataclass(frozen=True)
class LightFreeParams:
    """The light-free rule's knobs: its shift, and which events it spares."""

    light_free_shift: float = knob(
        0.0,
        "--light-free-shift",
        "raise the keep logit by this much in the windows without a light (flare needs a "
        "bright source; 0: off)",
    )
    light_free_support: int = knob(
        0,
        "--light-free-support",
        "the light-free shift raises only the events with at least this many other events "
        "of their window in their 5x5 square (a night lamp too slow for the light test "
        "scatters isolated events; 0: every event)",
        check=check_support,
        metavar="N",
    )
    light_free_crowding: float = knob(
        0.0,
        "--light-free-crowding",
        "with a light-free support, the isolated events still get the light-free shift "
        "unless they crowd, more of them within a sixth of the sensor's smaller side than "
        "the window's median density allows by this many Poisson standard deviations "
        "(scattered light lies around its source, background activity evenly; 0: no "
        "isolated event gets it)",
        metavar="Z",
    )
    scatter_shift: float = knob(
        0.0,
        "--scatter-shift",
        "with a light-free support and crowding: in a window without a light, where "
        "crowded isolated events are a share of all (the scattered light of a lamp too "
        "slow for the light test), lower them by this much, raise the dense events (the "
        "lamp) by this much more, and give the sparser ones (its bloom) no light-free "
        "shift (0: off)",
    )


def needs_support(params: LightFreeParams) -> bool:
    """Whether the rule reads each event's 5x5 support at these values."""
    return bool(params.light_free_support and (params.light_free_shift or params.scatter_shift))


def _light_free_shift(params: LightFreeParams, ctx: WindowContext) -> np.ndarray | float:
    if ctx.support is None or not needs_support(params):
        return params.light_free_shift
    return light_free_shifts(
        ctx.events, ctx.sensor_size, ctx.support, shift=params.light_free_shift,
        gate=params.light_free_support, crowding=params.light_free_crowding,
        scatter_shift=params.scatter_shift, span_us=ctx.span_us,
    )  # fmt: skip


LIGHT_FREE_RULE = Rule(
    "light-free", LightFreeParams, _light_free_shift,
    lambda p: bool(p.light_free_shift or p.scatter_shift), "light-free",
    "no light in the window (flare needs a bright source)",
)  # fmt: skip
