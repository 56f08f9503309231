"""Temporal alignment: the offset between two passes from their strobe signatures."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal

from ..errors import ParameterError
from ._common import PairingError, _positive_int
from .signature import Signature, polarity_signature  # noqa: F401  (polarity_signature: doctest)


@dataclass(frozen=True, eq=False)
class Alignment:
    """The time offset between two passes, found by :func:`estimate_offset`.

    Attributes
    ----------
    offset_us : float
        ``t_reference = t_observation + offset_us`` for the same scene instant;
        subtract it from the reference's timestamps to bring them onto the
        observation's clock.
    correlation : float
        Pearson correlation of the two ON-fraction signatures at the best
        coarse lag.
    second_peak : float
        The best correlation at any lag outside the main peak (where the
        correlation first falls below half the peak on each side); NaN when
        the search range holds no other lag.
    confidence : float
        ``correlation - max(second_peak, 0)`` clipped to [0, 1]: about the
        peak correlation for a unique match, near 0 when another lag fits as
        well (a periodic strobe searched over more than half its period), and
        0 when the best lag is at the edge of the search range (the true
        offset may lie beyond it).
    search_us : (float, float)
        Lowest and highest offsets searched.
    at_edge : bool
        The best fine lag is the first or last offset searched: the true
        offset may lie outside the range (widen ``max_offset_us``).
    bin_us, refine_bin_us : int
        Coarse search bin and fine (signature) bin.
    lags_us, scores : numpy.ndarray
        The coarse offsets tried and their correlations (for plots).
    """

    offset_us: float
    correlation: float
    second_peak: float
    confidence: float
    search_us: tuple[float, float]
    at_edge: bool
    bin_us: int
    refine_bin_us: int
    lags_us: np.ndarray = field(repr=False)
    scores: np.ndarray = field(repr=False)

    def describe(self) -> str:
        """One line: offset, peak and second peak, edge flag."""
        text = (
            f"offset {self.offset_us / 1000:.3f} ms, peak correlation {self.correlation:.3f}, "
            f"second peak {self.second_peak:.3f}"
        )
        return text + (", at the edge of the search range" if self.at_edge else "")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (NaN as None)."""

        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else round(float(v), 6)

        return {
            "offset_us": num(self.offset_us),
            "correlation": num(self.correlation),
            "second_peak": num(self.second_peak),
            "confidence": num(self.confidence),
            "search_us": [num(self.search_us[0]), num(self.search_us[1])],
            "bin_us": self.bin_us,
            "refine_bin_us": self.refine_bin_us,
            "at_edge": self.at_edge,
        }


def _ncc(a: np.ndarray, b: np.ndarray, lags: np.ndarray, min_overlap: int) -> np.ndarray:
    """Pearson correlation of ``a[i]`` with ``b[i + k]`` over their overlap, for each lag ``k``.

    NaN where the overlap is shorter than ``min_overlap`` or either side is constant.
    """
    lags = np.asarray(lags, dtype=np.int64)
    na, nb = a.size, b.size
    a = a - a.mean() if na else a
    b = b - b.mean() if nb else b
    i0 = np.maximum(0, -lags)
    i1 = np.minimum(na, nb - lags)
    n = i1 - i0
    valid = n >= max(2, int(min_overlap))
    i0 = np.where(valid, i0, 0)
    i1 = np.where(valid, i1, 0)
    if int(valid.sum()) <= 64:  # a few lags (the refinement): slices, no full-length temporaries
        sums = np.zeros((lags.size, 5))
        for row, (s, e, k, ok) in enumerate(zip(i0, i1, lags, valid, strict=True)):
            if ok:
                x, y = a[s:e], b[s + k : e + k]
                sums[row] = x.sum(), np.dot(x, x), y.sum(), np.dot(y, y), np.dot(x, y)
        sa, saa, sb, sbb, sab = sums.T
    else:  # many lags (the coarse search): prefix sums and one FFT correlation
        j0 = np.where(valid, i0 + lags, 0)
        j1 = np.where(valid, i1 + lags, 0)
        ca = np.concatenate([[0.0], np.cumsum(a)])
        caa = np.concatenate([[0.0], np.cumsum(a * a)])
        cb = np.concatenate([[0.0], np.cumsum(b)])
        cbb = np.concatenate([[0.0], np.cumsum(b * b)])
        sa, saa = ca[i1] - ca[i0], caa[i1] - caa[i0]
        sb, sbb = cb[j1] - cb[j0], cbb[j1] - cbb[j0]
        z = signal.correlate(b, a, mode="full", method="fft")  # z[k + na - 1] = sum a[i] b[i+k]
        sab = np.where(valid, z[np.clip(lags + na - 1, 0, z.size - 1)], 0.0)
    nn = np.maximum(n, 1).astype(np.float64)
    cov = sab - sa * sb / nn
    va = saa - sa * sa / nn
    vb = sbb - sb * sb / nn
    eps = 1e-12 * np.maximum(nn, 1.0)
    ok = valid & (va > eps) & (vb > eps)
    out = np.full(lags.shape, np.nan)
    out[ok] = cov[ok] / np.sqrt(va[ok] * vb[ok])
    return np.clip(out, -1.0, 1.0)


def _parabola(left: float, mid: float, right: float) -> float:
    """Vertex of the parabola through (-1, left), (0, mid), (1, right), in [-0.5, 0.5]."""
    den = left - 2.0 * mid + right
    if not (math.isfinite(left) and math.isfinite(right)) or den >= 0:
        return 0.0
    return float(np.clip(0.5 * (left - right) / den, -0.5, 0.5))


def estimate_offset(
    obs: Signature,
    ref: Signature,
    *,
    max_offset_us: int = 1_000_000,
    expected_offset_us: float | None = None,
    bin_us: int | None = None,
    pseudocount: float = 4.0,
    min_overlap: float = 0.5,
) -> Alignment:
    """Find the time offset between an observation and a reference from their strobe signatures.

    Each signature becomes its ON-fraction series
    (:meth:`Signature.on_fraction`, shrunk by ``pseudocount``). The Pearson
    correlation between the observation series and the shifted reference
    series is computed at every coarse lag (bins of ``bin_us``) whose offset
    lies within ``expected_offset_us ± max_offset_us`` and whose overlap
    covers at least ``min_overlap`` of the shorter recording. The best coarse
    lag is then refined at the signatures' own (fine) bin over ± one coarse
    bin, and the fine peak is interpolated with a parabola through its two
    neighbours.

    The coarse search correlates the ON *fraction*, which the filter leaves
    alone (it changes how many events the light makes by spreading it into a
    flare, not their polarity) and which bursts of scene motion, balanced in
    polarity, barely move. The refinement correlates the polarity *imbalance*
    (:meth:`Signature.imbalance`, ON events in excess of the overall ON
    fraction), which is linear in the counts: the fraction saturates at 0 or
    1 over a strobe edge for as long as the edge's events dominate a bin,
    i.e. longer in the pass with more events, and that would bias the
    sub-bin offset by about a fifth of a fine bin. Pearson correlation is
    invariant to the filter scaling the imbalance.

    Parameters
    ----------
    obs, ref : Signature
        Signatures of the two passes at the same (fine) bin, e.g. 100 µs.
    max_offset_us : int
        Half-width of the search range. A periodic strobe of period ``P``
        correlates equally well at every multiple of ``P``: either keep the
        search range under ``P / 2`` around a good ``expected_offset_us``, or
        use a non-periodic strobe (random on/off intervals), or rely on the
        scene's motion to break the tie; :attr:`Alignment.confidence` tells
        which case you are in.
    expected_offset_us : float, optional
        Centre of the search range; default ``ref.t_start_us -
        obs.t_start_us`` (signatures from :func:`scan_recording` start at the
        first event, so this aligns the starts of the two recordings).
    bin_us : int, optional
        Coarse search bin, a multiple of the signatures' bin; default ten
        times it.
    pseudocount : float
        Shrinkage of sparse bins toward the overall ON fraction.
    min_overlap : float
        Minimum overlap of the two series, as a fraction of the shorter one.

    Returns
    -------
    Alignment

    Raises
    ------
    PairingError
        Empty or constant signatures, or no lag with enough overlap.

    Examples
    --------
    A strobe switching at irregular times, seen by the reference 2.5 ms later:

    >>> from edeflare.events import make_events
    >>> rng = np.random.default_rng(0)
    >>> edges = np.cumsum(rng.integers(3_000, 9_000, 60))
    >>> t = np.repeat(edges, 20) + rng.integers(0, 300, edges.size * 20)
    >>> p = np.repeat(np.arange(edges.size) % 2, 20)
    >>> order = np.argsort(t, kind="stable")
    >>> obs = make_events(t[order], [0] * t.size, [0] * t.size, p[order])
    >>> ref = make_events(t[order] + 2_500, [0] * t.size, [0] * t.size, p[order])
    >>> a = estimate_offset(polarity_signature(obs, 100), polarity_signature(ref, 100),
    ...                     max_offset_us=20_000, expected_offset_us=0)
    >>> round(a.offset_us / 100) * 100, a.confidence > 0.5
    (2500, True)
    """
    if obs.bin_us != ref.bin_us:
        raise ParameterError(
            f"signatures have different bins ({obs.bin_us} µs and {ref.bin_us} µs)"
        )
    fine = int(obs.bin_us)
    coarse = 10 * fine if bin_us is None else _positive_int("bin_us", bin_us)
    if coarse % fine:
        raise ParameterError(f"bin_us {coarse} must be a multiple of the signature bin {fine} µs")
    max_offset_us = int(max_offset_us)
    if max_offset_us < 0:
        raise ParameterError(f"max_offset_us must be >= 0, got {max_offset_us}")
    if not 0 < min_overlap <= 1:
        raise ParameterError(f"min_overlap must lie in (0, 1], got {min_overlap}")
    for name, sig in (("observation", obs), ("reference", ref)):
        if sig.n_events == 0:
            raise PairingError(f"the {name} signature holds no events")
    factor = coarse // fine
    base = ref.t_start_us - obs.t_start_us  # offset of lag 0
    centre = float(base if expected_offset_us is None else expected_offset_us)
    lo_us, hi_us = centre - max_offset_us, centre + max_offset_us

    obs_c, ref_c = obs.rebin(factor), ref.rebin(factor)
    a, b = obs_c.on_fraction(pseudocount), ref_c.on_fraction(pseudocount)
    k_lo = math.ceil((lo_us - base) / coarse)
    k_hi = math.floor((hi_us - base) / coarse)
    if k_hi < k_lo:  # range narrower than a bin: take the nearest lag
        k_lo = k_hi = round((centre - base) / coarse)
    lags = np.arange(k_lo, k_hi + 1, dtype=np.int64)
    min_n = math.ceil(min_overlap * min(a.size, b.size))
    scores = _ncc(a, b, lags, min_n)
    lags_us = base + lags.astype(np.float64) * coarse
    if not np.isfinite(scores).any():
        raise PairingError(
            f"no offset within {lo_us / 1000:.3f}..{hi_us / 1000:.3f} ms lets the recordings "
            f"overlap by {min_overlap:.0%} of the shorter one with a varying signature; "
            "check expected_offset_us / max_offset_us and that the strobe is visible in both"
        )
    peak = int(np.nanargmax(scores))
    r_peak = float(scores[peak])
    # The main peak: where the correlation stays above half the peak on each side.
    left, right = peak, peak
    while left > 0 and np.isfinite(scores[left - 1]) and scores[left - 1] > r_peak / 2:
        left -= 1
    last = scores.size - 1
    while right < last and np.isfinite(scores[right + 1]) and scores[right + 1] > r_peak / 2:
        right += 1
    outside = np.concatenate([scores[: max(0, left - 1)], scores[right + 2 :]])
    outside = outside[np.isfinite(outside)]
    second = float(outside.max()) if outside.size else math.nan

    # Refinement at the fine bin around the coarse peak.
    af, bf = obs.imbalance(), ref.imbalance()
    m_lo = max(math.ceil((lo_us - base) / fine), int(lags[peak]) * factor - factor)
    m_hi = min(math.floor((hi_us - base) / fine), int(lags[peak]) * factor + factor)
    if m_hi < m_lo:
        m_lo = m_hi = int(lags[peak]) * factor
    fine_lags = np.arange(m_lo, m_hi + 1, dtype=np.int64)
    fine_scores = _ncc(af, bf, fine_lags, math.ceil(min_overlap * min(af.size, bf.size)))
    edges = (math.ceil((lo_us - base) / fine), math.floor((hi_us - base) / fine))
    if np.isfinite(fine_scores).any():
        j = int(np.nanargmax(fine_scores))
        delta = 0.0
        if 0 < j < fine_scores.size - 1:
            delta = _parabola(*(float(v) for v in fine_scores[j - 1 : j + 2]))
        offset = base + (float(fine_lags[j]) + delta) * fine
        at_edge = int(fine_lags[j]) in edges
    else:
        offset = float(lags_us[peak])
        at_edge = peak in (0, scores.size - 1)
    confidence = 0.0
    if r_peak > 0 and not at_edge:
        confidence = float(np.clip(r_peak - max(second if math.isfinite(second) else 0, 0), 0, 1))
    return Alignment(
        offset_us=float(offset),
        correlation=r_peak,
        second_peak=second,
        confidence=confidence,
        search_us=(float(lo_us), float(hi_us)),
        at_edge=at_edge,
        bin_us=coarse,
        refine_bin_us=fine,
        lags_us=lags_us,
        scores=scores,
    )
