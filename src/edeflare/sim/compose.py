r"""Stage 2 of the simulator: fuse event streams by their intensities (PNL-ES) into pairs.

PNL-ES (Algorithm 1 of the paper) and its N-way form (Appendix B.4)
---------------------------------------------------------------------
Components :math:`i = 1..N` with event streams :math:`E_i`, linear
intensities :math:`I_i(x, y, t)` and coefficients :math:`k_i` superpose as
:math:`I_{obs} = \sum_i k_i I_i`. Differentiating :math:`\log I_{obs}` gives
the weights

.. math::

    w_i(x, y, t) = \frac{k_i I_i(x, y, t)}{\sum_j k_j I_j(x, y, t)}, \qquad \sum_i w_i = 1,

and :func:`pnl_es` keeps each event of :math:`E_i` with probability
:math:`w_i` evaluated at that event's own pixel and time, then merges the
survivors sorted by time (ties keep the order of the streams). With two
streams and :math:`k = (1, 1)` this is Algorithm 1:
:math:`w_a = I_a / (I_a + I_b)`, :math:`w_b = 1 - w_a`. Where every
effective intensity :math:`k_j I_j` is zero the weights fall back to the
shares :math:`k_i / \sum_j k_j` (their limit for equal intensities).

The coefficients are scalars or ``(H, W)`` maps (read at each event's
pixel), which covers the applications of Appendix B.5:

- **reflections** in a window: ``k = (k_T, k_R)``, the glass's
  transmissivity and reflectivity for the transmitted and reflected scenes;
- **occlusion**: ``k_bg`` a visibility mask (1 visible, 0 occluded, values in
  between for smoke or foliage) and ``k_occ = 1 - k_bg``;
- **participating media** (fog, water): depth layers :math:`z_i` with
  :math:`k_i = e^{-\alpha z_i}`.

Intensity profiles
------------------
An *intensity field* is any object with ``sample(events) -> float64 (n,)``,
the linear intensity at each event's ``(t, x, y)``:

- :class:`VideoIntensity`: a rendered video (the flare and light videos of
  stage 1, a synthetic background), linear in time between frames;
- :class:`AccumulatedIntensity`: the estimate for **recorded** events, from
  the integral sensor model :math:`L(t) = c \int E + L_0`, i.e.
  :math:`I = I_0 \exp(c\,S(x, y, t))` with :math:`S` the running sum of
  polarities (ON +1, OFF -1) since the window start, on a time grid of
  ``time_resolution_us``, smoothed over ``smoothing_px`` (Gaussian sigma) and
  clipped to ``|c S| <= max_log``; :math:`I_0` is ``base_level`` on the 8-bit
  linear scale of the rendered videos (white = 255; 30 is a dim night street,
  the median of the synthetic scenes of :mod:`edeflare.sim.background`);
- :class:`CountIntensity`: the authors' choice, each pixel's event count over
  the whole window (constant in time);
- :class:`ConstantIntensity`: a constant or a fixed ``(H, W)`` map.

Pairs (Section 3.2) and the ablation variants (Table 3)
-------------------------------------------------------
:func:`compose_pair` builds :math:`E_{ob} = E_{bg} \oplus E_f` and
:math:`E_{gt} = E_{bg} \oplus E_{light}` from one set of components. A
background event gets **one** uniform draw used in both fusions (kept in
:math:`E_{ob}` iff :math:`u < w_{bg}^{ob}`, in :math:`E_{gt}` iff
:math:`u < w_{bg}^{gt}`), so where the flare and the light are equally dark
both keep the same background events; ``independent_background=True``
thins them separately instead. Variants:

- ``"physical"``: PNL-ES as above (the paper's method);
- ``"simple"``: plain merges :math:`E_{bg} \cup E_f` and :math:`E_{bg} \cup E_{light}`;
- ``"simple+random"`` / ``"physical+random"``: the same, then every kept
  flare and light event is moved by an independent uniform jitter in
  :math:`\pm` ``jitter_us`` (clipped to the sequence) and the streams re-sorted;
- ``"no-light"``: the physical input, and the background alone as ground truth.

The full forward model (Eq. 5-6) simulates events from the intensity sums
:math:`I_{bg} + I_f` and :math:`I_{bg} + I_{light}` (:func:`forward_pair`);
it needs the background as a video, e.g. a synthetic one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from scipy import ndimage

from ..events import (
    EVENT_DTYPE,
    SensorSize,
    check_events,
    check_sensor_size,
    count_map,
    merge_events,
)
from ._validation import SimError, check_choice, check_range, dataclass_from_dict, make_rng
from .dvs import IdealSimulator, VoltmeterSimulator

__all__ = [
    "COMPONENTS",
    "VARIANTS",
    "AccumulatedIntensity",
    "AccumulationParams",
    "Components",
    "ConstantIntensity",
    "CountIntensity",
    "IntensityField",
    "VideoIntensity",
    "compose_pair",
    "forward_pair",
    "fusion_weights",
    "jitter_times",
    "keep_masks",
    "pnl_es",
    "pnl_es_sampled",
]

VARIANTS = ("physical", "simple", "simple+random", "physical+random", "no-light")
"""Composition variants of :func:`compose_pair` (the paper's ablation, Table 3)."""

COMPONENTS = ("background", "flare", "light")
"""The three event streams a pair is built from."""

# Which component intensities are needed at which stream's events.
_NEEDED = {
    "background": ("background", "flare", "light"),
    "flare": ("background", "flare"),
    "light": ("background", "light"),
}


class IntensityField(Protocol):
    """Anything that gives a linear intensity at each event's ``(t, x, y)``."""

    def sample(self, events: np.ndarray) -> np.ndarray:
        """float64 ``(n,)`` intensities, ``>= 0``."""
        ...  # pragma: no cover


# ----------------------------------------------------------------------------- fusion


def _coefficient(k: Any, events: np.ndarray, i: int) -> np.ndarray | float:
    """``k`` at the events' pixels: a scalar, or an ``(H, W)`` map indexed by ``y, x``."""
    arr = np.asarray(k, dtype=np.float64)
    if arr.ndim == 0:
        value = float(arr)
        if not (np.isfinite(value) and value >= 0):
            raise SimError(f"k[{i}] must be finite and >= 0, got {k!r}")
        return value
    if arr.ndim != 2:
        raise SimError(f"k[{i}] must be a scalar or an (H, W) map, got shape {arr.shape}")
    if not (np.isfinite(arr).all() and (arr >= 0).all()):
        raise SimError(f"k[{i}] map must be finite and >= 0")
    if events.size and (
        int(events["y"].max()) >= arr.shape[0] or int(events["x"].max()) >= arr.shape[1]
    ):
        raise SimError(
            f"k[{i}] map of shape {arr.shape} (H, W) does not cover the events' pixels; "
            "give one value per sensor pixel"
        )
    return arr[events["y"], events["x"]]


def fusion_weights(
    intensities: np.ndarray,
    index: int,
    events: np.ndarray | None = None,
    *,
    k: Sequence[Any] | None = None,
) -> np.ndarray:
    r"""Keep probabilities :math:`w_i = k_i I_i / \sum_j k_j I_j` of stream ``index``'s events.

    Parameters
    ----------
    intensities : array ``(N, n)``
        Row ``j``: the intensity of component ``j`` at each of the ``n`` events.
    index : int
        The component the events belong to.
    events : numpy.ndarray, optional
        The events themselves, needed only when a coefficient is an ``(H, W)`` map.
    k : sequence of N scalars or ``(H, W)`` maps, optional
        Coefficients (default all 1).

    Returns
    -------
    numpy.ndarray
        float64 ``(n,)`` in ``[0, 1]``. Where every ``k_j I_j`` is zero, ``k_i / sum(k)``.

    Examples
    --------
    >>> fusion_weights(np.array([[1.0, 3.0], [3.0, 1.0]]), 0).tolist()
    [0.25, 0.75]
    >>> fusion_weights(np.array([[2.0], [2.0]]), 0, k=(1.0, 3.0)).tolist()
    [0.25]
    """
    inten = np.asarray(intensities, dtype=np.float64)
    if inten.ndim != 2 or inten.shape[0] < 1:
        raise SimError(f"intensities must be (N components, n events), got shape {inten.shape}")
    n_comp, n = inten.shape
    if not 0 <= index < n_comp:
        raise SimError(f"index must be in [0, {n_comp}), got {index}")
    if n and not (np.isfinite(inten).all() and inten.min() >= 0):
        raise SimError("intensities must be finite and >= 0")
    ks: Sequence[Any] = (1.0,) * n_comp if k is None else k
    if len(ks) != n_comp:
        raise SimError(f"k must hold one coefficient per component ({n_comp}), got {len(ks)}")
    needs_events = any(np.ndim(c) != 0 for c in ks)
    if needs_events and (events is None or events.size != n):
        raise SimError("(H, W) coefficient maps need the events (one per intensity column)")
    ev = events if events is not None else np.empty(0, dtype=EVENT_DTYPE)
    coeffs = [_coefficient(c, ev, j) for j, c in enumerate(ks)]
    total = np.zeros(n)
    for c, row in zip(coeffs, inten, strict=True):
        total += c * row
    mine = coeffs[index] * inten[index]
    k_total = sum(coeffs)
    dark = total <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        w = mine / total
    if dark.any():  # every k_j I_j is zero: the k shares
        share = np.broadcast_to(coeffs[index], (n,))[dark]
        k_sum = np.broadcast_to(k_total, (n,))[dark]
        w[dark] = np.where(k_sum > 0, share / np.where(k_sum > 0, k_sum, 1.0), 0.0)
    return np.clip(w, 0.0, 1.0, out=w)


def keep_masks(
    streams: Sequence[np.ndarray],
    intensities: Sequence[np.ndarray],
    *,
    k: Sequence[Any] | None = None,
    uniforms: Sequence[np.ndarray | None] | None = None,
    rng: np.random.Generator | int | None = None,
) -> list[np.ndarray]:
    """Which events of each stream PNL-ES keeps: ``u < w`` with ``u ~ U(0, 1)`` per event.

    Parameters
    ----------
    streams : sequence of N event streams
    intensities : sequence of N arrays ``(N, n_i)``
        ``intensities[i][j]``: component ``j``'s intensity at the events of stream ``i``.
    k : sequence of N scalars or ``(H, W)`` maps, optional
    uniforms : sequence of N arrays or None, optional
        Draws to use instead of fresh ones (to couple two fusions that share a
        stream); ``None`` entries are drawn from ``rng``, stream by stream.
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    list of bool arrays
        One mask per stream.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> a = make_events([0, 1], [0, 1], [0, 0], [1, 1])
    >>> b = make_events([2], [0], [0], [0])
    >>> masks = keep_masks([a, b], [np.array([[1.0, 1.0], [0.0, 0.0]]), np.array([[1.0], [0.0]])])
    >>> [m.tolist() for m in masks]
    [[True, True], [False]]
    """
    n_streams = len(streams)
    if len(intensities) != n_streams:
        raise SimError(f"need one intensity array per stream ({n_streams}), got {len(intensities)}")
    if uniforms is not None and len(uniforms) != n_streams:
        raise SimError(
            f"uniforms must hold one entry per stream ({n_streams}), got {len(uniforms)}"
        )
    gen = make_rng(rng)
    masks = []
    for i, (events, inten) in enumerate(zip(streams, intensities, strict=True)):
        check_events(events)
        inten = np.asarray(inten, dtype=np.float64)
        if inten.shape != (n_streams, events.size):
            raise SimError(
                f"intensities[{i}] must have shape (components, events) = "
                f"({n_streams}, {events.size}), got {inten.shape}"
            )
        w = fusion_weights(inten, i, events, k=k)
        u = None if uniforms is None else uniforms[i]
        if u is None:
            u = gen.random(events.size)
        elif np.shape(u) != (events.size,):
            raise SimError(f"uniforms[{i}] must have shape ({events.size},), got {np.shape(u)}")
        masks.append(np.asarray(u) < w)
    return masks


def pnl_es_sampled(
    streams: Sequence[np.ndarray],
    intensities: Sequence[np.ndarray],
    *,
    k: Sequence[Any] | None = None,
    uniforms: Sequence[np.ndarray | None] | None = None,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """PNL-ES from intensities already sampled at the events (see :func:`keep_masks`).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> bg = make_events([0, 5], [0, 1], [0, 0], [1, 0])
    >>> fl = make_events([3], [0], [0], [1])
    >>> inten = [np.array([[1.0, 1.0], [0.0, 0.0]]), np.array([[1.0], [1e9]])]
    >>> pnl_es_sampled([bg, fl], inten, rng=0)["t"].tolist()
    [0, 3, 5]
    """
    masks = keep_masks(streams, intensities, k=k, uniforms=uniforms, rng=rng)
    kept = [s[m] for s, m in zip(streams, masks, strict=True)]
    return merge_events(*kept) if kept else np.empty(0, dtype=EVENT_DTYPE)


def pnl_es(
    streams: Sequence[np.ndarray],
    fields: Sequence[IntensityField],
    *,
    k: Sequence[Any] | None = None,
    uniforms: Sequence[np.ndarray | None] | None = None,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    r"""Fuse N event streams by their intensities: PNL-ES (Algorithm 1) and its N-way form.

    Parameters
    ----------
    streams : sequence of N event streams
        :data:`~edeflare.events.EVENT_DTYPE`, each sorted by time.
    fields : sequence of N intensity fields
        ``fields[i].sample(events)`` is component ``i``'s intensity at any events.
    k : sequence of N scalars or ``(H, W)`` maps, optional
        Coefficients :math:`k_i` (default 1).
    uniforms : sequence of N arrays or None, optional
        Draws to reuse (see :func:`keep_masks`).
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    numpy.ndarray
        The kept events, sorted by time (ties in stream order).

    Notes
    -----
    :math:`w_i = k_i I_i / \sum_j k_j I_j` at each event's pixel and time;
    an event of stream :math:`i` survives with probability :math:`w_i`.

    Examples
    --------
    Algorithm 1: a flare 9 times brighter than the background keeps about 10 %
    of the background's events.

    >>> from edeflare.events import make_events
    >>> n = 100_000
    >>> bg = make_events(np.arange(n), np.zeros(n), np.zeros(n), np.ones(n))
    >>> fused = pnl_es([bg, bg[:0]], [ConstantIntensity(1.0), ConstantIntensity(9.0)], rng=0)
    >>> round(fused.size / bg.size, 2)
    0.1

    Reflections in a shop window: transmitted scene ``T`` and reflected scene
    ``R`` with transmissivity 0.9 and reflectivity 0.1, equally bright.

    >>> fused = pnl_es([bg, bg[:0]], [ConstantIntensity(5.0)] * 2, k=(0.9, 0.1), rng=0)
    >>> round(fused.size / bg.size, 2)
    0.9

    Occlusion: a visibility mask ``k_bg`` (here the left half of a 2x1 sensor
    hidden) and ``k_occ = 1 - k_bg``; background events behind the occluder vanish.

    >>> vis = np.array([[0.0, 1.0]])
    >>> ev = make_events([0, 1], [0, 1], [0, 0], [1, 1])
    >>> out = pnl_es([ev, ev[:0]], [ConstantIntensity(1.0)] * 2, k=(vis, 1 - vis), rng=0)
    >>> out["x"].tolist()
    [1]

    Participating media: depth layers at 10 m and 40 m in fog with
    :math:`\alpha = 0.05` m⁻¹ weigh :math:`e^{-0.5} : e^{-2}`, so the far
    layer keeps about 18 % of its events.

    >>> k = (np.exp(-0.05 * 10), np.exp(-0.05 * 40))
    >>> fused = pnl_es([bg[:0], bg], [ConstantIntensity(1.0)] * 2, k=k, rng=0)
    >>> round(fused.size / bg.size, 2)
    0.18
    """
    if len(fields) != len(streams):
        raise SimError(f"need one intensity field per stream ({len(streams)}), got {len(fields)}")
    intensities = [_sample_all(fields, events) for events in streams]
    return pnl_es_sampled(streams, intensities, k=k, uniforms=uniforms, rng=rng)


def _sample_all(fields: Sequence[IntensityField], events: np.ndarray) -> np.ndarray:
    rows = []
    for j, field in enumerate(fields):
        values = np.asarray(field.sample(events), dtype=np.float64)
        if values.shape != (events.size,):
            raise SimError(
                f"intensity field {j} returned shape {values.shape} for {events.size} events"
            )
        rows.append(values)
    return np.stack(rows) if rows else np.empty((0, events.size))


# ----------------------------------------------------------------------- intensity fields


class ConstantIntensity:
    """A constant intensity, or a fixed ``(H, W)`` map read at each event's pixel.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ConstantIntensity(np.array([[1.0, 7.0]])).sample(make_events([0], [1], [0], [1])).tolist()
    [7.0]
    """

    def __init__(self, value: float | np.ndarray) -> None:
        arr = np.asarray(value, dtype=np.float64)
        if arr.ndim not in (0, 2) or not (np.isfinite(arr).all() and (arr >= 0).all()):
            raise SimError(
                f"value must be a finite number >= 0 or an (H, W) map of them, got {value!r}"
            )
        self.value = arr

    def sample(self, events: np.ndarray) -> np.ndarray:
        """The value at each event."""
        if self.value.ndim == 0:
            return np.full(events.size, float(self.value))
        return self.value[events["y"], events["x"]].astype(np.float64)


class VideoIntensity:
    """An intensity video held in memory, sampled linearly in time between frames.

    Parameters
    ----------
    times_us : array ``(T,)`` of int
        Increasing frame times.
    frames : array ``(T, H, W)``
        Linear intensities ``>= 0``. Before the first frame and after the last,
        the nearest frame holds.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> video = VideoIntensity([0, 100], np.array([[[0.0]], [[10.0]]]))
    >>> video.sample(make_events([25, 200], [0, 0], [0, 0], [1, 1])).tolist()
    [2.5, 10.0]
    """

    def __init__(self, times_us: Any, frames: Any) -> None:
        t = np.asarray(times_us, dtype=np.int64)
        f = np.asarray(frames)
        if t.ndim != 1 or t.size == 0 or (np.diff(t) <= 0).any():
            raise SimError("times_us must be a non-empty, strictly increasing 1-D array")
        if f.ndim != 3 or f.shape[0] != t.size:
            raise SimError(
                f"frames must be (T, H, W) with T = {t.size} frame times, got shape {f.shape}"
            )
        if not (np.isfinite(f).all() and (f >= 0).all()):
            raise SimError("frames must be finite and >= 0")
        self.times_us = t
        self.frames = f

    def sample(self, events: np.ndarray) -> np.ndarray:
        """Intensity at each event, linear between the frames around its time."""
        t = events["t"]
        hi = np.clip(np.searchsorted(self.times_us, t, side="left"), 0, self.times_us.size - 1)
        lo = np.maximum(hi - 1, 0)
        t_lo, t_hi = self.times_us[lo], self.times_us[hi]
        span = np.where(t_hi > t_lo, t_hi - t_lo, 1)
        frac = np.clip((t - t_lo) / span, 0.0, 1.0)
        y, x = events["y"], events["x"]
        a = self.frames[lo, y, x].astype(np.float64)
        b = self.frames[hi, y, x].astype(np.float64)
        return a + frac * (b - a)


@dataclass(frozen=True)
class AccumulationParams:
    """Parameters of :class:`AccumulatedIntensity` (see the module docstring).

    Parameters
    ----------
    contrast : float
        :math:`c`, the log-intensity step of one event (a typical DVS threshold).
    base_level : float
        :math:`I_0`, the intensity of a pixel whose polarities sum to zero
        (8-bit linear scale of the rendered videos, white = 255).
    time_resolution_us : int
        Step of the time grid the running sums are kept on (linear in between).
    smoothing_px : float
        Gaussian sigma of the spatial smoothing of the running sums (0: none).
    max_log : float
        Clip of :math:`|c S|`, so a noisy pixel cannot run away.

    Examples
    --------
    >>> AccumulationParams.from_dict({"base_level": 20}).base_level
    20
    """

    contrast: float = 0.2
    base_level: float = 30.0
    time_resolution_us: int = 1000
    smoothing_px: float = 1.0
    max_log: float = 3.0

    def __post_init__(self) -> None:
        check_range("contrast", self.contrast, 0, lo_open=True)
        check_range("base_level", self.base_level, 0, lo_open=True)
        if isinstance(self.time_resolution_us, bool) or not isinstance(
            self.time_resolution_us, (int, np.integer)
        ):
            raise SimError(f"time_resolution_us must be an int, got {self.time_resolution_us!r}")
        check_range("time_resolution_us", self.time_resolution_us, 1)
        check_range("smoothing_px", self.smoothing_px, 0)
        check_range("max_log", self.max_log, 0, lo_open=True)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> AccumulationParams:
        """Build from a mapping; unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return dataclasses.asdict(self)


def _window(t_start_us: int, t_end_us: int) -> tuple[int, int]:
    t0, t1 = int(t_start_us), int(t_end_us)
    if t1 <= t0:
        raise SimError(f"the window must have t_end_us > t_start_us, got [{t0}, {t1})")
    return t0, t1


class AccumulatedIntensity:
    r"""Intensity of a recorded event stream from the integral sensor model.

    :math:`I(x, y, t) = I_0 \exp(\mathrm{clip}(c\,\tilde S(x, y, t), \pm m))`,
    with :math:`S` the running polarity sum since ``t_start_us`` on a grid of
    ``time_resolution_us`` (linear in between) and :math:`\tilde S` its
    Gaussian smoothing; parameters in :class:`AccumulationParams`. The grid
    holds ``(ceil(span / resolution) + 1, H, W)`` float32 values.

    Parameters
    ----------
    events : numpy.ndarray
        The stream the intensity is estimated from.
    sensor_size : (width, height)
    t_start_us, t_end_us : int
        The window; the running sum starts at zero at ``t_start_us``.
    params : AccumulationParams, optional

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([100, 1500, 2500], [0, 0, 0], [0, 0, 0], [1, 1, 1])
    >>> est = AccumulatedIntensity(ev, (1, 1), 0, 3000, AccumulationParams(smoothing_px=0))
    >>> (est.sample(make_events([0, 2000, 2999], [0] * 3, [0] * 3, [1] * 3)) / 30).round(3).tolist()
    [1.0, 1.492, 1.822]
    """

    def __init__(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        t_start_us: int,
        t_end_us: int,
        params: AccumulationParams | None = None,
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        check_events(events, self.sensor_size)
        self.params = params or AccumulationParams()
        self.t_start_us, self.t_end_us = _window(t_start_us, t_end_us)
        p = self.params
        width, height = self.sensor_size
        step = int(p.time_resolution_us)
        n_bins = -(-(self.t_end_us - self.t_start_us) // step)
        inside = events[(events["t"] >= self.t_start_us) & (events["t"] < self.t_end_us)]
        b = (inside["t"] - self.t_start_us) // step
        flat = (b * height + inside["y"].astype(np.int64)) * width + inside["x"]
        sign = np.where(inside["p"] > 0, 1.0, -1.0)
        counts = np.bincount(flat, weights=sign, minlength=n_bins * height * width)
        grid = np.zeros((n_bins + 1, height, width), dtype=np.float32)
        np.cumsum(counts.reshape(n_bins, height, width), axis=0, out=grid[1:])
        if p.smoothing_px > 0:
            for i in range(1, n_bins + 1):
                ndimage.gaussian_filter(grid[i], p.smoothing_px, output=grid[i], mode="nearest")
        grid *= np.float32(p.contrast)
        np.clip(grid, -p.max_log, p.max_log, out=grid)
        self.log_intensity = grid
        """``(bins + 1, H, W)`` float32 :math:`\\log(I / I_0)` at the grid times."""

    @property
    def times_us(self) -> np.ndarray:
        """Times of the grid planes."""
        n = self.log_intensity.shape[0]
        step = self.params.time_resolution_us
        return self.t_start_us + step * np.arange(n, dtype=np.int64)

    def sample(self, events: np.ndarray) -> np.ndarray:
        """Estimated intensity at each event (times outside the window clamp to its ends)."""
        step = self.params.time_resolution_us
        n_planes = self.log_intensity.shape[0]
        pos = np.clip((events["t"] - self.t_start_us) / step, 0.0, n_planes - 1.0)
        lo = np.minimum(pos.astype(np.int64), n_planes - 2)  # n_planes >= 2
        hi = lo + 1
        frac = pos - lo
        y, x = events["y"], events["x"]
        a = self.log_intensity[lo, y, x].astype(np.float64)
        b = self.log_intensity[hi, y, x].astype(np.float64)
        return self.params.base_level * np.exp(a + frac * (b - a))


class CountIntensity:
    """The authors' intensity estimate: each pixel's event count over the whole window.

    Parameters
    ----------
    events : numpy.ndarray
    sensor_size : (width, height)
    scale : float
        Multiplies the counts.
    smoothing_px : float
        Gaussian sigma of a spatial smoothing of the counts (0: none, as the authors).
    floor : float
        Added to every pixel (0 as the authors: a pixel without events has intensity 0).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 9, 20], [0, 0, 1], [0, 0, 0], [1, 0, 1])
    >>> CountIntensity(ev, (2, 1)).sample(ev).tolist()
    [2.0, 2.0, 1.0]
    """

    def __init__(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        *,
        scale: float = 1.0,
        smoothing_px: float = 0.0,
        floor: float = 0.0,
    ) -> None:
        width, height = check_sensor_size(sensor_size)
        check_events(events, (width, height))
        check_range("scale", scale, 0, lo_open=True)
        check_range("smoothing_px", smoothing_px, 0)
        check_range("floor", floor, 0)
        counts = count_map(events, (width, height)) * scale
        counts = counts.astype(np.float64)
        if smoothing_px > 0:
            counts = ndimage.gaussian_filter(counts, smoothing_px, mode="nearest")
        self.counts = counts + floor
        """``(H, W)`` intensity map."""

    def sample(self, events: np.ndarray) -> np.ndarray:
        """The map at each event's pixel."""
        return self.counts[events["y"], events["x"]]


# ------------------------------------------------------------------------------ pairs


@dataclass(frozen=True)
class Components:
    """The three streams of one sample and their intensities at each other's events.

    Parameters
    ----------
    events : mapping ``{"background", "flare", "light"} -> stream``
    intensity : mapping ``component -> {stream -> (n,) array}``
        ``intensity[c][s]``: component ``c``'s intensity at the events of stream
        ``s``. Needed: the background's at all three streams, the flare's at the
        background and flare events, the light's at the background and light events.
    t_start_us, t_end_us : int
        The sequence span (jitter is clipped to it).
    """

    events: Mapping[str, np.ndarray]
    intensity: Mapping[str, Mapping[str, np.ndarray]]
    t_start_us: int
    t_end_us: int

    def __post_init__(self) -> None:
        for name in COMPONENTS:
            if name not in self.events:
                raise SimError(f"components need a {name!r} stream; got {sorted(self.events)}")
            check_events(self.events[name])
        for comp, streams in _NEEDED.items():
            for stream in streams:
                values = self.intensity.get(comp, {}).get(stream)
                n = self.events[stream].size
                if values is None or np.shape(values) != (n,):
                    raise SimError(
                        f"intensity[{comp!r}][{stream!r}] must be an array of {n} values "
                        f"(the {comp} intensity at the {stream} events)"
                    )
        _window(self.t_start_us, self.t_end_us)

    @classmethod
    def from_fields(
        cls,
        events: Mapping[str, np.ndarray],
        fields: Mapping[str, IntensityField],
        t_start_us: int,
        t_end_us: int,
    ) -> Components:
        """Sample three intensity fields at the events that need them.

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> ev = make_events([0], [0], [0], [1])
        >>> c = Components.from_fields(
        ...     {"background": ev, "flare": ev, "light": ev[:0]},
        ...     {"background": ConstantIntensity(1.0), "flare": ConstantIntensity(3.0),
        ...      "light": ConstantIntensity(0.0)}, 0, 100)
        >>> c.intensity["flare"]["background"].tolist()
        [3.0]
        """
        intensity = {
            comp: {s: np.asarray(fields[comp].sample(events[s]), np.float64) for s in streams}
            for comp, streams in _NEEDED.items()
        }
        return cls(events, intensity, t_start_us, t_end_us)

    def samples(self, streams: Sequence[str]) -> list[np.ndarray]:
        """Intensity arrays ``(N, n_i)`` of the components ``streams`` at each one's events."""
        return [np.stack([self.intensity[c][s] for c in streams]) for s in streams]


def jitter_times(
    events: np.ndarray,
    jitter_us: float,
    t_start_us: int,
    t_end_us: int,
    *,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """A copy with each timestamp moved by ``U(-jitter_us, +jitter_us)``, clipped, re-sorted.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 50, 99], [0, 1, 2], [0] * 3, [1] * 3)
    >>> out = jitter_times(ev, 20, 0, 100, rng=0)
    >>> bool((np.diff(out["t"]) >= 0).all()), int(out["t"].min()) >= 0, int(out["t"].max()) < 100
    (True, True, True)
    """
    check_range("jitter_us", jitter_us, 0)
    t0, t1 = _window(t_start_us, t_end_us)
    gen = make_rng(rng)
    out = events.copy()
    shift = np.rint(gen.uniform(-jitter_us, jitter_us, events.size)).astype(np.int64)
    out["t"] = np.clip(events["t"] + shift, t0, t1 - 1)
    return out[np.argsort(out["t"], kind="stable")]


def compose_pair(
    components: Components,
    variant: str = "physical",
    *,
    jitter_us: float = 1000.0,
    independent_background: bool = False,
    rng: np.random.Generator | int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    r"""The input and ground-truth streams :math:`(E_{ob}, E_{gt})` of one sample.

    Parameters
    ----------
    components : Components
        Background, flare and light events and their intensities.
    variant : str
        One of :data:`VARIANTS` (see the module docstring).
    jitter_us : float
        Half-width of the uniform jitter of the ``+random`` variants.
    independent_background : bool
        Thin the background separately for the input and the ground truth
        (default: one draw per background event, shared).
    rng : numpy.random.Generator or int, optional
        Draws, in order: background, flare, light uniforms (physical variants),
        then a second background draw (independent), then the jitters.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        :math:`E_{ob} = E_{bg} \oplus E_f` and :math:`E_{gt} = E_{bg} \oplus E_{light}`.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> bg = make_events([0, 10], [0, 5], [0, 0], [1, 0])
    >>> fl = make_events([5], [0], [0], [1])
    >>> c = Components.from_fields(
    ...     {"background": bg, "flare": fl, "light": fl[:0]},
    ...     {"background": ConstantIntensity(10.0),
    ...      "flare": ConstantIntensity(np.array([[1e9, 0, 0, 0, 0, 0]])),
    ...      "light": ConstantIntensity(0.0)}, 0, 20)
    >>> ob, gt = compose_pair(c, rng=0)
    >>> ob["t"].tolist(), gt["t"].tolist()
    ([5, 10], [0, 10])
    """
    check_choice("variant", variant, VARIANTS)
    gen = make_rng(rng)
    ev = components.events
    bg, fl, li = ev["background"], ev["flare"], ev["light"]
    if variant.startswith("simple"):
        ob_parts, gt_parts = [bg, fl], [bg, li]
    else:
        u_bg = gen.random(bg.size)
        u_fl = gen.random(fl.size)
        u_li = gen.random(li.size)
        m_bg_ob, m_fl = keep_masks(
            [bg, fl], components.samples(["background", "flare"]), uniforms=[u_bg, u_fl]
        )
        u_bg_gt = gen.random(bg.size) if independent_background else u_bg
        m_bg_gt, m_li = keep_masks(
            [bg, li], components.samples(["background", "light"]), uniforms=[u_bg_gt, u_li]
        )
        ob_parts = [bg[m_bg_ob], fl[m_fl]]
        gt_parts = [bg, li[:0]] if variant == "no-light" else [bg[m_bg_gt], li[m_li]]
    if variant.endswith("+random"):
        t0, t1 = components.t_start_us, components.t_end_us
        ob_parts[1] = jitter_times(ob_parts[1], jitter_us, t0, t1, rng=gen)
        gt_parts[1] = jitter_times(gt_parts[1], jitter_us, t0, t1, rng=gen)
    return merge_events(*ob_parts), merge_events(*gt_parts)


def forward_pair(
    frames: Iterable[tuple[int, np.ndarray, np.ndarray, np.ndarray]],
    simulator_ob: VoltmeterSimulator | IdealSimulator,
    simulator_gt: VoltmeterSimulator | IdealSimulator,
) -> tuple[np.ndarray, np.ndarray]:
    r"""The full forward model (Eq. 5-6): the events of the intensity sums.

    Parameters
    ----------
    frames : iterable of ``(t_us, background, flare, light)``
        Linear intensity frames ``(H, W)`` on one scale.
    simulator_ob, simulator_gt : event simulators
        Two simulators of the same camera (e.g. from
        :func:`edeflare.sim.camera.sensor_pair`).

    Examples
    --------
    >>> from edeflare.sim.dvs import IdealParams, IdealSimulator
    >>> p = IdealParams(c_on=0.5, c_off=0.5)
    >>> video = [(0, np.ones((1, 1)), np.zeros((1, 1)), np.zeros((1, 1))),
    ...          (1000, np.ones((1, 1)), np.full((1, 1), 9.0), np.zeros((1, 1)))]
    >>> ob, gt = forward_pair(video, IdealSimulator((1, 1), p), IdealSimulator((1, 1), p))
    >>> ob.size, gt.size
    (3, 0)
    """
    from .pair import EventRecorder, run_frames  # the loop's module builds on this one

    def bg64(f: Mapping[str, np.ndarray]) -> np.ndarray:
        return np.asarray(f["background"], dtype=np.float64)

    ob = EventRecorder(simulator_ob, lambda f: bg64(f) + f["flare"])
    gt = EventRecorder(simulator_gt, lambda f: bg64(f) + f["light"])
    video = ((t, {"background": b, "flare": f, "light": lt}) for t, b, f, lt in frames)
    run_frames(video, [ob, gt])
    return ob.events(), gt.events()
