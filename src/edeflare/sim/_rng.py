"""Per-pixel random streams of the compiled simulators: a mixed Weyl sequence, a ziggurat normal.

Each pixel owns one 64-bit state, a Weyl sequence (``state += 0x9E37...``,
as in SplitMix64, Steele, Lea & Flood 2014) whose output goes through Pelle
Evensen's ``nasam`` mixer. SplitMix64's own finaliser is too weak when the
stream is consumed with a stride (a normal, then a uniform, then a normal...):
every other output then comes from an even increment, and the uniforms of such
a stream failed a Kolmogorov-Smirnov test at 1e5 draws; ``nasam`` is built to
be strong even for plain counters. A pixel's draws do not depend on which other
pixels fired or how pixels are ordered, so a simulator is bit-reproducible
from its seed. Normals come from the 256-layer ziggurat of Marsaglia &
Tsang (2000) with Marsaglia's exponential tail; the tail of a normal beyond
``a`` (needed by the DVS-Voltmeter's against-drift sampler) has its own exact
sampler.

The compiled functions take the state and return ``(state, value)``; they are
inlined into the kernels of :mod:`edeflare.sim.dvs`. Numba's on-disk cache
does not notice edits to this module from the kernels that inline it: after
changing it, delete ``src/edeflare/sim/__pycache__``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["seed_states"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_NASAM1 = np.uint64(0x9E6C63D0676A9A99)
_NASAM2 = np.uint64(0x9E6D62D06F6A9A9B)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S25 = np.uint64(25)
_S39 = np.uint64(39)
_S47 = np.uint64(47)
_S17 = np.uint64(17)
_S23 = np.uint64(23)
_S51 = np.uint64(51)
_S11 = np.uint64(11)
_S8 = np.uint64(8)
_BYTE = np.uint64(0xFF)
_ONE = np.uint64(1)
_TWO_M53 = 2.0**-53


def _ziggurat_tables(n: int = 256) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Layer edges ``x``, densities ``f`` and fast-accept bounds of the normal ziggurat.

    Layer 0 is the base strip (area ``v`` including the tail beyond ``r``);
    layer ``i >= 1`` spans heights ``[f(x[i]), f(x[i+1])]`` over ``[0, x[i]]``.
    """
    r = 3.6541528853610087963519472518  # Marsaglia & Tsang's 256-layer constant
    f = lambda z: math.exp(-0.5 * z * z)  # noqa: E731
    v = r * f(r) + math.sqrt(math.pi / 2.0) * math.erfc(r / math.sqrt(2.0))
    x = np.empty(n + 1)
    x[0] = v / f(r)
    x[1] = r
    for i in range(1, n - 1):
        x[i + 1] = math.sqrt(-2.0 * math.log(f(x[i]) + v / x[i]))
    x[n] = 0.0
    fx = np.array([f(z) for z in x])
    fx[n] = 1.0
    ki = np.floor(x[1:] / x[:-1] * 2.0**53).astype(np.uint64)
    width = x[:-1] * _TWO_M53
    return width, fx, ki, r


_ZIG_W, _ZIG_F, _ZIG_K, _ZIG_R = _ziggurat_tables()


def seed_states(n: int, seed: int) -> np.ndarray:
    """``n`` starting states derived from a 64-bit ``seed`` (SplitMix64 finaliser, twice).

    Examples
    --------
    >>> s = seed_states(3, 7)
    >>> s.dtype, len(set(s.tolist()))
    (dtype('uint64'), 3)
    """
    with np.errstate(over="ignore"):
        z = np.arange(1, n + 1, dtype=np.uint64) * _GOLDEN + np.uint64(seed)
        z = (z ^ (z >> _S30)) * _MIX1
        z = (z ^ (z >> _S27)) * _MIX2
        z ^= z >> _S31
        # A second round decorrelates neighbouring pixels' starting points further.
        z = (z ^ (z >> _S30)) * _MIX1
        z = (z ^ (z >> _S27)) * _MIX2
        z ^= z >> _S31
    return z


@numba.njit(cache=True, inline="always", error_model="numpy")
def next_u64(s):  # pragma: no cover - compiled
    """Advance the Weyl state; return ``(state, 64 random bits)`` (``nasam`` of the state)."""
    s = s + _GOLDEN
    z = s ^ ((s >> _S25) | (s << _S39)) ^ ((s >> _S47) | (s << _S17))  # rotr 25, rotr 47
    z = z * _NASAM1
    z = z ^ (z >> _S23) ^ (z >> _S51)
    z = z * _NASAM2
    return s, z ^ (z >> _S23) ^ (z >> _S51)


@numba.njit(cache=True, inline="always", error_model="numpy")
def uniform(s):  # pragma: no cover - compiled
    """A double uniform on ``[0, 1)`` (53 random bits)."""
    s, z = next_u64(s)
    return s, np.float64(z >> _S11) * _TWO_M53


@numba.njit(cache=True, inline="always", error_model="numpy")
def uniform_open(s):  # pragma: no cover - compiled
    """A double uniform on ``(0, 1)``, safe to take the log of."""
    s, z = next_u64(s)
    return s, (np.float64(z >> _S11) + 0.5) * _TWO_M53


@numba.njit(cache=True, error_model="numpy")
def _normal_tail(s, a):  # pragma: no cover - compiled
    """``a + x`` with ``x >= 0``: the standard normal conditioned on exceeding ``a >= 1``."""
    while True:
        s, u1 = uniform_open(s)
        s, u2 = uniform_open(s)
        x = -math.log(u1) / a
        y = -math.log(u2)
        if y + y > x * x:
            return s, a + x


@numba.njit(cache=True, error_model="numpy")
def _normal_rest(s, z):  # pragma: no cover - compiled
    """The ziggurat's rare branches for the 64 bits ``z`` (wedge or tail), then retries."""
    while True:
        i = np.intp(z & _BYTE)
        negative = ((z >> _S8) & _ONE) == _ONE
        j = z >> _S11
        x = np.float64(j) * _ZIG_W[i]
        if j < _ZIG_K[i]:
            return s, -x if negative else x
        if i == 0:
            s, x = _normal_tail(s, _ZIG_R)
            return s, -x if negative else x
        s, u = uniform(s)
        if _ZIG_F[i] + u * (_ZIG_F[i + 1] - _ZIG_F[i]) < math.exp(-0.5 * x * x):
            return s, -x if negative else x
        s, z = next_u64(s)


@numba.njit(cache=True, inline="always", error_model="numpy")
def normal(s):  # pragma: no cover - compiled
    """A standard normal draw: the ziggurat's fast path inline (about 99 %), the rest called."""
    s, z = next_u64(s)
    i = np.intp(z & _BYTE)
    j = z >> _S11
    if j < _ZIG_K[i]:
        x = np.float64(j) * _ZIG_W[i]
        return s, -x if ((z >> _S8) & _ONE) == _ONE else x
    return _normal_rest(s, z)


@numba.njit(cache=True, error_model="numpy")
def normal_sq_beyond(s, a):  # pragma: no cover - compiled
    """``X**2`` for a standard normal ``X`` conditioned on ``|X| >= a`` (``a >= 0``)."""
    if a < 1.0:  # plain rejection: acceptance 2 * Phi(-a) > 0.31
        while True:
            s, x = normal(s)
            if abs(x) >= a:
                return s, x * x
    s, x = _normal_tail(s, a)
    return s, x * x
