r"""Per-event evidence for a learned keep head: what the rules looked at, as numbers.

The rules of :mod:`edeflare.rules` each turn one piece of evidence into a fixed
logit shift (a verdict). Here the same evidence, and more, becomes one row of
input features per event; :class:`~edeflare.models.event_head.EventHead` learns
from simulated pairs how much each is worth, together with the mask network's
own keep logit (its whole-frame context).

:data:`FEATURES` names the columns, in order. A model card lists the names its
head was trained on; a name this version does not know is refused when the card
loads (:func:`check_feature_names`). Every feature is computed from the window's
own events, so the head runs in the same streaming windows as the network.

Examples
--------
>>> from edeflare.events import make_events
>>> from edeflare.rules.context import WindowContext
>>> ev = make_events([0, 5, 9], [1, 2, 2], [1, 1, 1], [1, 0, 1])
>>> ctx = WindowContext(ev, (16, 8), 20_000)
>>> table = window_features(ctx, np.zeros(3, np.float32))
>>> table.shape == (3, len(FEATURES)), table.dtype
(True, dtype('float32'))
>>> table[:, list(FEATURES).index("light_free")].tolist()   # no light in this window
[1.0, 1.0, 1.0]
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Mapping, Sequence

import numba
import numpy as np

from ..errors import ParameterError
from ..rules.context import WindowContext

__all__ = [
    "DEFAULT_FEATURES",
    "FEATURES",
    "LIGHT_FREE_FEATURES",
    "RELATIVE_FEATURES",
    "check_feature_names",
    "relative_features",
    "window_features",
]

FEATURES: dict[str, str] = {
    "net_logit": "the mask network's keep logit (cells of the whole frame, and the pixel)",
    "polarity": "1 for ON, 0 for OFF",
    "light_free": "1 where the window holds no light (flare needs a bright source)",
    "light_distance": "log(1 + distance to the nearest light's centre in its radii); "
    f"log(1 + {64}) without a light",
    "halo": "1 in the band of scattered light around a light (edeflare.rules.halo)",
    "ghost": "1 where a reflective ghost of a light can be, and sparse there",
    "spike": "1 on a light's saturated diffraction spike",
    "far": "1 far from every light (beyond 0.3 of the width and 8 radii)",
    "support": "log(1 + other events of the window in the event's 5x5 square)",
    "crowded": "1 for an isolated event (support <= 2) among more isolated ones than the "
    "window's median density allows (3 Poisson standard deviations)",
    "field": "1 in scattered light: where crowded isolated events are a share of all",
    "rate_pixel": "log(1 + events of the event's pixel in the window)",
    "rate_8": "log(1 + events per pixel of its 8x8 cell)",
    "rate_32": "log(1 + events per pixel of the 32x32 square around its cell)",
    "rate_128": "log(1 + events per pixel of the 128x128 square around its cell)",
    "rate_window": "log(1 + events per pixel of the whole window)",
    "balance_pixel": "(ON - OFF) / all events of its pixel",
    "balance_8": "(ON - OFF) / all events of its 8x8 cell",
    "balance_32": "(ON - OFF) / all events of the 32x32 square around its cell",
    "since_pixel": "log(1 + ms since its pixel's previous event of the window); "
    "log(1 + window in ms) for the pixel's first",
    "centre_distance": "distance to the sensor's centre over half its diagonal",
    "since_same": "log(1 + ms since its pixel's previous event of the same polarity in the "
    "window); log(1 + window in ms) for the first (a flickering light's period)",
    "sync_64": "log((1 + events of its polarity in its 64x64 block and 1 ms) / (1 + their "
    "mean over the window's 1 ms bins)): in a burst, as a flicker's scattered light fires",
    "rel_pixel": "log(events of its pixel / events per pixel of its 8x8 cell): the pixel "
    "against its cell, the same at any rate",
    "rel_8": "log(events per pixel of its 8x8 cell / events per pixel of the whole window)",
    "rel_32": "log(events per pixel of the 32x32 square around its cell / of the whole window)",
    "rel_128": "log(events per pixel of the 128x128 square around its cell / of the whole window)",
    "rel_support": "log((1 + support) / (25 x events per pixel of its 8x8 cell)): its 5x5 "
    "square against its cell's density",
    "rel_since": "log(1 + ms since its pixel's previous event x its pixel's events / window "
    "in ms): the gap over the pixel's mean gap",
    "free_support": "support in a window without a light; 0 where a light is found",
    "free_rate_pixel": "rate_pixel in a window without a light; 0 where a light is found",
    "free_rate_8": "rate_8 in a window without a light; 0 where a light is found",
    "free_rate_32": "rate_32 in a window without a light; 0 where a light is found",
    "free_rate_128": "rate_128 in a window without a light; 0 where a light is found",
    "free_rate_window": "rate_window in a window without a light; 0 where a light is found",
    "free_since_pixel": "since_pixel in a window without a light; 0 where a light is found",
}
"""The per-event features, in column order, with what each holds. The ``rate_*`` counts
are scaled to a full window where the stream covers only part of it."""

RELATIVE_FEATURES: dict[str, tuple[str, ...]] = {
    "rel_pixel": ("rate_pixel", "rate_8"),
    "rel_8": ("rate_8", "rate_window"),
    "rel_32": ("rate_32", "rate_window"),
    "rel_128": ("rate_128", "rate_window"),
    "rel_support": ("support", "rate_8"),
    "rel_since": ("since_pixel", "rate_pixel"),
}
"""Each rate-relative feature and the absolute features it is computed from
(:func:`relative_features`). Thinning a window at random scales every count, and each
absolute rate with it, by the same share; these ratios stay (in expectation)."""

LIGHT_FREE_FEATURES: dict[str, str] = {
    name: name.removeprefix("free_") for name in FEATURES if name.startswith("free_")
}
"""Each light-free feature and the absolute one it gates: its value in a window where the
light test finds no light, 0 in one where it finds a light. Beside the rate-relative
features, a head can read the absolute rates where no light's own rate sets the scale
(a quiet window's sparse scattered light) and only the ratios where one does."""

DEFAULT_FEATURES: tuple[str, ...] = tuple(
    name
    for name in FEATURES
    if name not in ("since_same", "sync_64", *RELATIVE_FEATURES, *LIGHT_FREE_FEATURES)
)
"""What ``train-head`` reads unless told otherwise: every feature but the two flicker
features, which a head of ``learned``'s form trained with them used to keep 64 % of a real
day street that has flicker in it (``experiments/context-head``), and the rate-relative
ones (:data:`RELATIVE_FEATURES`) and the light-free ones (:data:`LIGHT_FREE_FEATURES`)."""

NO_LIGHT_RADII = 64.0
"""The distance, in radii, given to every event of a window without a light."""

_CELL = 8


def check_feature_names(names: Sequence[str], where: str = "model card") -> tuple[str, ...]:
    """``names`` as a tuple, each a known :data:`FEATURES` name, none twice.

    Examples
    --------
    >>> check_feature_names(["net_logit", "support"])
    ('net_logit', 'support')
    >>> check_feature_names(["net_logit", "moon_phase"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: model card: unknown feature 'moon_phase'; known: net_logit, ...
    """
    names = tuple(str(n) for n in names)
    for name in names:
        if name not in FEATURES:
            known = ", ".join(FEATURES)
            raise ParameterError(f"{where}: unknown feature {name!r}; known: {known}")
    if len(set(names)) != len(names):
        raise ParameterError(f"{where}: a feature is named twice in {list(names)}")
    return names


def relative_features(
    columns: Mapping[str, np.ndarray], names: Sequence[str], window_us: int = 20_000
) -> dict[str, np.ndarray]:
    """The rate-relative features ``names`` (of :data:`RELATIVE_FEATURES`) from the absolute
    columns they are computed from, as :func:`window_features` gives them.

    Only ratios of counts enter, so a window with every event kept at random with
    probability q gives (in expectation) the same values as the whole window. Computed from
    the absolute columns (not from the counts) so that rows drawn with the absolute features
    give the relative ones too.

    Examples
    --------
    >>> # a pixel with 4 events in a cell of 1 event per pixel, in a window of 0.25 a pixel
    >>> cols = {"rate_pixel": np.log1p([4.0]), "rate_8": np.log1p([1.0]),
    ...         "rate_window": np.log1p([0.25])}
    >>> out = relative_features(cols, ["rel_pixel", "rel_8"])
    >>> np.round(np.exp([out["rel_pixel"][0], out["rel_8"][0]]), 6).tolist()
    [4.0, 4.0]
    """
    for name in names:
        if name not in RELATIVE_FEATURES:
            raise ParameterError(f"{name!r} is not a rate-relative feature")
    # each column read, once (rate_8 and rate_window serve three features each); not the
    # others: a window's every column is millions of rows
    read = {k for name in names for k in RELATIVE_FEATURES[name]}
    counts = {k: np.expm1(np.asarray(columns[k], np.float64)) for k in read}
    out: dict[str, np.ndarray] = {}
    for name in names:
        a, b = (counts[k] for k in RELATIVE_FEATURES[name])
        if name == "rel_support":  # the event and its 5x5 square against 25 pixels' share
            out[name] = np.log((1.0 + a) / np.maximum(25.0 * b, 1e-9))
        elif name == "rel_since":  # the gap in ms x the pixel's events / the window in ms
            out[name] = np.log1p(a * b / (window_us / 1000.0))
        else:  # every event's pixel and cell hold one event at least
            out[name] = np.log(np.maximum(a, 1e-9) / np.maximum(b, 1e-9))
    return out


def _box(per_cell: np.ndarray, radius: int) -> np.ndarray:
    """Sums over the ``(2 radius + 1)^2`` squares of cells around each cell (cut at the edges)."""
    h, w = per_cell.shape
    table = np.zeros((h + 1, w + 1), np.float64)
    table[1:, 1:] = per_cell.cumsum(0).cumsum(1)
    y0 = np.clip(np.arange(h) - radius, 0, h)
    y1 = np.clip(np.arange(h) + radius + 1, 0, h)
    x0 = np.clip(np.arange(w) - radius, 0, w)
    x1 = np.clip(np.arange(w) + radius + 1, 0, w)
    return table[y1][:, x1] - table[y0][:, x1] - table[y1][:, x0] + table[y0][:, x0]


def _box_area(h: int, w: int, radius: int, cell: int, sensor: tuple[int, int]) -> np.ndarray:
    """Pixels of each cell's square of cells, cut at the sensor's edges."""
    ones = np.zeros((h, w), np.float64)
    width, height = sensor
    ones[:, :] = cell * cell
    ones[-1, :] = cell * (height - (h - 1) * cell)
    ones[:, -1] = cell * (width - (w - 1) * cell)
    ones[-1, -1] = (height - (h - 1) * cell) * (width - (w - 1) * cell)
    return _box(ones, radius)


def _light_distance(ctx: WindowContext) -> np.ndarray:
    """Distance to the nearest light's centre in its radii (:data:`NO_LIGHT_RADII` without)."""
    ev = ctx.events
    out = np.full(ev.size, NO_LIGHT_RADII, np.float64)
    if not ctx.has_lights or not ev.size:
        return out
    from ..lights.cells import _lights

    _, found, _ = _lights(ev, ctx.sensor_size, ctx.span_us, _CELL, ctx.lights)
    x, y = ev["x"].astype(np.float64), ev["y"].astype(np.float64)
    for ys, xs, own, radius in found:
        py, px = np.nonzero(own)
        cy, cx = py.mean() + ys.start, px.mean() + xs.start
        if not ctx.lights[int(cy) // _CELL, int(cx) // _CELL]:
            continue  # dense scene, not a light (window_lights left it out)
        d = np.hypot(x - cx, y - cy) / max(radius, 1.0)
        np.minimum(out, d, out=out)
    return np.minimum(out, NO_LIGHT_RADII)


@numba.njit(cache=True, nogil=True)
def _gaps(t, x, y, width, window_us, last):  # pragma: no cover - compiled
    """One pass in time order with each pixel's last time (``last``: -1 everywhere,
    left so): the gap to the pixel's previous event, ``window_us`` for its first."""
    out = np.empty(t.size, np.int64)
    for i in range(t.size):
        pix = np.int64(y[i]) * width + x[i]
        out[i] = window_us if last[pix] < 0 else np.int64(t[i]) - last[pix]
        last[pix] = t[i]
    for i in range(t.size):
        last[np.int64(y[i]) * width + x[i]] = -1
    return out


# A compiled pass instead of numpy's stable argsort by pixel: 5-10x faster on dense
# windows, the same integers.
_last_times = threading.local()


def _since_pixel(
    ev: np.ndarray, width: int, height: int, window_us: int, by_polarity: bool = False
) -> np.ndarray:
    """Microseconds since the pixel's previous event in the window (``window_us`` for its
    first); ``ev`` sorted by time, on the sensor. ``by_polarity``: the previous event of
    the same polarity (a grid twice as wide, ON beside OFF)."""
    x = ev["x"]
    if by_polarity:
        x, width = ev["x"].astype(np.int64) * 2 + (ev["p"] != 0), 2 * width
    n = width * height
    key = "polarity" if by_polarity else "frame"
    last = getattr(_last_times, key, None)
    if last is None or last.size != n:
        last = np.full(n, -1, np.int64)
        setattr(_last_times, key, last)
    return _gaps(ev["t"], x, ev["y"], width, window_us, last)


_SYNC_BLOCK, _SYNC_BIN_US = 64, 1_000


def _sync(ev: np.ndarray, x: np.ndarray, y: np.ndarray, on: np.ndarray, width: int) -> np.ndarray:
    """Each event's :data:`FEATURES` ``sync_64``: the events of its polarity in its block and
    1 ms bin against their mean over the window's bins (bins from its first event).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 100, 200, 5_000], [1, 2, 3, 4], [1, 1, 1, 1], [1, 1, 1, 1])
    >>> x, y = ev["x"].astype(np.int64), ev["y"].astype(np.int64)
    >>> # three in the first ms, one in the sixth: 4 / 6 a bin; log(4 / (5 / 3)), log(2 / (5 / 3))
    >>> np.round(_sync(ev, x, y, np.ones(4), 16), 3).tolist()
    [0.875, 0.875, 0.875, 0.182]
    """
    if not ev.size:
        return np.zeros(0)
    t = ev["t"].astype(np.int64)
    b = (t - t[0]) // _SYNC_BIN_US
    bins = int(b[-1]) + 1
    blocks_wide = -(-width // _SYNC_BLOCK)
    series = ((y // _SYNC_BLOCK) * blocks_wide + x // _SYNC_BLOCK) * 2 + on.astype(np.int64)
    key = series * bins + b
    counts = np.bincount(key)
    mean = np.bincount(series, minlength=int(series.max()) + 1) / bins
    return np.log((1.0 + counts[key]) / (1.0 + mean[series]))


def window_features(
    ctx: WindowContext,
    net_logit: np.ndarray,
    names: Sequence[str] | None = None,
    *,
    window_us: int = 20_000,
) -> np.ndarray:
    """The features of each event of one window ``(n, len(names))`` (float32).

    Parameters
    ----------
    ctx : WindowContext
        The window (its events, sensor, covered span, and each event's 5x5
        ``support``; counted here when the context has none).
    net_logit : numpy.ndarray
        The mask network's keep logit of each event.
    names : sequence of str, optional
        The columns (default: every :data:`FEATURES` name, in order).
    window_us : int
        The model's window: rates over a shorter covered span are scaled up to it.
    """
    names = tuple(FEATURES) if names is None else check_feature_names(names)
    relative = [n for n in names if n in RELATIVE_FEATURES]
    gated = [n for n in names if n in LIGHT_FREE_FEATURES]
    need = (
        set(names)
        | {k for n in relative for k in RELATIVE_FEATURES[n]}
        | {LIGHT_FREE_FEATURES[n] for n in gated}
    )
    ev = ctx.events
    n = ev.size
    if net_logit.shape != (n,):
        raise ValueError(f"net_logit has shape {net_logit.shape}, expected ({n},)")
    width, height = int(ctx.sensor_size[0]), int(ctx.sensor_size[1])
    scale = window_us / max(int(ctx.span_us), 1)
    x, y = ev["x"].astype(np.int64), ev["y"].astype(np.int64)
    on = (ev["p"] != 0).astype(np.float64)
    sign = 2.0 * on - 1.0
    cols: dict[str, np.ndarray] = {}

    def support() -> np.ndarray:
        if ctx.support is None:
            from .mask_kernels import event_support

            ctx.support = event_support(ev, ctx.sensor_size)
        return ctx.support

    cols["net_logit"] = np.asarray(net_logit, np.float64)
    cols["polarity"] = on
    cols["light_free"] = np.full(n, 0.0 if ctx.has_lights else 1.0)
    if "light_distance" in need:
        cols["light_distance"] = np.log1p(_light_distance(ctx))
    if "halo" in need:
        from ..rules.halo import in_halo_prior

        cols["halo"] = in_halo_prior(ev, ctx.sensor_size, ctx.span_us, lights=ctx.lights)
    if "ghost" in need:
        from ..rules.ghost import in_ghost_prior

        cols["ghost"] = in_ghost_prior(
            ev, ctx.sensor_size, ctx.span_us, lights=ctx.lights, cells=ctx.ghost_cells
        )
    if "spike" in need:
        cols["spike"] = ctx.on_spikes
    if "far" in need:
        from ..rules.halo import far_from_lights

        cols["far"] = far_from_lights(
            ev, ctx.sensor_size, ctx.span_us, lights=ctx.lights, exclude=ctx.ghost_cells
        )
    if "support" in need:
        cols["support"] = np.log1p(support().astype(np.float64))
    if need & {"crowded", "field"}:
        from ..rules.light_free import crowded_isolated, scatter_field

        crowded = (
            crowded_isolated(ev, ctx.sensor_size, support() <= 2, z=3.0) if n else np.zeros(0, bool)
        )
        cols["crowded"] = crowded
        if "field" in need:
            cols["field"] = (
                scatter_field(ev, ctx.sensor_size, crowded, span_us=ctx.span_us)
                if n
                else np.zeros(0, bool)
            )
    # Features of a pixel or a cell are computed once on its grid and gathered per event:
    # the same numbers, a dense window holding far more events than pixels or cells.
    pixel = y * width + x
    if need & {"rate_pixel", "balance_pixel"}:
        # gathered first: a window's events touch far fewer pixels than the sensor has
        count = np.bincount(pixel, minlength=width * height)[pixel]
        signed = np.bincount(pixel, weights=sign, minlength=width * height)[pixel]
        cols["rate_pixel"] = np.log1p(count * scale)
        cols["balance_pixel"] = signed / count  # every event's pixel has one event at least
    h, w = -(-height // _CELL), -(-width // _CELL)
    cid = (y // _CELL) * w + x // _CELL
    if need & {"rate_8", "rate_32", "rate_128", "balance_8", "balance_32"}:
        per_cell = np.bincount(cid, minlength=h * w).reshape(h, w).astype(np.float64)
        signed_cell = np.bincount(cid, weights=sign, minlength=h * w).reshape(h, w)
        for name, radius in (("8", 0), ("32", 2), ("128", 8)):
            count = _box(per_cell, radius) if radius else per_cell
            area = _box_area(h, w, radius, _CELL, (width, height))
            cols[f"rate_{name}"] = np.log1p((count / area).ravel() * scale)[cid]
            if name != "128":
                signed = _box(signed_cell, radius) if radius else signed_cell
                cols[f"balance_{name}"] = (signed / np.maximum(count, 1.0)).ravel()[cid]
    cols["rate_window"] = np.full(n, np.log1p(n / (width * height) * scale))
    if "since_pixel" in need:
        cols["since_pixel"] = np.log1p(_since_pixel(ev, width, height, window_us) / 1000.0)
    if "since_same" in need:
        same = _since_pixel(ev, width, height, window_us, by_polarity=True)
        cols["since_same"] = np.log1p(same / 1000.0)
    if "sync_64" in need:
        cols["sync_64"] = _sync(ev, x, y, on, width)
    if "centre_distance" in need:
        cols["centre_distance"] = _centre_distance(width, height)[pixel]
    cols.update(relative_features(cols, relative, window_us))
    for name in gated:  # one light test per window: all of its column, or none of it
        cols[name] = np.zeros(n) if ctx.has_lights else cols[LIGHT_FREE_FEATURES[name]]
    # one feature per row while filling (contiguous writes), returned as (n, F)
    out = np.empty((len(names), n), np.float32)
    for k, name in enumerate(names):
        out[k] = cols[name]
    return out.T


@functools.lru_cache(maxsize=4)
def _centre_distance(width: int, height: int) -> np.ndarray:
    """Each pixel's distance from the sensor's centre over half its diagonal (flat)."""
    yy, xx = np.mgrid[:height, :width]
    half = 0.5 * np.hypot(width, height)
    grid = np.hypot(xx + 0.5 - width / 2, yy + 0.5 - height / 2) / half
    grid.flags.writeable = False
    return grid.ravel()
