"""Event-to-image reconstruction: a per-pixel leaky (high-pass) integrator of events.

The classical filter of Scheerlinck et al. (2018) without frames. Every pixel
holds a log-intensity estimate ``L`` (zero: no change from the mean); an
event adds its polarity times the contrast threshold ``c``, and between
events ``L`` decays exponentially toward zero with rate ``alpha`` (the
cut-off angular frequency), which forgets slow drift and old edges:

.. math::

    L(t_k^+) = e^{-\\alpha (t_k - t_{k-1})} L(t_{k-1}^+) + \\sigma_k c,
    \\qquad L(\\tau) = e^{-\\alpha (\\tau - t_k)} L(t_k^+),

with ``t_{k-1}`` and ``t_k`` consecutive events of the pixel, ``sigma_k``
= +1 for ON and -1 for OFF, and ``tau`` a frame time after ``t_k`` and before
the pixel's next event. ``alpha = 2 pi f_c`` for a cut-off frequency
``f_c`` in Hz (the time constant is ``1 / alpha``). With a frame input the
complementary filter of the same paper blends ``L`` toward the frame; with
events only, as here, it reduces to this high-pass filter. The result is a
*relative* log-intensity image: gray where nothing changed recently, bright
where brightness rose, dark where it fell; flare shows up as bright halos
and streaks around a light source.

:func:`reconstruct` samples ``L`` at given times (a frame at ``tau`` sees the
events with ``t < tau``, as half-open windows do); :func:`to_uint8` maps
frames to displayable gray levels. The per-event state machine is compiled
with numba; everything is deterministic.

References
----------
C. Scheerlinck, N. Barnes, R. Mahony, "Continuous-time intensity estimation
using event cameras", ACCV 2018.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, check_events, check_sensor_size

__all__ = ["LeakyIntegrator", "display_scale", "reconstruct", "to_uint8"]


@numba.njit(cache=True, nogil=True)
def _emit(state, last, tau, rate, frame):  # pragma: no cover - compiled
    for k in range(state.size):
        s = state[k]
        frame[k] = s * math.exp(-rate * (tau - last[k])) if s != 0.0 else 0.0


@numba.njit(cache=True, nogil=True)
def _integrate(t, x, y, p, width, state, last, times, rate, contrast, out):  # pragma: no cover
    f = 0
    n_frames = times.size
    for i in range(t.size):
        ti = t[i]
        while f < n_frames and times[f] <= ti:
            _emit(state, last, times[f], rate, out[f])
            f += 1
        k = np.int64(y[i]) * width + np.int64(x[i])
        s = state[k]
        if s != 0.0:
            s *= math.exp(-rate * (ti - last[k]))
        state[k] = s + (contrast if p[i] else -contrast)
        last[k] = ti
    while f < n_frames:
        _emit(state, last, times[f], rate, out[f])
        f += 1


def _check_times(times_us: Any) -> np.ndarray:
    times = np.asarray(times_us)
    integral = times.dtype.kind in "iu" or (
        times.dtype.kind == "f" and bool(np.all(np.isfinite(times) & (times == np.round(times))))
    )
    if times.ndim != 1 or not integral:
        raise ParameterError(f"times_us must be a 1-D array of whole µs, got {times_us!r}")
    times = times.astype(np.int64, copy=False)
    if times.size > 1 and np.any(np.diff(times) < 0):
        raise ParameterError("times_us must be non-decreasing")
    return times


class LeakyIntegrator:
    """The integrator of :func:`reconstruct` as a stream: feed events in time order, get frames.

    Each call to :meth:`frames` continues from the state the previous calls
    left, so cutting a stream into chunks gives the same frames as one call
    on the whole stream, with memory bounded by the chunk.

    Parameters
    ----------
    sensor_size : (width, height)
    cutoff_hz, contrast : float
        As :func:`reconstruct`.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5_000, 12_000], [0, 0, 1], [0, 0, 0], [1, 0, 1])
    >>> whole = reconstruct(ev, (2, 1), [10_000, 20_000])
    >>> integ = LeakyIntegrator((2, 1))
    >>> parts = [integ.frames(ev[:2], [10_000]), integ.frames(ev[2:], [20_000])]
    >>> bool(np.array_equal(whole, np.concatenate(parts)))
    True
    """

    def __init__(
        self, sensor_size: SensorSize, *, cutoff_hz: float = 5.0, contrast: float = 0.2
    ) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        cutoff_hz, contrast = float(cutoff_hz), float(contrast)
        if not (math.isfinite(cutoff_hz) and cutoff_hz >= 0):
            raise ParameterError(f"cutoff_hz must be a finite number >= 0, got {cutoff_hz!r}")
        if not (math.isfinite(contrast) and contrast > 0):
            raise ParameterError(f"contrast must be a finite number > 0, got {contrast!r}")
        self.cutoff_hz, self.contrast = cutoff_hz, contrast
        width, height = self.sensor_size
        self._state = np.zeros(width * height, dtype=np.float64)
        self._last = np.zeros(width * height, dtype=np.int64)
        self._events_from: int | None = None  # later events must be at or after this
        self._frames_from: int | None = None  # later frame times must be at or after this

    def frames(self, events: np.ndarray, times_us: np.ndarray | list[int]) -> np.ndarray:
        """Feed the next events and return ``L`` at ``times_us`` (``float32`` ``(n, H, W)``).

        ``events`` must not be earlier than anything fed or sampled before,
        and ``times_us`` not earlier than the events fed before.
        """
        check_events(events, self.sensor_size)
        times = _check_times(times_us)
        if events.size and self._events_from is not None and events["t"][0] < self._events_from:
            raise ParameterError(
                f"events go back in time: {int(events['t'][0])} µs after {self._events_from} µs"
            )
        if times.size and self._frames_from is not None and times[0] < self._frames_from:
            raise ParameterError(
                f"frame time {int(times[0])} µs is before events already fed "
                f"(up to {self._frames_from - 1} µs)"
            )
        width, height = self.sensor_size
        out = np.zeros((times.size, height * width), dtype=np.float32)
        _integrate(
            events["t"],
            events["x"],
            events["y"],
            events["p"],
            width,
            self._state,
            self._last,
            times,
            2.0 * math.pi * self.cutoff_hz * 1e-6,  # per µs
            self.contrast,
            out,
        )
        last_t = int(events["t"][-1]) if events.size else None
        last_f = int(times[-1]) if times.size else None
        after_t = None if last_t is None else last_t + 1
        ev_bounds = [v for v in (self._events_from, last_t, last_f) if v is not None]
        fr_bounds = [v for v in (self._frames_from, after_t, last_f) if v is not None]
        self._events_from = max(ev_bounds) if ev_bounds else None
        self._frames_from = max(fr_bounds) if fr_bounds else None
        return out.reshape(times.size, height, width)


def reconstruct(
    events: np.ndarray,
    sensor_size: SensorSize,
    times_us: np.ndarray | list[int],
    *,
    cutoff_hz: float = 5.0,
    contrast: float = 0.2,
) -> np.ndarray:
    """Log-intensity frames of a leaky per-pixel integrator of events, sampled at ``times_us``.

    Parameters
    ----------
    events : numpy.ndarray
        Sorted events (the state starts at zero before the first one).
    sensor_size : (width, height)
    times_us : array_like of int
        Non-decreasing frame times (absolute µs). A frame at ``tau`` reflects
        the events with ``t < tau``.
    cutoff_hz : float
        Cut-off frequency ``f_c`` of the high-pass filter; the decay rate is
        ``alpha = 2 pi f_c`` per second (0: a pure integrator, no decay).
    contrast : float
        Contrast threshold ``c``: the log-intensity step of one event.

    Returns
    -------
    numpy.ndarray
        ``float32`` ``(n_frames, H, W)``: ``L`` at each time.

    Notes
    -----
    ``L(t_k+) = exp(-alpha (t_k - t_prev)) L(t_prev+) + sigma_k c`` per pixel at
    each of its events, ``L(tau) = exp(-alpha (tau - t_last)) L(t_last+)`` at
    a frame time (see the module docstring). :class:`LeakyIntegrator` gives
    the same frames chunk by chunk.

    Examples
    --------
    One pixel, an ON event at 0 and another at 10 ms; ``f_c = 1 / (2 pi)`` Hz
    makes ``alpha = 1 /s``:

    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 10_000], [0, 0], [0, 0], [1, 1])
    >>> f = reconstruct(ev, (1, 1), [10_000, 20_000], cutoff_hz=1 / (2 * np.pi), contrast=0.5)
    >>> round(float(f[0, 0, 0]), 6)  # 0.5 e^-0.01 (the 2nd event is not seen yet)
    0.495025
    >>> round(float(f[1, 0, 0]), 6)  # (0.5 e^-0.01 + 0.5) e^-0.01
    0.985124
    """
    integrator = LeakyIntegrator(sensor_size, cutoff_hz=cutoff_hz, contrast=contrast)
    return integrator.frames(events, times_us)


def display_scale(frames: np.ndarray, percentile: float = 99.0) -> float:
    """A robust full-scale value for :func:`to_uint8`: a percentile of the non-zero ``|L|``.

    Examples
    --------
    >>> display_scale(np.array([[0.0, 0.5], [-1.0, 2.0]]), percentile=50)
    1.0
    """
    if not 0 < percentile <= 100:
        raise ParameterError(f"percentile must be in (0, 100], got {percentile!r}")
    mag = np.abs(np.asarray(frames, dtype=np.float64))
    mag = mag[(mag > 0) & np.isfinite(mag)]
    return float(np.percentile(mag, percentile)) if mag.size else 1.0


def to_uint8(
    frames: np.ndarray,
    *,
    scale: float | None = None,
    percentile: float = 99.0,
) -> np.ndarray:
    """Map log-intensity frames to gray levels: 0 -> 128, ``+scale`` -> 255, ``-scale`` -> 0.

    The mapping is symmetric around zero (no change is mid-gray) and linear;
    values beyond ``scale`` saturate. ``scale`` defaults to
    :func:`display_scale` of ``frames`` (a percentile of the non-zero
    magnitudes, robust to a few hot pixels); pass one shared value to compare
    several reconstructions on the same scale.

    Examples
    --------
    >>> to_uint8(np.array([[-1.0, 0.0, 0.5, 4.0]]), scale=1.0).tolist()
    [[0, 128, 191, 255]]
    """
    frames = np.asarray(frames, dtype=np.float64)
    if scale is None:
        scale = display_scale(frames, percentile)
    if not (math.isfinite(scale) and scale > 0):
        raise ParameterError(f"scale must be a finite number > 0, got {scale!r}")
    gray = 127.5 + 127.5 * np.clip(np.nan_to_num(frames) / scale, -1.0, 1.0)
    return np.clip(np.floor(gray + 0.5), 0, 255).astype(np.uint8)
