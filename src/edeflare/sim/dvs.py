r"""Event simulators fed one intensity frame at a time: DVS-Voltmeter and an ideal log model.

Both take linear intensity frames ``(H, W)`` on the 8-bit scale (255 = white
of an 8-bit frame; values may exceed it) with integer timestamps in
microseconds, keep per-pixel state between calls, and return the events of
each frame interval as :data:`edeflare.events.EVENT_DTYPE`, sorted by time.
The first frame only initialises the state. Both are seeded and vectorised
(compiled loops over pixels, parallel over pixel ranges); their output does not
depend on the number of threads.

**Cold or warm start.** By default (``warm_start=False``, the original programs'
behaviour) every pixel starts exactly at its reference level, so a pixel whose log
intensity changes by less than one threshold over the simulated span never fires.
A real sensor has been running long before any recording starts, and a pixel under
a steady change (a slowly drifting camera, the slope of a lamp's halo) sits anywhere
between its reference and the threshold it moves towards, uniformly: that change fires
it at its long-run rate from the first instant. ``warm_start=True`` starts each pixel
so, by the direction it moves in over the first frame interval: DVS-Voltmeter's carried
residual uniform in ``(0, 1)`` threshold units where its drift (the light's change and
the leak) is positive, ``(-1, 0)`` where it is negative and ``(-1, 1)`` where it is 0;
the ideal model's log intensity over its reference uniform in ``(0, C_on)`` where the
light rises, ``(-C_off, 0)`` where it falls and ``(-C_off, C_on)`` where it holds. A rise of
``d`` (log units) over a span then fires ``d / C_on`` events per pixel on average, the
long-run rate, where a cold start fires ``floor(d / C_on)``. It matters where change is
slow: the far scattered light of a steady lamp, a dim street under a drifting camera.

DVS-Voltmeter (Lin et al., ECCV 2022)
-------------------------------------
Between frames with intensities :math:`L_p` and :math:`L_n` (step
:math:`\Delta t` µs) a pixel's voltage is Brownian motion with drift

.. math::

    \bar L = \tfrac12 (L_p + L_n), \qquad
    \mu = \frac{k_1 (L_n - L_p) / \Delta t}{\bar L + k_2} + k_4 + k_5 \bar L, \qquad
    \sigma = \frac{k_3 \sqrt{\bar L}}{\bar L + k_2} + k_6 .

ON and OFF thresholds are 1. With the residual :math:`r` carried from the last
step the barriers are :math:`A = 1 - r` (ON) and :math:`B = 1 + r` (OFF); the
ON barrier is hit first with probability

.. math::

    P_{on} = \frac{e^{2\mu B/\sigma^2} - 1}{e^{2\mu B/\sigma^2} - e^{-2\mu A/\sigma^2}}

(evaluated with ``expm1`` in overflow-free forms; :math:`B/(A+B)` at
:math:`\mu = 0`). After drawing the polarity, the first-passage time
:math:`\tau` towards the drift is inverse Gaussian with mean
:math:`\varepsilon/|\mu|` and shape :math:`\varepsilon^2/\sigma^2`
(:math:`\varepsilon = A` or :math:`B`). Against the drift the original draws
:math:`X` from a normal truncated to :math:`X^2 \ge T = 4\varepsilon|\mu|/\sigma^2`
and keeps the smaller root of the inverse-Gaussian transform,
:math:`\tau = M/g` with :math:`M = \varepsilon/|\mu|`, :math:`b = 4X^2/T`,
:math:`g = (b - 2 + \sqrt{b(b-4)})/2` (``against_drift="original"``, the
default, which reproduces the original's output distributions); the exact
conditioned law :math:`\mathrm{IG}(\varepsilon/|\mu|, \varepsilon^2/\sigma^2)`
is available as ``against_drift="exact"``. If :math:`t + \tau` falls before
the next frame an event is emitted there, :math:`r = 0` and sampling repeats
from the event time; otherwise :math:`r \mathrel{+}= \pm\varepsilon\,
(t_n - t)/\tau`. Event times are rounded to whole µs (half to even).

Calibrated parameters: :data:`DVS346_K` and :data:`DVS240_K`.

Differences from the original program (which are all at the edges): no NaN is
possible (the original's truncated-normal step collapses when
:math:`4\varepsilon|\mu|/\sigma^2 \gtrsim 70`); at exactly :math:`\mu = 0`
:math:`P_{on} = B/(A+B)` (the continuous limit) instead of 1/2, and the
driftless passage time is Lévy with scale :math:`\varepsilon^2/\sigma^2` (the
original's has twice that scale); frame times are kept in float64 (the
original's float32 start times lose precision after 16.8 s).

Ideal log-intensity simulator (ESIM-like)
-----------------------------------------
Each pixel tracks :math:`\ell = \log(L + \epsilon)`, interpolated linearly
between frames, and a reference level :math:`\ell_r`. Every crossing of
:math:`\ell_r + C_{on}` (ON) or :math:`\ell_r - C_{off}` (OFF) emits an event at
the interpolated time and moves the reference by one threshold. Thresholds are
per pixel (mean and mismatch sigma); an event within the refractory period of
the pixel's last emitted event is dropped (the reference still moves, as in
ESIM). Optional background-activity noise and hot pixels add Poisson events of
random polarity that do not touch the pixel state. Without noise the output is
deterministic, so a log ramp gives exactly ``floor(delta / C)`` events.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from ..events import EVENT_DTYPE, SensorSize, check_sensor_size
from ._buffer import new_buffers, to_events
from ._esim import esim_frame
from ._rng import seed_states
from ._validation import SimError, check_choice, check_range, dataclass_from_dict, make_rng
from ._voltmeter import drifts, voltmeter_frame

__all__ = [
    "DVS240_K",
    "DVS346_K",
    "IdealParams",
    "IdealSimulator",
    "VoltmeterParams",
    "VoltmeterSimulator",
    "draw_thresholds",
    "make_simulator",
    "simulate_frames",
]

DVS346_K = (5.265, 20.0, 1e-4, 1e-7, 5e-9, 1e-5)
"""DVS-Voltmeter's calibrated ``k1..k6`` for the DAVIS346."""
DVS240_K = (4.424, 23.0, 2e-4, 1e-7, 5e-8, 1e-5)
"""DVS-Voltmeter's calibrated ``k1..k6`` for the DAVIS240."""

_AGAINST = ("original", "exact")
_FRAME_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)


@dataclass(frozen=True)
class VoltmeterParams:
    """Parameters of the DVS-Voltmeter model.

    Parameters
    ----------
    k : tuple of 6 floats
        ``k1..k6`` (default :data:`DVS346_K`). ``k1`` sets the contrast
        sensitivity (the paper draws it per sample), ``k2`` the dark offset,
        ``k3``/``k6`` the diffusion, ``k4``/``k5`` the leak drift.
    against_drift : {"original", "exact"}
        First-passage sampler against the drift (see the module docstring).

    Examples
    --------
    >>> VoltmeterParams.from_dict({"k": [5.0, 20, 1e-4, 1e-7, 5e-9, 1e-5]}).k[0]
    5.0
    """

    k: tuple[float, ...] = DVS346_K
    against_drift: str = "original"

    def __post_init__(self) -> None:
        try:
            k = tuple(float(v) for v in self.k)
        except (TypeError, ValueError):
            raise SimError(f"k must be six numbers k1..k6, got {self.k!r}") from None
        if len(k) != 6 or not all(math.isfinite(v) and v >= 0 for v in k) or k[1] <= 0:
            raise SimError(f"k must be six finite numbers >= 0 with k2 > 0, got {self.k!r}")
        object.__setattr__(self, "k", k)
        check_choice("against_drift", self.against_drift, _AGAINST)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> VoltmeterParams:
        """Build from a mapping (e.g. parsed JSON); unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (lists for tuples)."""
        return {"k": list(self.k), "against_drift": self.against_drift}


@dataclass(frozen=True)
class IdealParams:
    """Parameters of the ideal log-intensity simulator.

    Parameters
    ----------
    c_on, c_off : float
        Mean ON / OFF contrast thresholds (log units).
    c_sigma : float
        Per-pixel threshold mismatch (standard deviation, log units).
    c_min : float
        Floor of a pixel's threshold after mismatch.
    refractory_us : float
        Minimum time between two emitted events of one pixel.
    log_eps : float
        Offset inside the log, ``log(L + log_eps)`` (8-bit units), so 0 is finite.
    noise_rate_hz : float
        Background-activity noise events per pixel per second.
    hot_pixel_fraction : float
        Fraction of pixels that are hot.
    hot_pixel_rate_hz : float
        Events per second of each hot pixel.

    Examples
    --------
    >>> IdealParams(c_on=0.3).c_off
    0.2
    """

    c_on: float = 0.2
    c_off: float = 0.2
    c_sigma: float = 0.0
    c_min: float = 0.01
    refractory_us: float = 0.0
    log_eps: float = 1.0
    noise_rate_hz: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_rate_hz: float = 1000.0

    def __post_init__(self) -> None:
        check_range("c_on", self.c_on, 0, lo_open=True)
        check_range("c_off", self.c_off, 0, lo_open=True)
        check_range("c_sigma", self.c_sigma, 0)
        check_range("c_min", self.c_min, 0, lo_open=True)
        check_range("refractory_us", self.refractory_us, 0)
        check_range("log_eps", self.log_eps, 0, lo_open=True)
        check_range("noise_rate_hz", self.noise_rate_hz, 0)
        check_range("hot_pixel_fraction", self.hot_pixel_fraction, 0, 1)
        check_range("hot_pixel_rate_hz", self.hot_pixel_rate_hz, 0)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> IdealParams:
        """Build from a mapping (e.g. parsed JSON); unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return dataclasses.asdict(self)


def draw_thresholds(
    sensor_size: SensorSize,
    params: IdealParams | None = None,
    *,
    rng: np.random.Generator | int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel ON and OFF thresholds ``(H, W)``: mean plus mismatch, floored at ``c_min``.

    Draw them once per sensor and pass them to every :class:`IdealSimulator`
    that models the same camera (e.g. the flare and light videos of a sample).

    Examples
    --------
    >>> on, off = draw_thresholds((4, 3), IdealParams(c_sigma=0.03), rng=0)
    >>> on.shape, bool((on > 0.1).all())
    ((3, 4), True)
    """
    width, height = check_sensor_size(sensor_size)
    params = params or IdealParams()
    gen = make_rng(rng)
    maps = []
    for mean in (params.c_on, params.c_off):
        c = np.full((height, width), mean, dtype=np.float64)
        if params.c_sigma > 0:
            c += params.c_sigma * gen.standard_normal((height, width))
        maps.append(np.maximum(c, params.c_min))
    return maps[0], maps[1]


@numba.njit(cache=True, nogil=True)
def _count_invalid(flat):  # pragma: no cover - compiled
    """Pixels that are negative, NaN or infinite (a branch-free, vectorised count)."""
    bad = 0
    top = np.finfo(flat.dtype).max
    for i in range(np.uint64(flat.size)):
        v = flat[i]
        bad += np.int64(not ((v >= 0) & (v <= top)))
    return bad


class _FrameSimulator:
    """Frame bookkeeping shared by both simulators: validation, times, first frame."""

    def __init__(self, sensor_size: SensorSize) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        self.t_us: int | None = None
        """Timestamp of the last frame fed (``None`` before the first)."""

    def _frame(self, frame: Any, t_us: Any) -> tuple[np.ndarray, int]:
        width, height = self.sensor_size
        arr = np.asarray(frame)
        if arr.shape != (height, width):
            raise SimError(
                f"frame must have shape (height, width) = ({height}, {width}), got {arr.shape}"
            )
        if arr.dtype.kind not in "uif" or arr.dtype == np.bool_:
            raise SimError(f"frame must hold real intensities, got dtype {arr.dtype}")
        if not any(arr.dtype == d for d in _FRAME_DTYPES):
            arr = arr.astype(np.float64)
        flat = np.ascontiguousarray(arr).reshape(-1)
        if flat.dtype.kind == "f":
            bad = int(_count_invalid(flat))
            if bad:
                raise SimError(
                    f"frame at t={t_us} has {bad} negative, NaN or infinite pixel(s); "
                    "intensities must be finite and >= 0"
                )
        if isinstance(t_us, bool) or not isinstance(t_us, (int, np.integer)):
            raise SimError(f"t_us must be an int (microseconds), got {t_us!r}")
        t = int(t_us)
        if self.t_us is not None and t <= self.t_us:
            raise SimError(f"frame times must increase: got t_us={t} after {self.t_us}")
        return flat, t

    def feed(self, frame: Any, t_us: int) -> np.ndarray:
        """Take the next frame; return the events of ``(previous frame, t_us]``."""
        flat, t = self._frame(frame, t_us)
        if self.t_us is None:
            self._init(flat)
            self.t_us = t
            return np.empty(0, dtype=EVENT_DTYPE)
        events = self._interval(flat, float(self.t_us), float(t))
        self.t_us = t
        return events

    def _init(self, flat: np.ndarray) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _interval(self, flat: np.ndarray, t0: float, t1: float) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError


class VoltmeterSimulator(_FrameSimulator):
    """DVS-Voltmeter, streaming and seeded (model in the module docstring).

    Parameters
    ----------
    sensor_size : (width, height)
    params : VoltmeterParams, optional
        Defaults to the DAVIS346 calibration.
    rng : numpy.random.Generator or int, optional
        Seed of the per-pixel random streams (one 64-bit draw; with ``warm_start``,
        then the starting residuals).
    warm_start : bool
        Start each pixel's residual uniformly between 0 and the barrier its drift over
        the first interval moves it towards instead of at 0 (see the module docstring).

    Examples
    --------
    >>> sim = VoltmeterSimulator((4, 2), rng=0, warm_start=True)
    >>> _ = sim.feed(np.full((2, 4), 40.0), 0)
    >>> _ = sim.feed(np.full((2, 4), 40.1), 1)   # rising: residuals in (0, 1)
    >>> bool((sim.residual > 0).all() and (sim.residual < 1).all())
    True
    >>> sim = VoltmeterSimulator((4, 2), rng=0)
    >>> sim.feed(np.full((2, 4), 40.0), 0).size
    0
    >>> ev = sim.feed(np.full((2, 4), 80.0), 1000)  # k1 * 40 / (60 + k2) = 2.6 thresholds
    >>> int(ev.size), bool((ev["p"] == 1).all())
    (16, True)
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        params: VoltmeterParams | None = None,
        *,
        rng: np.random.Generator | int | None = None,
        warm_start: bool = False,
    ) -> None:
        super().__init__(sensor_size)
        if params is not None and not isinstance(params, VoltmeterParams):
            raise SimError(f"params must be VoltmeterParams, got {type(params).__name__}")
        self.params = params or VoltmeterParams()
        width, height = self.sensor_size
        n = width * height
        gen = make_rng(rng)
        seed = int(gen.integers(0, 2**63))
        self._state = seed_states(n, seed)
        self._residual = np.zeros(n, dtype=np.float64)
        # the warm start's draws, taken at the first interval (None: cold, or done)
        self._warm = gen.random(n) if warm_start else None
        # The previous frame, stored exactly in float32 while frames are uint8, uint16 or
        # float32 (less memory traffic in the per-pixel pass), in float64 once one is float64.
        self._prev = np.zeros(n, dtype=np.float32)
        self._mark = np.empty(n, dtype=np.bool_)
        self._k = np.array(self.params.k, dtype=np.float64)
        self._exact = self.params.against_drift == "exact"
        self._buffers = list(new_buffers())

    @property
    def residual(self) -> np.ndarray:
        """The carried residual voltage ``(H, W)`` in threshold units (a copy)."""
        width, height = self.sensor_size
        return self._residual.reshape(height, width).copy()

    def _init(self, flat: np.ndarray) -> None:
        if flat.dtype == np.float64:
            self._prev = self._prev.astype(np.float64)
        self._prev[:] = flat

    def _interval(self, flat: np.ndarray, t0: float, t1: float) -> np.ndarray:
        if flat.dtype == np.float64 and self._prev.dtype != np.float64:
            self._prev = self._prev.astype(np.float64)
        if self._warm is not None:  # by the sign of each pixel's drift
            drift = drifts(self._prev, flat, t0, t1, self._k)
            self._residual[:] = _warm_offsets(self._warm, drift, 1.0, 1.0)
            self._warm = None
        t, x, y, p, *self._buffers = voltmeter_frame(
            self._prev, flat, self._residual, self._state, t0, t1, self._k, self._exact,
            self._mark, *self._buffers, self.sensor_size[0],
        )  # fmt: skip
        return to_events(t, x, y, p)


class IdealSimulator(_FrameSimulator):
    """Ideal log-intensity (ESIM-like) simulator, streaming (model in the module docstring).

    Parameters
    ----------
    sensor_size : (width, height)
    params : IdealParams, optional
    thresholds : (on, off) arrays ``(H, W)``, optional
        Per-pixel thresholds (see :func:`draw_thresholds`); drawn from ``rng``
        when omitted.
    rng : numpy.random.Generator or int, optional
        Seeds the thresholds (when drawn here), hot pixels, the warm start and noise.
    warm_start : bool
        Start each pixel's log intensity uniformly between its reference and the
        threshold its first change moves it towards instead of on the reference (see
        the module docstring).

    Examples
    --------
    A rise of 0.05 in log intensity, a tenth of a threshold, fires nothing from a cold
    start, and a tenth of the pixels from a warm one:

    >>> flat = np.full((100, 100), 10.0)
    >>> def fired(warm):
    ...     sim = IdealSimulator((100, 100), IdealParams(c_on=0.5, c_off=0.5), rng=0,
    ...                          warm_start=warm)
    ...     _ = sim.feed(flat, 0)
    ...     return sim.feed(np.exp(np.log(flat + 1.0) + 0.05) - 1.0, 1000).size
    >>> fired(False), 900 < fired(True) < 1100
    (0, True)
    >>> sim = IdealSimulator((1, 1), IdealParams(c_on=0.5, c_off=0.5, log_eps=1e-9))
    >>> _ = sim.feed(np.array([[10.0]]), 0)
    >>> ev = sim.feed(np.array([[10.0 * np.exp(1.2)]]), 1000)
    >>> ev["t"].tolist(), ev["p"].tolist()
    ([417, 833], [1, 1])
    """

    def __init__(
        self,
        sensor_size: SensorSize,
        params: IdealParams | None = None,
        *,
        thresholds: tuple[np.ndarray, np.ndarray] | None = None,
        rng: np.random.Generator | int | None = None,
        warm_start: bool = False,
    ) -> None:
        super().__init__(sensor_size)
        self.warm_start = bool(warm_start)
        if params is not None and not isinstance(params, IdealParams):
            raise SimError(f"params must be IdealParams, got {type(params).__name__}")
        self.params = params or IdealParams()
        width, height = self.sensor_size
        n = width * height
        self._rng = make_rng(rng)
        if thresholds is None:
            thresholds = draw_thresholds(self.sensor_size, self.params, rng=self._rng)
        c_on, c_off = (np.asarray(c, dtype=np.float64) for c in thresholds)
        for name, c in (("on", c_on), ("off", c_off)):
            if c.shape != (height, width) or not (np.isfinite(c).all() and (c > 0).all()):
                raise SimError(
                    f"{name} thresholds must be finite, > 0 and of shape ({height}, {width}); "
                    f"got shape {c.shape}"
                )
        self._c_on = c_on.reshape(-1).copy()
        self._c_off = c_off.reshape(-1).copy()
        hot = self._rng.random(n) < self.params.hot_pixel_fraction
        self.hot_pixels = np.flatnonzero(hot)
        """Flat indices (``y * width + x``) of the hot pixels."""
        self._log = np.zeros(n, dtype=np.float64)
        self._ref = np.zeros(n, dtype=np.float64)
        self._last = np.full(n, -np.inf, dtype=np.float64)
        self._warm = False
        self._buffers = list(new_buffers())

    def _init(self, flat: np.ndarray) -> None:
        np.log(flat.astype(np.float64) + self.params.log_eps, out=self._log)
        self._ref[:] = self._log
        self._warm = self.warm_start  # the reference moves at the first interval

    def _warm_up(self, flat: np.ndarray) -> None:
        change = np.log(flat.astype(np.float64) + self.params.log_eps) - self._log
        u = self._rng.random(self._ref.size)
        self._ref -= _warm_offsets(u, change, self._c_on, self._c_off)
        self._warm = False

    def _interval(self, flat: np.ndarray, t0: float, t1: float) -> np.ndarray:
        p = self.params
        if self._warm:
            self._warm_up(flat)
        t, x, y, pol, *self._buffers = esim_frame(
            self._log, flat, self._ref, self._last, self._c_on, self._c_off,
            p.log_eps, p.refractory_us, t0, t1, *self._buffers, self.sensor_size[0],
        )  # fmt: skip
        events = to_events(t, x, y, pol)
        noise = self._noise(t0, t1)
        if noise.size:
            events = np.concatenate([events, noise])
            events = events[np.argsort(events["t"], kind="stable")]
        return events

    def _noise(self, t0: float, t1: float) -> np.ndarray:
        """Background-activity and hot-pixel events in ``(t0, t1]`` (not touching the state)."""
        p = self.params
        width, height = self.sensor_size
        dt_s = (t1 - t0) * 1e-6
        n_ba = self._rng.poisson(p.noise_rate_hz * dt_s * width * height) if p.noise_rate_hz else 0
        n_hot = (
            self._rng.poisson(p.hot_pixel_rate_hz * dt_s, self.hot_pixels.size)
            if self.hot_pixels.size and p.hot_pixel_rate_hz
            else np.zeros(0, dtype=np.int64)
        )
        total = int(n_ba + n_hot.sum())
        out = np.empty(total, dtype=EVENT_DTYPE)
        if total == 0:
            return out
        pix = np.concatenate(
            [self._rng.integers(0, width * height, n_ba), np.repeat(self.hot_pixels, n_hot)]
        )
        t = t0 + (t1 - t0) * (1.0 - self._rng.random(total))  # in (t0, t1]
        out["t"] = np.rint(t).astype(np.int64)
        out["x"] = pix % width
        out["y"] = pix // width
        out["p"] = self._rng.integers(0, 2, total)
        return out[np.argsort(out["t"], kind="stable")]


def _warm_offsets(
    u: np.ndarray, change: np.ndarray, up: np.ndarray | float, down: np.ndarray | float
) -> np.ndarray:
    """A warm start's offsets from the reference: ``u`` (uniform in [0, 1)) of the way to
    the threshold ``up`` where ``change`` rises, to ``-down`` where it falls, and across
    both where it holds.

    Examples
    --------
    >>> _warm_offsets(np.full(3, 0.5), np.array([1.0, -1.0, 0.0]), 0.2, 0.3).tolist()
    [0.1, -0.15, -0.04999999999999999]
    """
    u = np.asarray(u, np.float64)
    return np.where(change > 0, u * up, np.where(change < 0, -u * down, u * (up + down) - down))


def make_simulator(
    model: str,
    sensor_size: SensorSize,
    params: VoltmeterParams | IdealParams | None = None,
    *,
    thresholds: tuple[np.ndarray, np.ndarray] | None = None,
    rng: np.random.Generator | int | None = None,
    warm_start: bool = False,
) -> VoltmeterSimulator | IdealSimulator:
    """Create a simulator by name: ``"voltmeter"`` or ``"ideal"`` (``warm_start``: see
    the module docstring).

    Examples
    --------
    >>> type(make_simulator("ideal", (8, 8))).__name__
    'IdealSimulator'
    """
    check_choice("model", model, ("voltmeter", "ideal"))
    if model == "voltmeter":
        if thresholds is not None:
            raise SimError("thresholds apply to the ideal simulator only")
        return VoltmeterSimulator(sensor_size, params, rng=rng, warm_start=warm_start)  # type: ignore[arg-type]
    return IdealSimulator(  # type: ignore[arg-type]
        sensor_size, params, thresholds=thresholds, rng=rng, warm_start=warm_start
    )


def simulate_frames(
    simulator: VoltmeterSimulator | IdealSimulator,
    frames: Iterable[tuple[int, np.ndarray]],
) -> np.ndarray:
    """Feed ``(t_us, frame)`` pairs to ``simulator``; return all events, sorted by time.

    Examples
    --------
    >>> sim = IdealSimulator((2, 1), IdealParams(c_on=0.5))
    >>> video = [(0, np.ones((1, 2))), (1000, np.full((1, 2), 10.0))]
    >>> simulate_frames(sim, video)["p"].tolist()
    [1, 1, 1, 1, 1, 1]
    """
    chunks = [simulator.feed(frame, t_us) for t_us, frame in frames]
    if not chunks:
        return np.empty(0, dtype=EVENT_DTYPE)
    return np.concatenate(chunks)
