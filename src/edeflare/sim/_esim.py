"""Compiled kernel of the ideal log-intensity simulator (model in :mod:`edeflare.sim.dvs`)."""

from __future__ import annotations

import math

import numba
import numpy as np

from ._buffer import collect, grown

__all__: list[str] = []


@numba.njit(cache=True, nogil=True, error_model="numpy")
def esim_interval(
    log_prev, new, ref, last, c_on, c_off, log_eps, refractory, t0, t1, q, n, buf_t, buf_pix, buf_p
):  # pragma: no cover - compiled
    """Emit the threshold crossings of ``(t0, t1]`` of pixels ``q, q+1, ...``.

    The log intensity moves linearly from ``log_prev`` to ``log(new + eps)``;
    each crossing of ``ref + c_on`` / ``ref - c_off`` is an event at the
    interpolated time unless it falls within ``refractory`` of the pixel's last
    emitted event; the reference moves either way.
    """
    dt = t1 - t0
    cap = buf_t.size
    while q < log_prev.size:
        l0 = log_prev[q]
        l1 = math.log(np.float64(new[q]) + log_eps)
        r = ref[q]
        last_t = last[q]
        n_px = n
        if l1 > l0:
            step = c_on[q]
            level = r + step
            while level > l0 and level <= l1:
                te = t0 + (level - l0) * dt / (l1 - l0)
                if te - last_t >= refractory:
                    if n >= cap:
                        return q, n_px
                    buf_t[n] = te
                    buf_pix[n] = q
                    buf_p[n] = 1
                    n += 1
                    last_t = te
                r = level
                level = r + step
        elif l1 < l0:
            step = c_off[q]
            level = r - step
            while level < l0 and level >= l1:
                te = t0 + (level - l0) * dt / (l1 - l0)
                if te - last_t >= refractory:
                    if n >= cap:
                        return q, n_px
                    buf_t[n] = te
                    buf_pix[n] = q
                    buf_p[n] = 0
                    n += 1
                    last_t = te
                r = level
                level = r - step
        log_prev[q] = l1
        ref[q] = r
        last[q] = last_t
        q += 1
    return q, n


@numba.njit(cache=True, nogil=True, error_model="numpy")
def esim_frame(
    log_prev, new, ref, last, c_on, c_off, log_eps, refractory, t0, t1, buf_t, buf_pix, buf_p, width
):  # pragma: no cover - compiled
    """One frame interval of every pixel in one compiled call; events sorted.

    Returns ``(t, x, y, p, buf_t, buf_pix, buf_p)`` like
    :func:`edeflare.sim._voltmeter.voltmeter_frame`.
    """
    q = 0
    n = 0
    while q < log_prev.size:
        q, n = esim_interval(
            log_prev, new, ref, last, c_on, c_off, log_eps, refractory, t0, t1,
            q, n, buf_t, buf_pix, buf_p,
        )  # fmt: skip
        if q < log_prev.size:
            buf_t, buf_pix, buf_p = grown(buf_t, buf_pix, buf_p, n)
    t, x, y, p = collect(buf_t, buf_pix, buf_p, n, width, np.int64(math.floor(t0)))
    return t, x, y, p, buf_t, buf_pix, buf_p
