"""Compiled kernel of the DVS-Voltmeter simulator (see :mod:`edeflare.sim.dvs` for the model).

:func:`voltmeter_frame` simulates one frame interval ``(t0, t1]`` for every
pixel in one call: a vectorised pass settles the common case, the full model
handles the rest, and the events come back sorted (see
:mod:`edeflare.sim._buffer`). Pixels are independent: each has its own
residual voltage and its own random stream.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._buffer import collect, grown
from ._rng import _BYTE, _S11, _ZIG_K, _ZIG_W, next_u64, normal, normal_sq_beyond, uniform

__all__: list[str] = []

# P_on below this is treated as 0: a 53-bit uniform can only be <= it when it is exactly 0.
_P_TINY = 2.0**-54


@numba.njit(cache=True, inline="always", error_model="numpy")
def p_on_first(mu, sigma, a_on, b_off):  # pragma: no cover - compiled
    """Probability that Brownian motion with drift ``mu`` hits ``+a_on`` before ``-b_off``.

    ``(exp(2 mu B / s^2) - 1) / (exp(2 mu B / s^2) - exp(-2 mu A / s^2))`` in
    forms that never overflow: for ``mu > 0`` divide by ``exp(2 mu B / s^2)``,
    for ``mu < 0`` multiply by ``exp(2 mu A / s^2)``; ``B / (A + B)`` at
    ``mu = 0``.
    """
    if b_off <= 0.0:
        return 0.0
    if a_on <= 0.0:
        return 1.0
    if mu == 0.0:
        return b_off / (a_on + b_off)
    if sigma <= 0.0:
        return 1.0 if mu > 0.0 else 0.0
    a = 2.0 * mu / (sigma * sigma)
    if mu > 0.0:
        x = a * b_off
        if x > 40.0:  # expm1(-40) == -1.0 in double precision: the ratio is exactly 1
            return 1.0
        return math.expm1(-x) / math.expm1(-a * (a_on + b_off))
    y = a * a_on
    if y < -745.0:
        return 0.0
    return math.exp(y) * math.expm1(a * b_off) / math.expm1(a * (a_on + b_off))


@numba.njit(cache=True, error_model="numpy")
def first_passage(s, eps, drift, sigma, exact):  # pragma: no cover - compiled
    """Time for Brownian motion (drift ``drift``, diffusion ``sigma``) to travel ``eps``.

    ``drift > 0`` (towards the barrier): inverse Gaussian with mean
    ``eps / drift`` and shape ``eps**2 / sigma**2`` (Michael, Schucany & Haas
    1976, written without cancellation). ``drift < 0`` (against it): the
    original simulator's sampler, a normal truncated to ``X**2 >= 4 eps |drift|
    / sigma**2`` pushed through the same transform, whose admissible root is
    ``tau = M / g`` with ``M = eps / |drift|``, ``b = 4 X**2 / T`` and
    ``g = (b - 2 + sqrt(b (b - 4))) / 2``; with ``exact`` the conditioned law
    ``IG(eps / |drift|, eps**2 / sigma**2)`` instead. ``drift == 0``: Levy,
    ``eps**2 / (sigma**2 Z**2)``.
    """
    if eps <= 0.0:
        return s, 0.0
    if sigma <= 0.0:
        return s, (eps / drift if drift > 0.0 else math.inf)
    lam = (eps * eps) / (sigma * sigma)
    if drift == 0.0:
        s, z = normal(s)
        return s, (lam / (z * z) if z != 0.0 else math.inf)
    if drift > 0.0 or exact:
        m = eps / abs(drift)
        s, z = normal(s)
        a = m * z * z / lam
        if a == 0.0:
            x = m
        elif a < 1e150:
            root = math.sqrt(a * a + 4.0 * a)
            x = 4.0 * m * a / ((a + root) * (a + root))
        else:
            x = m / a
        s, u = uniform(s)
        # Branch-free choice between the two roots (the branch is a coin flip).
        pick = np.float64(u * (m + x) <= m)
        return s, pick * x + (1.0 - pick) * (m * m / x)
    m = eps / -drift
    t = 4.0 * eps * -drift / (sigma * sigma)
    s, x2 = normal_sq_beyond(s, math.sqrt(t))
    if t > 0.0:
        b = 4.0 * x2 / t
        g = 0.5 * (b - 2.0 + math.sqrt(b * (b - 4.0))) if b > 4.0 else 1.0
        return s, m / g
    return s, lam / x2  # the limit T -> 0 (Levy)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _drift_step(mu, s2, r, s, rem):  # pragma: no cover - compiled
    """One sampling step towards the drift, branch-free (for the vectorised passes).

    Returns ``(ok, fire, v, tau, s)``. ``ok``: the step is the one
    :func:`voltmeter_slow` would take, with the same draws: the barrier
    towards the drift is certain (``P_on`` is 1, or below 2**-54, in double
    precision, so no polarity is drawn) and the ziggurat takes its fast path.
    With ``a = z**2 sigma**2 / (eps |mu|)`` and ``w = 1 + a/2 + sqrt(a + a**2/4)``
    the two Michael-Schucany-Haas roots are ``tau = m / w`` (taken with
    probability ``w / (1 + w)``) and ``m w``, ``m = eps / |mu|``. With ``g = w``
    or ``1 / w`` the voltage gathered in ``rem`` µs, ``eps rem / tau``, is
    ``v = rem |mu| g``: an event happens iff ``v > eps``, at ``tau = eps / (|mu| g)``.
    """
    up = mu > 0.0
    drift = abs(mu)
    eps = 1.0 - r if up else 1.0 + r  # distance to the barrier the drift heads for
    other = 1.0 + r if up else 1.0 - r
    ed = eps * drift
    certain = (2.0 * drift * other > 40.0 * s2) & (ed > 0.0) & (s2 > 0.0)
    s, bits = next_u64(s)
    i = bits & _BYTE
    j = bits >> _S11
    x = np.float64(j) * _ZIG_W[i]
    fast = j < _ZIG_K[i]
    s, u = uniform(s)
    a = x * x * s2 / ed
    w = 1.0 + 0.5 * a + math.sqrt(a * (1.0 + 0.25 * a))
    g = w if u * (w + 1.0) <= w else 1.0 / w
    v = rem * drift * g
    return certain & fast, v > eps, v, eps / (drift * g), s


@numba.njit(cache=True, inline="always", error_model="numpy")
def _model(l0, l1, dt, k1, k2, k3, k4, k5, k6):  # pragma: no cover - compiled
    """Drift ``mu`` and squared diffusion ``sigma**2`` of one pixel over one interval."""
    avg = (l1 + l0) / 2.0
    den = 1.0 / (avg + k2)
    mu = (k1 * (l1 - l0) / dt) * den + k4 + k5 * avg
    sigma = (k3 * math.sqrt(avg)) * den + k6
    return mu, sigma * sigma


@numba.njit(cache=True, nogil=True, error_model="numpy")
def drifts(prev, new, t0, t1, k):  # pragma: no cover - compiled
    """Each pixel's drift ``mu`` over ``(t0, t1]`` (:func:`_model`): the warm start's side."""
    k1, k2, k3, k4, k5, k6 = k[0], k[1], k[2], k[3], k[4], k[5]
    out = np.empty(prev.size, np.float64)
    for px in range(prev.size):
        out[px] = _model(np.float64(prev[px]), np.float64(new[px]), t1 - t0,
                         k1, k2, k3, k4, k5, k6)[0]  # fmt: skip
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def voltmeter_fast(prev, new, residual, state, t0, t1, k, mark):  # pragma: no cover - compiled
    """First pass over every pixel, branch-free so that it vectorises.

    Settles the common case exactly as :func:`voltmeter_slow` would (see
    :func:`_drift_step`): one step towards the drift, no event before ``t1``;
    the residual moves by ``v``, the state advances by two draws and ``prev``
    takes the new intensity, in place. Every other pixel is left untouched and
    marked for :func:`voltmeter_slow`, which redoes it from the same state
    with the same draws, so the split does not change a single result.
    """
    k1, k2, k3, k4, k5, k6 = k[0], k[1], k[2], k[3], k[4], k[5]
    dt = t1 - t0
    # An unsigned index lets numba drop its negative-index checks, so the loop vectorises.
    for px in range(np.uint64(prev.size)):
        l0 = np.float64(prev[px])
        l1 = np.float64(new[px])
        mu, s2 = _model(l0, l1, dt, k1, k2, k3, k4, k5, k6)
        r = residual[px]
        ok, fire, v, _tau, s = _drift_step(mu, s2, r, state[px], dt)
        done = ok & ~fire & (mu != 0.0)
        mark[px] = not done
        if done:
            prev[px] = l1
            residual[px] = r + v if mu > 0.0 else r - v
            state[px] = s


@numba.njit(cache=True, nogil=True, error_model="numpy")
def voltmeter_slow(
    idx, prev, new, residual, state, t0, t1, k, exact, q, n, buf_t, buf_pix, buf_p
):  # pragma: no cover - compiled
    """The full model over ``(t0, t1]`` for the pixels ``idx[q:]`` (increasing).

    Updates a pixel's ``prev``, ``residual`` and random ``state`` in place
    and appends its events to the buffers after ``n`` stored events; a pixel
    whose events do not fit is left untouched. Returns ``(q, n)``: the first pixel not done
    (``idx.size`` when all are) and the events stored.
    """
    k1, k2, k3, k4, k5, k6 = k[0], k[1], k[2], k[3], k[4], k[5]
    dt = t1 - t0
    cap = buf_t.size
    while q < idx.size:
        px = idx[q]
        l0 = np.float64(prev[px])
        l1 = np.float64(new[px])
        mu, s2 = _model(l0, l1, dt, k1, k2, k3, k4, k5, k6)
        sigma = math.sqrt(s2)
        r = residual[px]
        s = state[px]
        ts = t0
        n_px = n
        while True:
            a_on = 1.0 - r
            b_off = 1.0 + r
            if mu > 0.0 and 2.0 * mu * b_off > 40.0 * s2 and a_on > 0.0:
                on = True  # P_on == 1.0 in double precision
            elif mu < 0.0 and -2.0 * mu * a_on > 40.0 * s2 and b_off > 0.0:
                on = False  # P_on < exp(-40) < 2**-54
            else:
                pon = p_on_first(mu, sigma, a_on, b_off)
                if pon >= 1.0:
                    on = True
                elif pon < _P_TINY:
                    on = False
                else:
                    s, u = uniform(s)
                    on = u <= pon
            if on:
                eps = a_on
                drift = mu
                sign = 1.0
            else:
                eps = b_off
                drift = -mu
                sign = -1.0
            rem = t1 - ts
            ed = eps * drift
            if ed > 0.0 and s2 > 0.0:
                s, z = normal(s)
                a = z * z * s2 / ed
                w = 1.0 + 0.5 * a + math.sqrt(a * (1.0 + 0.25 * a))
                s, u = uniform(s)
                inv_w = 1.0 / w
                g = w if u * (w + 1.0) <= w else inv_w  # both computed: a select, no branch
                v = rem * drift * g
                fire = v > eps
                tau = eps / (drift * g) if fire else math.inf
            else:
                s, tau = first_passage(s, eps, drift, sigma, exact)
                fire = tau < rem
                v = eps * rem / tau
            if not fire:
                r = r + sign * v
                break
            if n >= cap:
                return q, n_px  # the buffer is full: redo this pixel after growing it
            ts = ts + tau
            buf_t[n] = ts
            buf_pix[n] = px
            buf_p[n] = on
            n += 1
            r = 0.0
        prev[px] = l1
        residual[px] = r
        state[px] = s
        q += 1
    return q, n


@numba.njit(cache=True, nogil=True, error_model="numpy")
def sample_first_passage(n, eps, drift, sigma, exact, seed):  # pragma: no cover - compiled
    """``n`` independent passage times from :func:`first_passage` (for tests and studies)."""
    out = np.empty(n)
    s = np.uint64(seed)
    for i in range(n):
        s, out[i] = first_passage(s, eps, drift, sigma, exact)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def voltmeter_frame(
    prev, new, residual, state, t0, t1, k, exact, mark, buf_t, buf_pix, buf_p, width
):  # pragma: no cover - compiled
    """One frame interval ``(t0, t1]`` of every pixel, in one compiled call.

    :func:`voltmeter_fast` for all pixels, :func:`voltmeter_slow` for the
    marked ones (growing the event buffers as needed), then the sorted events.
    Returns ``(t, x, y, p, buf_t, buf_pix, buf_p)``: the events' fields and
    the buffers to reuse next time.
    """
    voltmeter_fast(prev, new, residual, state, t0, t1, k, mark)
    count = 0
    for px in range(np.uint64(mark.size)):
        count += np.int64(mark[px])
    rest = np.empty(count, dtype=np.int64)
    j = 0
    for px in range(mark.size):
        if mark[px]:
            rest[j] = px
            j += 1
    q = 0
    n = 0
    while q < rest.size:
        q, n = voltmeter_slow(
            rest, prev, new, residual, state, t0, t1, k, exact, q, n, buf_t, buf_pix, buf_p
        )
        if q < rest.size:
            buf_t, buf_pix, buf_p = grown(buf_t, buf_pix, buf_p, n)
    t, x, y, p = collect(buf_t, buf_pix, buf_p, n, width, np.int64(math.floor(t0)))
    return t, x, y, p, buf_t, buf_pix, buf_p
