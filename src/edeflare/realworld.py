r"""Real paired captures (E-Flare-R): alignment, reference cleaning, noise, crop and slicing.

The paper's real-world benchmark (Sec. 3.3, Appendix A.3) records every scene
twice with a static camera: an *observation* pass with a flare-making filter
(e.g. a six-point star filter) in front of the lens, and a *reference* pass
without it. There is no hardware trigger between the passes; a strobe light in
the scene is the common clock. This module turns such a pair of recordings
(any readable format) into a paired benchmark in the layout of simulated
datasets (:mod:`edeflare.data.pairs`), one step per function:

1. **Temporal alignment.** :func:`polarity_signature` bins a stream into ON
   and OFF counts; its ON fraction over time is the strobe's signature (every
   switch-on is a burst of ON events, every switch-off a burst of OFF events),
   and it is insensitive to the filter multiplying the event counts.
   :func:`estimate_offset` cross-correlates the two signatures (Pearson
   correlation over the overlap at each lag, coarse bins over the search
   range), refines in fine bins around the peak with a parabolic fit, and
   returns an :class:`Alignment`: the offset (``t_reference = t_observation +
   offset_us``), the peak correlation, the best correlation at any clearly
   different lag, and a confidence that falls to 0 when these are equal (a
   periodic strobe searched over more than half its period is ambiguous).
2. **Reference cleaning.** Light sources are :class:`Circle` and
   :class:`Polygon` shapes, parsed from ``circle:CX,CY,R`` /
   ``polygon:X1,Y1,...`` (:func:`parse_light`), read from JSON
   (:func:`load_lights`) or found as the brightest compact region of the
   event-density map (:func:`detect_light_source`). :func:`clean_reference`
   removes the events of the glare zone (:func:`glare_mask`: within
   ``glare_radius_px`` of a source but outside every source) and keeps the
   sources themselves.
3. **Noise injection.** :func:`estimate_background_rate` measures the
   sensor's background activity (events per second per pixel, and its ON
   fraction) in the quiet regions of the observation; :func:`inject_noise`
   adds Poisson noise at that rate to the cleaned reference, by default only
   where cleaning removed everything, so the ground truth is not unnaturally
   clean there.
4. **Crop and slicing.** :func:`pair_recordings` runs the whole pipeline
   streaming (two passes over each file, memory bounded by one window), crops
   the sensor centre (640x480 by default) and writes one sequence file per
   aligned window (100 ms by default) plus ``manifest.json`` and a plot of the
   signatures before and after alignment. ``edeflare pair`` is its command
   line.

Output layout (``OUT`` may collect many scenes, one ``edeflare pair`` run each)::

    OUT/test/NAME_0000.h5        sequence files: groups input + gt, attrs t_start_us/t_end_us
    OUT/test/input/NAME_0000.h5  the observation window alone (for edeflare deflare/evaluate)
    OUT/test/gt/NAME_0000.h5     the ground truth alone
    OUT/alignment/NAME.png       signatures before / after alignment, correlation curve
    OUT/manifest.json            per scene: files, offset, confidence, lights, noise; written last

``edeflare benchmark OUT/test`` and ``edeflare evaluate --gt OUT/test/gt
--pred raw=OUT/test/input`` read it unchanged.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import sys
import warnings
import zlib
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from scipy import ndimage, signal

from .errors import EdeflareError, EventFileError, ParameterError
from .events import (
    EVENT_DTYPE,
    SensorSize,
    center_crop,
    check_events,
    check_sensor_size,
    merge_events,
)
from .io import EventSource, open_events, write_events
from .io._atomic import atomic_path
from .io.dsec import write_dsec_groups

__all__ = [
    "LOW_CONFIDENCE",
    "Alignment",
    "Circle",
    "LightSource",
    "NoiseEstimate",
    "PairConfig",
    "PairReport",
    "PairingError",
    "Polygon",
    "RecordingScan",
    "Signature",
    "clean_reference",
    "detect_light_source",
    "draw_noise",
    "estimate_background_rate",
    "estimate_offset",
    "glare_mask",
    "inject_noise",
    "light_mask",
    "load_lights",
    "pair_recordings",
    "parse_light",
    "parse_lights",
    "plot_alignment",
    "polarity_signature",
    "scan_recording",
]

MANIFEST_FORMAT = "edeflare-pairs/1"
LOW_CONFIDENCE = 0.1
"""Alignments below this confidence are reported with a warning."""


class PairingError(EdeflareError, ValueError):
    """Two recordings cannot be paired as asked (the message names the files and says why)."""


# ----------------------------------------------------------------------------- signatures


@dataclass(frozen=True, eq=False)
class Signature:
    """ON and OFF event counts in consecutive time bins: a recording's polarity signature.

    Bin ``i`` covers ``[t_start_us + i * bin_us, t_start_us + (i + 1) * bin_us)``.

    Parameters
    ----------
    t_start_us, bin_us : int
        Start of bin 0 and bin length (µs).
    on, off : numpy.ndarray
        Counts per bin, ``(n_bins,)``.
    """

    t_start_us: int
    bin_us: int
    on: np.ndarray = field(repr=False)
    off: np.ndarray = field(repr=False)

    @property
    def n_bins(self) -> int:
        """Number of bins."""
        return int(self.on.size)

    @property
    def t_end_us(self) -> int:
        """End of the last bin (exclusive)."""
        return self.t_start_us + self.n_bins * self.bin_us

    @property
    def n_events(self) -> int:
        """Events counted."""
        return int(self.on.sum(dtype=np.int64) + self.off.sum(dtype=np.int64))

    @property
    def overall_on_fraction(self) -> float:
        """ON events over all events (0.5 without events)."""
        n = self.n_events
        return float(self.on.sum(dtype=np.int64)) / n if n else 0.5

    def on_fraction(self, pseudocount: float = 0.0) -> np.ndarray:
        """ON fraction per bin, ``(on + k g) / (on + off + k)`` with ``g`` the overall fraction.

        The pseudocount ``k`` shrinks bins holding few events toward the
        recording's overall ON fraction ``g`` (empty bins get ``g`` whatever
        ``k``), so that sparse background bins do not look like strobe edges.

        Examples
        --------
        >>> sig = Signature(0, 10, np.array([3, 0, 0]), np.array([1, 2, 0]))
        >>> sig.on_fraction().tolist()
        [0.75, 0.0, 0.5]
        >>> sig.on_fraction(2.0).tolist()
        [0.6666666666666666, 0.25, 0.5]
        """
        on = self.on.astype(np.float64)
        n = on + self.off
        g = self.overall_on_fraction
        k = float(pseudocount)
        if k > 0:
            return (on + k * g) / (n + k)
        out = np.full(n.shape, g)
        np.divide(on, n, out=out, where=n > 0)
        return out

    def imbalance(self) -> np.ndarray:
        """ON events in excess of the overall ON fraction per bin: ``on - g (on + off)``.

        Examples
        --------
        >>> Signature(0, 10, np.array([3, 0, 1]), np.array([1, 2, 1])).imbalance().tolist()
        [1.0, -1.0, 0.0]
        """
        on = self.on.astype(np.float64)
        return on - self.overall_on_fraction * (on + self.off)

    def rebin(self, factor: int) -> Signature:
        """Sum blocks of ``factor`` bins (the last block may be partial).

        Examples
        --------
        >>> Signature(0, 10, np.array([1, 2, 3]), np.array([0, 1, 0])).rebin(2).on.tolist()
        [3, 3]
        """
        factor = int(factor)
        if factor < 1:
            raise ParameterError(f"rebin factor must be a positive int, got {factor}")
        if factor == 1:
            return self
        n = -(-self.n_bins // factor)
        pad = n * factor - self.n_bins
        on = np.pad(self.on.astype(np.int64), (0, pad)).reshape(n, factor).sum(axis=1)
        off = np.pad(self.off.astype(np.int64), (0, pad)).reshape(n, factor).sum(axis=1)
        return Signature(self.t_start_us, self.bin_us * factor, on, off)


class _SignatureAccumulator:
    """Grows ON/OFF bin counts chunk by chunk (events sorted, ``t >= t_start_us``)."""

    def __init__(self, t_start_us: int, bin_us: int) -> None:
        self.t_start_us = int(t_start_us)
        self.bin_us = int(bin_us)
        self.on = np.zeros(4096, dtype=np.uint32)
        self.off = np.zeros(4096, dtype=np.uint32)

    def add(self, t: np.ndarray, p: np.ndarray) -> None:
        if t.size == 0:
            return
        idx = (t - self.t_start_us) // self.bin_us
        lo, hi = int(idx[0]), int(idx[-1]) + 1
        if hi > self.on.size:
            size = max(hi, int(self.on.size * 1.5))
            self.on = np.pad(self.on, (0, size - self.on.size))
            self.off = np.pad(self.off, (0, size - self.off.size))
        rel = idx - lo
        total = np.bincount(rel, minlength=hi - lo)
        on = np.bincount(rel[p.astype(bool)], minlength=hi - lo)
        self.on[lo:hi] += on.astype(np.uint32)
        self.off[lo:hi] += (total - on).astype(np.uint32)

    def finish(self, t_end_us: int) -> Signature:
        n = max(0, -(-(int(t_end_us) - self.t_start_us) // self.bin_us))
        on = np.pad(self.on, (0, max(0, n - self.on.size)))[:n].copy()
        off = np.pad(self.off, (0, max(0, n - self.off.size)))[:n].copy()
        return Signature(self.t_start_us, self.bin_us, on, off)


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)):
        raise ParameterError(f"{name} must be a positive integer, got {value!r}")
    if isinstance(value, float) and not value.is_integer():
        raise ParameterError(f"{name} must be a whole number of µs, got {value!r}")
    if int(value) <= 0:
        raise ParameterError(f"{name} must be positive, got {value!r}")
    return int(value)


def _check_mask(mask: Any, sensor_size: SensorSize | None) -> tuple[np.ndarray, SensorSize]:
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != bool:
        raise ParameterError(f"mask must be a boolean (H, W) array, got {mask.dtype} {mask.shape}")
    size = (mask.shape[1], mask.shape[0])
    if sensor_size is not None and check_sensor_size(sensor_size) != size:
        raise ParameterError(f"mask shape {mask.shape} (H, W) does not match sensor {sensor_size}")
    return mask, size


def polarity_signature(
    events: np.ndarray,
    bin_us: int,
    *,
    t_start_us: int | None = None,
    t_end_us: int | None = None,
    sensor_size: SensorSize | None = None,
    mask: np.ndarray | None = None,
) -> Signature:
    """ON and OFF counts of ``events`` in bins of ``bin_us``: the strobe's polarity signature.

    Parameters
    ----------
    events : numpy.ndarray
        A sorted stream.
    bin_us : int
        Bin length (µs). A strobe edge is a burst of one polarity lasting a
        few hundred µs; bins of 0.1 ms resolve it, bins of 1 ms suit a
        coarse search.
    t_start_us, t_end_us : int, optional
        Span ``[t_start_us, t_end_us)`` to bin (default: first event to last
        event + 1); events outside are ignored.
    sensor_size : (width, height), optional
        Checked against the events (and the mask) when given.
    mask : numpy.ndarray of bool, optional
        ``(H, W)``: count only events on these pixels (e.g. around the strobe).

    Returns
    -------
    Signature

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 100, 150, 1200], [0, 1, 1, 0], [0, 0, 0, 0], [1, 1, 0, 0])
    >>> sig = polarity_signature(ev, 1000)
    >>> sig.on.tolist(), sig.off.tolist(), sig.on_fraction().round(3).tolist()
    ([2, 0], [1, 1], [0.667, 0.0])
    >>> polarity_signature(ev, 1000, mask=np.array([[False, True]])).on.tolist()
    [1, 0]
    """
    bin_us = _positive_int("bin_us", bin_us)
    check_events(events, sensor_size)
    if mask is not None:
        mask, size = _check_mask(mask, sensor_size)
        check_events(events, size)
    if t_start_us is None:
        t_start_us = int(events["t"][0]) if events.size else 0
    if t_end_us is None:
        t_end_us = int(events["t"][-1]) + 1 if events.size else int(t_start_us)
    if t_end_us < t_start_us:
        raise ParameterError(f"t_end_us {t_end_us} precedes t_start_us {t_start_us}")
    t = events["t"]
    part = events[np.searchsorted(t, t_start_us) : np.searchsorted(t, t_end_us)]
    if mask is not None:
        part = part[mask[part["y"], part["x"]]]
    acc = _SignatureAccumulator(int(t_start_us), bin_us)
    acc.add(part["t"], part["p"])
    return acc.finish(int(t_end_us))


@dataclass(frozen=True, eq=False)
class RecordingScan:
    """What one streaming pass over a recording learns (see :func:`scan_recording`).

    Attributes
    ----------
    path : str or None
        The file (None for an in-memory stream).
    sensor_size : (width, height)
    n_events : int
    t_first_us, t_last_us : int
        First and last timestamps (0 for an empty recording).
    signature : Signature
        Polarity signature from the first event, at the scan's bin.
    counts, on_counts : numpy.ndarray
        ``(H, W)`` int64 events (all, ON) per pixel.
    """

    path: str | None
    sensor_size: SensorSize
    n_events: int
    t_first_us: int
    t_last_us: int
    signature: Signature = field(repr=False)
    counts: np.ndarray = field(repr=False)
    on_counts: np.ndarray = field(repr=False)

    @property
    def duration_us(self) -> int:
        """``t_last_us - t_first_us + 1`` (0 when empty)."""
        return self.t_last_us - self.t_first_us + 1 if self.n_events else 0


def _progress(total: int | None, desc: str, enabled: bool, unit: str = "ev") -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        unit_scale=unit == "ev",
        disable=None if enabled else True,
        leave=False,
        file=sys.stderr,
        dynamic_ncols=True,
    )


def scan_recording(
    source: str | os.PathLike[str] | EventSource | np.ndarray,
    bin_us: int,
    *,
    sensor_size: SensorSize | None = None,
    mask: np.ndarray | None = None,
    progress: bool = False,
) -> RecordingScan:
    """One streaming pass: polarity signature, per-pixel counts, span and event count.

    Memory is one chunk of events plus the signature (8 bytes per bin: about
    80 kB per second of recording at 0.1 ms bins) and two ``(H, W)`` count maps.

    Parameters
    ----------
    source : path-like, EventSource or numpy.ndarray
        A file of any readable format, an opened one, or events in memory
        (then ``sensor_size`` is required).
    bin_us : int
        Bin of the signature (µs).
    sensor_size : (width, height), optional
        For files that record none; required for arrays.
    mask : numpy.ndarray of bool, optional
        ``(H, W)``: the signature counts only these pixels (the maps count all).
    progress : bool
        Show a progress bar.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([500, 900, 2500], [0, 1, 1], [0, 0, 1], [1, 0, 1])
    >>> scan = scan_recording(ev, 1000, sensor_size=(2, 2))
    >>> scan.n_events, scan.duration_us, scan.signature.on.tolist(), scan.counts.tolist()
    (3, 2001, [1, 0, 1], [[1, 1], [0, 1]])
    """
    bin_us = _positive_int("bin_us", bin_us)
    path: str | None
    if isinstance(source, np.ndarray):
        if sensor_size is None:
            raise ParameterError("scan_recording needs sensor_size for events in memory")
        size = check_sensor_size(sensor_size)
        check_events(source, size)
        chunks: Iterable[np.ndarray] = [source] if source.size else []
        total: int | None = source.size
        path = None
    else:
        src = source if isinstance(source, EventSource) else open_events(source, sensor_size)
        size = src.sensor_size
        chunks = src.chunks()
        total = src.n_events
        path = str(src.path)
    if mask is not None:
        mask, _ = _check_mask(mask, size)
    width, height = size
    counts = np.zeros(width * height, dtype=np.int64)
    on_counts = np.zeros(width * height, dtype=np.int64)
    acc: _SignatureAccumulator | None = None
    n = 0
    first = last = 0
    with _progress(total, f"scan {Path(path).name if path else 'events'}", progress) as bar:
        for chunk in chunks:
            if not chunk.size:
                continue
            if acc is None:
                first = int(chunk["t"][0])
                acc = _SignatureAccumulator(first, bin_us)
            last = int(chunk["t"][-1])
            flat = chunk["y"].astype(np.int64) * width + chunk["x"]
            on = chunk["p"].astype(bool)
            counts += np.bincount(flat, minlength=width * height)
            on_counts += np.bincount(flat[on], minlength=width * height)
            part = chunk if mask is None else chunk[mask[chunk["y"], chunk["x"]]]
            acc.add(part["t"], part["p"])
            n += chunk.size
            bar.update(chunk.size)
    signature = (
        acc.finish(last + 1)
        if acc is not None
        else Signature(0, bin_us, np.zeros(0, np.uint32), np.zeros(0, np.uint32))
    )
    return RecordingScan(
        path,
        size,
        n,
        first,
        last,
        signature,
        counts.reshape(height, width),
        on_counts.reshape(height, width),
    )


# ----------------------------------------------------------------------------- alignment


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


# ----------------------------------------------------------------------------- geometry


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"{what}: {text!r} is not a finite number")
    return value


@dataclass(frozen=True)
class Circle:
    """A round light source: centre ``(cx, cy)`` and radius ``r`` in pixels.

    A pixel belongs to it when its centre ``(x, y)`` satisfies
    ``(x - cx)**2 + (y - cy)**2 <= r**2``.

    Examples
    --------
    >>> Circle(2, 1, 1).mask((5, 3)).astype(int).tolist()
    [[0, 0, 1, 0, 0], [0, 1, 1, 1, 0], [0, 0, 1, 0, 0]]
    >>> str(Circle(320, 240, 15))
    'circle:320,240,15'
    """

    cx: float
    cy: float
    r: float

    def __post_init__(self) -> None:
        for name in ("cx", "cy", "r"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ParameterError(f"circle {name} must be a number, got {value!r}")
            if not math.isfinite(float(value)):
                raise ParameterError(f"circle {name} must be finite, got {value!r}")
        if not self.r > 0:
            raise ParameterError(f"circle radius must be positive, got {self.r!r}")

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether the points ``(x, y)`` lie in the disc."""
        return (x - self.cx) ** 2 + (y - self.cy) ** 2 <= self.r**2

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Euclidean distance from the points to the disc (0 inside)."""
        return np.maximum(0.0, np.hypot(x - self.cx, y - self.cy) - self.r)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)``."""
        return self.cx - self.r, self.cy - self.r, self.cx + self.r, self.cy + self.r

    def shifted(self, dx: float, dy: float) -> Circle:
        """The same circle moved by ``(dx, dy)`` (e.g. into crop coordinates)."""
        return Circle(self.cx + dx, self.cy + dy, self.r)

    def mask(self, sensor_size: SensorSize) -> np.ndarray:
        """``(H, W)`` bool: pixels of the sensor inside the circle."""
        return light_mask([self], sensor_size)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "circle", "cx", "cy", "r"}``."""
        return {"type": "circle", "cx": float(self.cx), "cy": float(self.cy), "r": float(self.r)}

    def __str__(self) -> str:
        return "circle:" + ",".join(f"{float(v):g}" for v in (self.cx, self.cy, self.r))


@dataclass(frozen=True)
class Polygon:
    """A light source of any outline: vertices ``((x1, y1), (x2, y2), ...)`` in pixels.

    A pixel belongs to it when its centre is inside by the even-odd rule,
    with points on left and top edges inside and on right and bottom edges
    outside, so an axis-aligned rectangle with corners ``(x0, y0)`` and
    ``(x1, y1)`` holds the pixels ``x0 <= x < x1``, ``y0 <= y < y1``, like an
    array slice.

    Examples
    --------
    >>> Polygon(((1, 0), (3, 0), (3, 2), (1, 2))).mask((4, 3)).astype(int).tolist()
    [[0, 1, 1, 0], [0, 1, 1, 0], [0, 0, 0, 0]]
    """

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        try:
            pts = tuple((float(x), float(y)) for x, y in self.points)
        except (TypeError, ValueError):
            raise ParameterError(
                f"polygon points must be (x, y) pairs, got {self.points!r}"
            ) from None
        if len(pts) < 3:
            raise ParameterError(f"a polygon needs at least 3 points, got {len(pts)}")
        if not all(math.isfinite(v) for pt in pts for v in pt):
            raise ParameterError("polygon points must be finite numbers")
        object.__setattr__(self, "points", pts)

    def _edges(self) -> Iterator[tuple[float, float, float, float]]:
        pts = self.points
        for i in range(len(pts)):
            (x1, y1), (x2, y2) = pts[i], pts[(i + 1) % len(pts)]
            yield x1, y1, x2, y2

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether the points lie inside (even-odd rule, half-open edges)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        inside = np.zeros(np.broadcast(x, y).shape, dtype=bool)
        for x1, y1, x2, y2 in self._edges():
            if y1 == y2:
                continue
            crosses = (y1 > y) != (y2 > y)
            x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            inside ^= crosses & (x < x_at)
        return inside

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Euclidean distance from the points to the polygon's area (0 inside)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        best = np.full(np.broadcast(x, y).shape, np.inf)
        for x1, y1, x2, y2 in self._edges():
            dx, dy = x2 - x1, y2 - y1
            length2 = dx * dx + dy * dy
            s = np.zeros_like(best) if length2 == 0 else ((x - x1) * dx + (y - y1) * dy) / length2
            s = np.clip(s, 0.0, 1.0)
            best = np.minimum(best, np.hypot(x - (x1 + s * dx), y - (y1 + s * dy)))
        return np.where(self.contains(x, y), 0.0, best)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)``."""
        xs, ys = zip(*self.points, strict=True)
        return min(xs), min(ys), max(xs), max(ys)

    def shifted(self, dx: float, dy: float) -> Polygon:
        """The same polygon moved by ``(dx, dy)``."""
        return Polygon(tuple((x + dx, y + dy) for x, y in self.points))

    def mask(self, sensor_size: SensorSize) -> np.ndarray:
        """``(H, W)`` bool: pixels of the sensor inside the polygon."""
        return light_mask([self], sensor_size)

    def to_dict(self) -> dict[str, Any]:
        """``{"type": "polygon", "points": [[x, y], ...]}``."""
        return {"type": "polygon", "points": [[x, y] for x, y in self.points]}

    def __str__(self) -> str:
        return "polygon:" + ",".join(f"{v:g}" for pt in self.points for v in pt)


LightSource = Circle | Polygon
"""A light source's outline on the sensor."""

_LIGHT_SYNTAX = "circle:CX,CY,R or polygon:X1,Y1,X2,Y2,X3,Y3,... (pixels)"


def parse_light(text: str) -> LightSource:
    """Parse ``circle:CX,CY,R`` or ``polygon:X1,Y1,X2,Y2,...`` (pixel coordinates).

    Raises
    ------
    ParameterError
        Naming the string and the expected syntax.

    Examples
    --------
    >>> parse_light("circle:320,240,15")
    Circle(cx=320.0, cy=240.0, r=15.0)
    >>> parse_light("polygon:0,0,4,0,4,2").points
    ((0.0, 0.0), (4.0, 0.0), (4.0, 2.0))
    """
    kind, sep, rest = str(text).strip().partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in ("circle", "polygon"):
        raise ParameterError(f"light {text!r}: expected {_LIGHT_SYNTAX}")
    parts = [s.strip() for s in rest.split(",")]
    if parts == [""]:
        parts = []
    values = [_number(s, f"light {text!r}") for s in parts]
    try:
        if kind == "circle":
            if len(values) != 3:
                raise ParameterError(f"a circle needs 3 numbers CX,CY,R, got {len(values)}")
            return Circle(*values)
        if len(values) % 2 or len(values) < 6:
            raise ParameterError(
                f"a polygon needs an even number (>= 6) of coordinates, got {len(values)}"
            )
        return Polygon(tuple(zip(values[::2], values[1::2], strict=True)))
    except ParameterError as exc:
        raise ParameterError(f"light {text!r}: {exc}; expected {_LIGHT_SYNTAX}") from None


def _light_from_json(item: Any) -> LightSource:
    if isinstance(item, str):
        return parse_light(item)
    if not isinstance(item, dict):
        raise ParameterError(f"a light must be an object or a string, got {item!r}")
    kind = item.get("type")
    if kind == "circle":
        unknown = set(item) - {"type", "cx", "cy", "r"}
        if unknown or not {"cx", "cy", "r"} <= set(item):
            raise ParameterError(f"a circle needs exactly cx, cy, r; got {sorted(item)}")
        return Circle(item["cx"], item["cy"], item["r"])
    if kind == "polygon":
        if set(item) != {"type", "points"}:
            raise ParameterError(f"a polygon needs exactly points; got {sorted(item)}")
        return Polygon(tuple(tuple(pt) for pt in item["points"]))
    raise ParameterError(f"light type must be 'circle' or 'polygon', got {kind!r}")


def load_lights(path: str | os.PathLike[str]) -> list[LightSource]:
    """Read light sources from JSON: a list (or ``{"lights": [...]}``) of shapes.

    Each shape is ``{"type": "circle", "cx": .., "cy": .., "r": ..}``,
    ``{"type": "polygon", "points": [[x, y], ...]}`` or a string as for
    :func:`parse_light`.

    Raises
    ------
    EventFileError
        Naming the file: missing, not JSON, or a shape it cannot read.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "lights.json"
    >>> _ = p.write_text('[{"type": "circle", "cx": 10, "cy": 5, "r": 3}, "circle:1,1,1"]')
    >>> [str(s) for s in load_lights(p)]
    ['circle:10,5,3', 'circle:1,1,1']
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise EventFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise EventFileError(path, f"is not a JSON file of light sources ({exc})") from None
    if isinstance(data, dict) and set(data) == {"lights"}:
        data = data["lights"]
    if not isinstance(data, list):
        raise EventFileError(path, 'must hold a list of lights (or {"lights": [...]})')
    lights = []
    for i, item in enumerate(data):
        try:
            lights.append(_light_from_json(item))
        except ParameterError as exc:
            raise EventFileError(path, f"light {i}: {exc}") from None
    return lights


def parse_lights(specs: Iterable[str]) -> list[LightSource]:
    """Shapes from strings (:func:`parse_light`) and ``*.json`` files (:func:`load_lights`).

    Examples
    --------
    >>> [str(s) for s in parse_lights(["circle:5,5,2", "polygon:0,0,2,0,2,2"])]
    ['circle:5,5,2', 'polygon:0,0,2,0,2,2']
    """
    lights: list[LightSource] = []
    for spec in specs:
        spec = str(spec)
        if spec.lower().endswith(".json") and not spec.lower().startswith(("circle:", "polygon:")):
            lights.extend(load_lights(spec))
        else:
            lights.append(parse_light(spec))
    return lights


def _window(
    shape: LightSource, margin: float, sensor_size: SensorSize
) -> tuple[slice, slice, np.ndarray, np.ndarray] | None:
    """Rows/columns of the sensor within ``margin`` of a shape's bounds, and their pixel grid."""
    width, height = sensor_size
    x0, y0, x1, y1 = shape.bounds()
    c0, c1 = max(0, math.floor(x0 - margin)), min(width, math.ceil(x1 + margin) + 1)
    r0, r1 = max(0, math.floor(y0 - margin)), min(height, math.ceil(y1 + margin) + 1)
    if c0 >= c1 or r0 >= r1:
        return None
    yy, xx = np.mgrid[r0:r1, c0:c1]
    return slice(r0, r1), slice(c0, c1), xx.astype(np.float64), yy.astype(np.float64)


def light_mask(lights: Sequence[LightSource], sensor_size: SensorSize) -> np.ndarray:
    """``(H, W)`` bool: pixels whose centre lies inside any of the light sources.

    Examples
    --------
    >>> square = Polygon(((0, 0), (2, 0), (2, 1), (0, 1)))  # pixels (0, 0) and (1, 0)
    >>> int(light_mask([Circle(5, 5, 2), square], (10, 10)).sum())
    15
    """
    width, height = check_sensor_size(sensor_size)
    mask = np.zeros((height, width), dtype=bool)
    for shape in lights:
        win = _window(shape, 0.0, (width, height))
        if win is not None:
            rows, cols, xx, yy = win
            mask[rows, cols] |= shape.contains(xx, yy)
    return mask


def glare_mask(
    lights: Sequence[LightSource], sensor_size: SensorSize, glare_radius_px: float
) -> np.ndarray:
    """``(H, W)`` bool: the glare zone, within ``glare_radius_px`` of a source but inside none.

    A pixel is in the zone when the Euclidean distance from its centre to the
    nearest light source's area (disc or polygon) is at most
    ``glare_radius_px``, and its centre is inside no source. For a circle
    ``(cx, cy, r)`` this is the ring ``r < d <= r + glare_radius_px`` around
    the centre. A radius of 0 gives an empty zone.

    Examples
    --------
    >>> m = glare_mask([Circle(3, 3, 1)], (7, 7), 1)
    >>> for row in m.astype(int)[1:6]:
    ...     print(*row)
    0 0 0 1 0 0 0
    0 0 1 0 1 0 0
    0 1 0 0 0 1 0
    0 0 1 0 1 0 0
    0 0 0 1 0 0 0
    """
    width, height = check_sensor_size(sensor_size)
    radius = float(glare_radius_px)
    if not math.isfinite(radius) or radius < 0:
        raise ParameterError(f"glare_radius_px must be a finite number >= 0, got {glare_radius_px}")
    zone = np.zeros((height, width), dtype=bool)
    if radius == 0:
        return zone
    for shape in lights:
        win = _window(shape, radius, (width, height))
        if win is not None:
            rows, cols, xx, yy = win
            zone[rows, cols] |= shape.distance(xx, yy) <= radius
    return zone & ~light_mask(lights, (width, height))


def _pixel_mask_of(events: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return mask[events["y"], events["x"]]


def clean_reference(
    events: np.ndarray,
    sensor_size: SensorSize,
    lights: Sequence[LightSource],
    *,
    glare_radius_px: float = 40.0,
) -> np.ndarray:
    """Remove residual glare from a reference stream, keeping the light sources themselves.

    Events on pixels of the glare zone (:func:`glare_mask`) are removed;
    every other event is kept, in particular those on the sources' own
    pixels (the light is part of the scene) and those farther than
    ``glare_radius_px`` from every source.

    Parameters
    ----------
    events : numpy.ndarray
        The reference stream (not modified).
    sensor_size : (width, height)
    lights : sequence of Circle or Polygon
        Light sources in sensor pixel coordinates.
    glare_radius_px : float
        Width of the glare zone around each source (pixels).

    Returns
    -------
    numpy.ndarray
        A new stream without the glare zone's events.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 1, 2], [5, 7, 9], [5, 5, 5], [1, 1, 1])
    >>> clean_reference(ev, (12, 12), [Circle(5, 5, 1)], glare_radius_px=2)["x"].tolist()
    [5, 9]
    """
    size = check_sensor_size(sensor_size)
    check_events(events, size)
    zone = glare_mask(lights, size, glare_radius_px)
    return events[~_pixel_mask_of(events, zone)]


def _count_map(data: np.ndarray, sensor_size: SensorSize | None) -> np.ndarray:
    """``(H, W)`` float64 counts from events (needs ``sensor_size``) or a 2-D map."""
    if isinstance(data, np.ndarray) and data.dtype == EVENT_DTYPE:
        if sensor_size is None:
            raise ParameterError("sensor_size is required with events")
        width, height = check_sensor_size(sensor_size)
        check_events(data, (width, height))
        flat = data["y"].astype(np.int64) * width + data["x"]
        return np.bincount(flat, minlength=width * height).reshape(height, width).astype(float)
    counts = np.asarray(data, dtype=np.float64)
    if counts.ndim != 2:
        raise ParameterError(f"expected events or an (H, W) count map, got shape {counts.shape}")
    if sensor_size is not None and check_sensor_size(sensor_size) != counts.shape[::-1]:
        raise ParameterError(f"count map {counts.shape} (H, W) does not match sensor {sensor_size}")
    if not np.isfinite(counts).all() or (counts < 0).any():
        raise ParameterError("count map must hold finite non-negative values")
    return counts


def detect_light_source(
    data: np.ndarray,
    sensor_size: SensorSize | None = None,
    *,
    sigma_px: float = 2.0,
    level: float = 0.5,
    max_sources: int = 1,
    min_area_px: int = 4,
    margin_px: float = 1.0,
) -> list[Circle]:
    """Find the brightest compact region(s) of the event density: the light source(s).

    The per-pixel event counts are median-filtered (3x3, removing isolated hot
    pixels), smoothed with a Gaussian of ``sigma_px``, and thresholded at
    ``level`` times their maximum. Connected regions (8-connectivity) of at
    least ``min_area_px`` pixels are ranked by their peak density, and the
    first ``max_sources`` become circles: centre at the density-weighted
    centroid, radius ``sqrt(area / pi) + margin_px`` (the smoothing pulls the
    threshold contour inside the source's rim; the margin keeps the rim a
    source pixel rather than glare). Run it on the reference pass, where
    the source is not spread by the filter; sources need a radius of at least
    about 2 pixels to survive the median filter.

    Parameters
    ----------
    data : numpy.ndarray
        Events (with ``sensor_size``) or an ``(H, W)`` count map.
    sensor_size : (width, height), optional
    sigma_px : float
        Gaussian smoothing (pixels).
    level : float
        Threshold as a fraction of the smoothed maximum.
    max_sources : int
        How many regions to return at most.
    min_area_px : int
        Smallest region kept (pixels above the threshold).
    margin_px : float
        Added to each circle's equivalent radius.

    Returns
    -------
    list of Circle
        Brightest first.

    Raises
    ------
    ParameterError
        No events, or no region large enough.

    Examples
    --------
    >>> counts = np.zeros((40, 60)); yy, xx = np.mgrid[:40, :60]
    >>> counts[(xx - 30) ** 2 + (yy - 20) ** 2 <= 25] = 100.0
    >>> counts[3, 3] = 1e4  # a hot pixel
    >>> (c,) = detect_light_source(counts)
    >>> round(c.cx), round(c.cy), round(c.r)
    (30, 20, 6)
    """
    counts = _count_map(data, sensor_size)
    if not 0 < level < 1:
        raise ParameterError(f"level must lie in (0, 1), got {level}")
    if int(max_sources) < 1:
        raise ParameterError(f"max_sources must be >= 1, got {max_sources}")
    smooth = ndimage.median_filter(counts, size=3, mode="nearest")
    if sigma_px > 0:
        smooth = ndimage.gaussian_filter(smooth, float(sigma_px), mode="nearest")
    peak = float(smooth.max()) if smooth.size else 0.0
    if peak <= 0:
        raise ParameterError("no events (after removing isolated pixels): no light source found")
    labels, n = ndimage.label(smooth >= level * peak, structure=np.ones((3, 3), dtype=bool))
    index = np.arange(1, n + 1)
    area = np.asarray(ndimage.sum_labels(np.ones_like(smooth), labels, index))
    peaks = np.asarray(ndimage.maximum(smooth, labels, index))
    order = [int(i) for i in np.argsort(-peaks, kind="stable") if area[i] >= min_area_px]
    if not order:
        raise ParameterError(
            f"no bright region of at least {min_area_px} pixels; give the light as circle:CX,CY,R"
        )
    lights = []
    for i in order[: int(max_sources)]:
        cy, cx = ndimage.center_of_mass(smooth, labels, i + 1)
        radius = math.sqrt(area[i] / math.pi) + max(0.0, float(margin_px))
        lights.append(Circle(float(cx), float(cy), radius))
    return lights


# ----------------------------------------------------------------------------- noise


@dataclass(frozen=True)
class NoiseEstimate:
    """The sensor's background activity, measured by :func:`estimate_background_rate`.

    Attributes
    ----------
    rate_hz : float
        Background events per second per pixel.
    on_fraction : float
        Fraction of ON events in the background.
    pixels : int
        Pixels the estimate pools (the quiet tiles' usable pixels).
    tiles : int
        Quiet tiles pooled.
    """

    rate_hz: float
    on_fraction: float
    pixels: int
    tiles: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return dataclasses.asdict(self)


def estimate_background_rate(
    data: np.ndarray,
    duration_us: int,
    sensor_size: SensorSize | None = None,
    *,
    on_counts: np.ndarray | None = None,
    exclude: np.ndarray | None = None,
    tile_px: int = 16,
    quantile: float = 0.25,
    hot_factor: float = 10.0,
) -> NoiseEstimate:
    """Per-pixel background event rate (Hz) from the quiet regions of a recording.

    1. Pixels in ``exclude`` (e.g. light sources and their glare) and hot
       pixels (more than ``hot_factor`` times the median count + 1) are unusable.
    2. The sensor is cut into ``tile_px`` x ``tile_px`` tiles; tiles with
       fewer than half their pixels usable are dropped. Each tile's rate is
       its usable pixels' mean count over the duration.
    3. The floor is the ``quantile`` of the tile rates; quiet tiles are those
       within three Poisson standard errors of the floor (so on a sensor that
       sees only noise nearly every tile is quiet, and in a busy scene only
       the static ones are).
    4. The rate is the pooled mean over the quiet tiles' usable pixels, and
       the ON fraction their pooled ON share.

    Parameters
    ----------
    data : numpy.ndarray
        Events (with ``sensor_size``) or an ``(H, W)`` count map.
    duration_us : int
        Span the counts were collected over (µs).
    on_counts : numpy.ndarray, optional
        ``(H, W)`` ON counts, for the ON fraction with a count map (else 0.5).
    exclude : numpy.ndarray of bool, optional
        ``(H, W)`` pixels to ignore.

    Returns
    -------
    NoiseEstimate

    Examples
    --------
    >>> counts = np.random.default_rng(0).poisson(3.0, (64, 64))  # 3 events in 2 s
    >>> counts[:16, :16] += 50  # a busy corner
    >>> est = estimate_background_rate(counts, 2_000_000)
    >>> round(est.rate_hz, 1), est.tiles
    (1.5, 15)
    """
    duration_us = _positive_int("duration_us", duration_us)
    if isinstance(data, np.ndarray) and data.dtype == EVENT_DTYPE and on_counts is None:
        counts = _count_map(data, sensor_size)
        on_counts = _count_map(data[data["p"] == 1], sensor_size)
    else:
        counts = _count_map(data, sensor_size)
    height, width = counts.shape
    if on_counts is not None:
        on_counts = np.asarray(on_counts, dtype=np.float64)
        if on_counts.shape != counts.shape:
            raise ParameterError(f"on_counts shape {on_counts.shape} differs from {counts.shape}")
    usable = np.ones_like(counts, dtype=bool)
    if exclude is not None:
        exclude, _ = _check_mask(exclude, (width, height))
        usable &= ~exclude
    if not 0 < quantile < 1:
        raise ParameterError(f"quantile must lie in (0, 1), got {quantile}")
    tile_px = _positive_int("tile_px", tile_px)
    if usable.any():
        usable &= counts <= hot_factor * (float(np.median(counts[usable])) + 1.0)
    yy, xx = np.mgrid[:height, :width]
    n_tx = -(-width // tile_px)
    tile = ((yy // tile_px) * n_tx + xx // tile_px)[usable]
    n_tiles = n_tx * -(-height // tile_px)
    n_px = np.bincount(tile, minlength=n_tiles).astype(np.float64)
    sums = np.bincount(tile, weights=counts[usable], minlength=n_tiles)
    on_sums = (
        np.bincount(tile, weights=on_counts[usable], minlength=n_tiles)
        if on_counts is not None
        else None
    )
    tile_area = np.bincount(
        ((yy // tile_px) * n_tx + xx // tile_px).ravel(), minlength=n_tiles
    ).astype(np.float64)
    good = n_px >= 0.5 * tile_area
    if not good.any():
        raise ParameterError(
            "no quiet region to measure the background rate in (everything excluded); "
            "give the rate explicitly"
        )
    seconds = duration_us / 1e6
    rates = sums[good] / n_px[good] / seconds
    floor = float(np.quantile(rates, quantile))
    typical_px = float(np.median(n_px[good]))
    se = math.sqrt(max(floor, 1.0 / seconds) * seconds * typical_px) / (seconds * typical_px)
    quiet = rates <= floor + 3.0 * se
    total_px = float(n_px[good][quiet].sum())
    total = float(sums[good][quiet].sum())
    rate = total / total_px / seconds
    on_fraction = 0.5
    if on_sums is not None and total > 0:
        on_fraction = float(on_sums[good][quiet].sum()) / total
    return NoiseEstimate(float(rate), float(on_fraction), int(total_px), int(quiet.sum()))


def draw_noise(
    sensor_size: SensorSize,
    rate_hz: float,
    t_start_us: int,
    t_end_us: int,
    *,
    mask: np.ndarray | None = None,
    on_fraction: float = 0.5,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Poisson background events: ``rate_hz`` per pixel on the mask's pixels over a span.

    Every pixel of ``mask`` (all pixels by default) fires as an independent
    Poisson process of rate ``rate_hz`` over ``[t_start_us, t_end_us)``;
    polarities are ON with probability ``on_fraction``. Draws: the total
    count, then pixels, times and polarities, so a seed gives one stream.

    Examples
    --------
    >>> ev = draw_noise((100, 100), 2.0, 0, 1_000_000, rng=0)  # 2 Hz x 10,000 pixels x 1 s
    >>> 19_500 < ev.size < 20_500, bool((np.diff(ev["t"]) >= 0).all())
    (True, True)
    """
    width, height = check_sensor_size(sensor_size)
    rate = float(rate_hz)
    if not math.isfinite(rate) or rate < 0:
        raise ParameterError(f"rate_hz must be a finite number >= 0, got {rate_hz}")
    if not 0 <= on_fraction <= 1:
        raise ParameterError(f"on_fraction must lie in [0, 1], got {on_fraction}")
    if t_end_us < t_start_us:
        raise ParameterError(f"t_end_us {t_end_us} precedes t_start_us {t_start_us}")
    rng = np.random.default_rng(rng)
    if mask is None:
        pixels = None
        n_pixels = width * height
    else:
        mask, _ = _check_mask(mask, (width, height))
        pixels = np.flatnonzero(mask)
        n_pixels = pixels.size
    expected = rate * (int(t_end_us) - int(t_start_us)) / 1e6 * n_pixels
    n = int(rng.poisson(expected)) if expected > 0 else 0
    which = rng.integers(0, max(n_pixels, 1), n)
    flat = which if pixels is None else pixels[which]
    t = rng.integers(int(t_start_us), max(int(t_end_us), int(t_start_us) + 1), n)
    p = rng.random(n) < on_fraction
    order = np.argsort(t, kind="stable")
    out = np.empty(n, dtype=EVENT_DTYPE)
    out["t"] = t[order]
    out["x"] = (flat % width)[order]
    out["y"] = (flat // width)[order]
    out["p"] = p[order]
    return out


def inject_noise(
    events: np.ndarray,
    sensor_size: SensorSize,
    rate_hz: float,
    t_start_us: int,
    t_end_us: int,
    *,
    mask: np.ndarray | None = None,
    on_fraction: float = 0.5,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """``events`` merged with :func:`draw_noise` (a new sorted stream; ties keep ``events`` first).

    Parameters
    ----------
    events : numpy.ndarray
        The cleaned reference (not modified).
    sensor_size : (width, height)
    rate_hz : float
        Per-pixel rate, e.g. :attr:`NoiseEstimate.rate_hz`.
    t_start_us, t_end_us : int
        Span of the noise.
    mask : numpy.ndarray of bool, optional
        ``(H, W)`` pixels that get noise (e.g. the glare zone that cleaning
        emptied); all pixels by default.
    on_fraction : float
    rng : numpy.random.Generator or int, optional

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([10], [0], [0], [1])
    >>> out = inject_noise(ev, (10, 10), 100.0, 0, 100_000, rng=1)
    >>> out.size > ev.size, ev.size
    (True, 1)
    """
    check_events(events, sensor_size)
    noise = draw_noise(
        sensor_size, rate_hz, t_start_us, t_end_us, mask=mask, on_fraction=on_fraction, rng=rng
    )
    return merge_events(events, noise)


# ----------------------------------------------------------------------------- plot

_OBS_COLOR = (230, 120, 20)
_REF_COLOR = (20, 110, 200)


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=size)


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not hi > lo:
        return [lo]
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step) * step
    return [first + i * step for i in range(int((hi - first) / step) + 1)]


def _panel(
    draw: ImageDraw.ImageDraw,
    box: tuple[int, int, int, int],
    series: Sequence[tuple[np.ndarray, np.ndarray, tuple[int, int, int], str]],
    xlim: tuple[float, float],
    ylim: tuple[float, float],
    title: str,
    xlabel: str,
    vline: float | None = None,
) -> None:
    x0, y0, x1, y1 = box
    font, small = _font(14), _font(12)
    draw.text((x0, y0 - 20), title, fill=(0, 0, 0), font=font)
    draw.rectangle(box, outline=(0, 0, 0))
    (xa, xb), (ya, yb) = xlim, ylim

    def px(x: np.ndarray) -> np.ndarray:
        return x0 + (np.asarray(x, dtype=np.float64) - xa) / (xb - xa or 1) * (x1 - x0)

    def py(y: np.ndarray) -> np.ndarray:
        return y1 - (np.asarray(y, dtype=np.float64) - ya) / (yb - ya or 1) * (y1 - y0)

    for tx in _ticks(xa, xb):
        u = float(px(tx))
        draw.line([(u, y1), (u, y1 + 4)], fill=(0, 0, 0))
        draw.text((u, y1 + 6), f"{tx:g}", fill=(0, 0, 0), font=small, anchor="mt")
    for ty in _ticks(ya, yb, 4):
        v = float(py(ty))
        draw.line([(x0 - 4, v), (x0, v)], fill=(0, 0, 0))
        draw.line([(x0, v), (x1, v)], fill=(230, 230, 230))
        draw.text((x0 - 6, v), f"{ty:g}", fill=(0, 0, 0), font=small, anchor="rm")
    draw.text(((x0 + x1) / 2, y1 + 22), xlabel, fill=(0, 0, 0), font=small, anchor="mt")
    if vline is not None and xa <= vline <= xb:
        u = float(px(vline))
        draw.line([(u, y0), (u, y1)], fill=(120, 120, 120), width=1)
    legend_x = float(x1)
    for _, _, color, label in reversed(series):  # legend in the title row, right-aligned
        if label:
            draw.text((legend_x, y0 - 20), label, fill=color, font=font, anchor="ra")
            legend_x -= font.getlength(label) + 16
    for k, (xs, ys, color, _) in enumerate(series):
        keep = np.isfinite(ys) & (xs >= xa) & (xs <= xb)
        pts = list(
            zip(
                px(xs[keep]).tolist(),
                np.clip(py(ys[keep]), y0, y1).tolist(),
                strict=True,
            )
        )
        if len(pts) > 1:
            draw.line(pts, fill=color, width=2 if k == 0 else 1)


def plot_alignment(
    obs: Signature,
    ref: Signature,
    alignment: Alignment,
    path: str | os.PathLike[str] | None = None,
    *,
    span_us: int | None = None,
    expected_offset_us: float | None = None,
    pseudocount: float = 4.0,
) -> np.ndarray:
    """Picture both signatures before and after alignment, and the correlation curve.

    Top: the ON fraction of both passes over ``span_us`` (default 40 coarse
    bins) with the reference placed by ``expected_offset_us`` (default: the
    recordings' starts aligned); middle: the same with the reference shifted
    by the found offset; bottom: correlation against offset. The span is
    where the observation's polarity activity is strongest.

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 3)``; also written to ``path`` (PNG) when given.

    Examples
    --------
    >>> sig = Signature(0, 100, np.array([5, 0, 0, 5] * 50), np.array([0, 5, 0, 0] * 50))
    >>> a = estimate_offset(sig, sig, max_offset_us=2_000)
    >>> plot_alignment(sig, sig, a).shape
    (760, 1000, 3)
    """
    fine = obs.bin_us
    span = int(span_us) if span_us is not None else 40 * alignment.bin_us
    span = max(span, 4 * fine)
    prior = ref.t_start_us - obs.t_start_us if expected_offset_us is None else expected_offset_us
    offset = alignment.offset_us
    # Where to look: the span of the observation with the most polarity activity.
    activity = np.abs(obs.on.astype(np.float64) - obs.off)
    n_span = max(1, min(obs.n_bins, span // fine))
    csum = np.concatenate([[0.0], np.cumsum(activity)])
    moving = csum[n_span:] - csum[:-n_span]
    start_bin = int(np.argmax(moving)) if moving.size else 0
    t0 = obs.t_start_us + start_bin * fine
    fo, fr = obs.on_fraction(pseudocount), ref.on_fraction(pseudocount)
    xo = (obs.t_start_us + (np.arange(obs.n_bins) + 0.5) * fine - t0) / 1000
    xr_ref = ref.t_start_us + (np.arange(ref.n_bins) + 0.5) * fine - t0
    width, height = 1000, 760
    canvas = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    xlim = (0.0, span / 1000)
    labels = ("observation (filter)", "reference")
    for k, (shift, title) in enumerate(
        (
            (prior, f"before: reference shifted by {prior / 1000:.3f} ms"),
            (offset, f"after alignment: reference shifted by {offset / 1000:.3f} ms"),
        )
    ):
        box = (70, 40 + k * 240, width - 30, 40 + k * 240 + 170)
        _panel(
            draw,
            box,
            [
                (xo, fo, _OBS_COLOR, labels[0]),
                ((xr_ref - shift) / 1000, fr, _REF_COLOR, labels[1]),
            ],
            xlim,
            (0.0, 1.0),
            title,
            f"time (ms) from t = {t0} us of the observation; y: ON fraction",
        )
    lags = alignment.lags_us / 1000
    scores = alignment.scores
    finite = scores[np.isfinite(scores)]
    ylo = min(0.0, float(finite.min())) if finite.size else -1.0
    second = alignment.second_peak
    title = (
        f"correlation vs offset: peak {alignment.correlation:.3f} at {offset / 1000:.3f} ms, "
        f"second peak {second:.3f}, confidence {alignment.confidence:.3f}"
        if math.isfinite(second)
        else f"correlation vs offset: peak {alignment.correlation:.3f} at {offset / 1000:.3f} ms, "
        f"confidence {alignment.confidence:.3f}"
    )
    xl = (
        (float(lags[0]), float(lags[-1]))
        if lags.size > 1
        else (offset / 1000 - 1, offset / 1000 + 1)
    )
    _panel(
        draw,
        (70, 40 + 2 * 240, width - 30, 40 + 2 * 240 + 170),
        [(lags, scores, (40, 40, 40), "")],
        xl,
        (ylo, 1.0),
        title,
        "offset t_reference - t_observation (ms)",
        vline=offset / 1000,
    )
    image = np.asarray(canvas)
    if path is not None:
        from .viz import save_image

        save_image(path, image)
    return image


# ----------------------------------------------------------------------------- pipeline


_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class PairConfig:
    """How :func:`pair_recordings` turns two passes into paired windows.

    Parameters
    ----------
    name : str, optional
        Scene name, the prefix of its files (default: the observation's file stem).
    split : str
        Sub-folder of the output (``test``: E-Flare-R is a test set).
    sensor_size : (width, height), optional
        For files that record none.
    bin_us, refine_bin_us : int
        Coarse search bin and signature (fine) bin of the alignment.
    max_offset_us : int
        Half-width of the offset search (see :func:`estimate_offset`).
    expected_offset_us : int, optional
        Centre of the search (default: the recordings' first events aligned).
    min_confidence : float
        Refuse alignments below this confidence (0: never refuse; below
        :data:`LOW_CONFIDENCE` a warning is issued).
    lights : tuple of Circle or Polygon
        Light sources in full-sensor pixel coordinates.
    detect_light : bool
        Add the brightest compact region of the reference (:func:`detect_light_source`).
    glare_radius_px : float
        Width of the glare zone removed from the reference around each source.
    noise_rate_hz : float, optional
        Background noise rate per pixel to inject; None measures it (and its
        ON fraction) on the observation (:func:`estimate_background_rate`);
        a given rate injects 50 % ON events; 0 injects none.
    noise_region : {"cleaned", "all"}
        Where noise is injected: the glare zone that cleaning emptied
        (default; the rest of the reference keeps its own recorded
        background activity, which noise there would double), or every pixel.
    crop : (width, height), optional
        Centre crop (default 640x480, the paper's); None keeps the full sensor.
    window_us : int
        Length of one output sequence (default 100 ms, the paper's); windows
        are aligned to multiples of it on the observation's clock and only
        complete ones within the overlap of both passes are written.
    seed : int
        Seeds the noise: window ``k`` draws from
        ``SeedSequence([seed, crc32(name), k])``.
    stream_files : bool
        Also write each window's input and ground truth as separate DSEC
        files under ``split/input`` and ``split/gt`` (for ``edeflare
        deflare`` and ``edeflare evaluate``).
    """

    name: str | None = None
    split: str = "test"
    sensor_size: SensorSize | None = None
    bin_us: int = 1_000
    refine_bin_us: int = 100
    max_offset_us: int = 1_000_000
    expected_offset_us: int | None = None
    min_confidence: float = 0.0
    lights: tuple[LightSource, ...] = ()
    detect_light: bool = False
    glare_radius_px: float = 40.0
    noise_rate_hz: float | None = None
    noise_region: str = "cleaned"
    crop: SensorSize | None = (640, 480)
    window_us: int = 100_000
    seed: int = 0
    stream_files: bool = True

    def __post_init__(self) -> None:
        if self.name is not None and not _NAME.fullmatch(self.name):
            raise ParameterError(
                f"name must be letters, digits, '_', '.', '-' (not starting with them), "
                f"got {self.name!r}"
            )
        if not _NAME.fullmatch(self.split):
            raise ParameterError(f"split must be a plain folder name, got {self.split!r}")
        if self.sensor_size is not None:
            object.__setattr__(self, "sensor_size", check_sensor_size(self.sensor_size))
        if self.crop is not None:
            object.__setattr__(self, "crop", check_sensor_size(self.crop))
        for key in ("bin_us", "refine_bin_us", "window_us"):
            _positive_int(key, getattr(self, key))
        if self.bin_us % self.refine_bin_us:
            raise ParameterError(
                f"bin_us {self.bin_us} must be a multiple of refine_bin_us {self.refine_bin_us}"
            )
        if self.max_offset_us < 0:
            raise ParameterError(f"max_offset_us must be >= 0, got {self.max_offset_us}")
        if not 0 <= self.min_confidence <= 1:
            raise ParameterError(f"min_confidence must lie in [0, 1], got {self.min_confidence}")
        for light in self.lights:
            if not isinstance(light, (Circle, Polygon)):
                raise ParameterError(f"lights must be Circle or Polygon, got {light!r}")
        object.__setattr__(self, "lights", tuple(self.lights))
        if not math.isfinite(self.glare_radius_px) or self.glare_radius_px < 0:
            raise ParameterError(f"glare_radius_px must be >= 0, got {self.glare_radius_px}")
        if self.noise_rate_hz is not None and (
            not math.isfinite(self.noise_rate_hz) or self.noise_rate_hz < 0
        ):
            raise ParameterError(f"noise_rate_hz must be >= 0, got {self.noise_rate_hz}")
        if self.noise_region not in ("cleaned", "all"):
            raise ParameterError(
                f"noise_region must be 'cleaned' or 'all', got {self.noise_region!r}"
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)):
            raise ParameterError(f"seed must be an int, got {self.seed!r}")
        if self.seed < 0:
            raise ParameterError(f"seed must be >= 0, got {self.seed}")


@dataclass(frozen=True)
class PairReport:
    """What :func:`pair_recordings` did.

    Attributes
    ----------
    name : str
        Scene name.
    alignment : Alignment
    lights : tuple of Circle or Polygon
        Light sources used (given and detected), full-sensor coordinates.
    noise_rate_hz : float
        Noise injected per pixel and second.
    noise : NoiseEstimate or None
        The measurement, when the rate was measured.
    files : list of Path
        Sequence files written.
    manifest_path, plot_path : Path
    entry : dict
        The scene's manifest entry.
    """

    name: str
    alignment: Alignment
    lights: tuple[LightSource, ...]
    noise_rate_hz: float
    noise: NoiseEstimate | None
    files: list[Path]
    manifest_path: Path
    plot_path: Path
    entry: dict[str, Any] = field(repr=False)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _read_manifest(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        raise EventFileError(
            path, "is not a readable manifest; write the pairs to another folder"
        ) from None
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        fmt = data.get("format") if isinstance(data, dict) else None
        raise EventFileError(
            path,
            f"belongs to another kind of dataset (format {fmt!r}, not {MANIFEST_FORMAT!r}); "
            "write the pairs to another folder",
        )
    if not isinstance(data.get("scenes"), dict):
        raise EventFileError(path, "has no 'scenes'; write the pairs to another folder")
    return data


def _file_info(source: EventSource, scan: RecordingScan) -> dict[str, Any]:
    return {
        "file": source.path.name,
        "path": str(source.path.resolve()),
        "format": source.format,
        "bytes": source.path.stat().st_size,
        "events": scan.n_events,
        "sensor_size": list(scan.sensor_size),
        "t_first_us": scan.t_first_us,
        "t_last_us": scan.t_last_us,
    }


def _remove_stale(folders: Sequence[Path], name: str, keep: set[str]) -> None:
    """Delete the scene's ``NAME_dddd.h5`` files this run did not write, and killed runs' temps."""
    pattern = re.compile(rf"{re.escape(name)}_\d{{4,}}\.h5")
    partial = re.compile(rf"\.{re.escape(name)}_\d{{4,}}\.h5\..*\.partial\.h5")
    for folder in folders:
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            if (pattern.fullmatch(path.name) and path.name not in keep) or partial.fullmatch(
                path.name
            ):
                path.unlink()


def pair_recordings(
    observation: str | os.PathLike[str],
    reference: str | os.PathLike[str],
    out: str | os.PathLike[str],
    config: PairConfig = PairConfig(),
    *,
    progress: bool = True,
) -> PairReport:
    """Turn an observation pass and a reference pass into paired benchmark windows.

    Two streaming passes over each file: the first measures the polarity
    signature, the per-pixel counts and the span (:func:`scan_recording`);
    then the offset is estimated (:func:`estimate_offset`), the light sources
    are taken from ``config.lights`` and/or detected on the reference, the
    background rate is measured on the observation (away from the sources and
    their glare); the second pass reads both files window by window (the
    reference shifted onto the observation's clock), cleans the reference
    (:func:`clean_reference`), centre-crops both, injects noise
    (:func:`inject_noise`) and writes one sequence file per window. Memory
    holds one window of each pass, the signatures and four count maps.

    The manifest is written last and updated per scene, so a folder can
    collect many scenes (run one after the other, not concurrently); a run
    killed midway leaves complete files but no manifest entry, and rerunning
    the same command finishes cleanly (files of the scene that the new run
    does not write are deleted).

    Parameters
    ----------
    observation, reference : path-like
        The pass with the filter (input) and without (ground truth source).
    out : path-like
        Dataset folder (see the module docstring for its layout).
    config : PairConfig
    progress : bool
        Progress bars on stderr.

    Returns
    -------
    PairReport

    Raises
    ------
    EventFileError
        Unreadable or empty recordings, a foreign manifest in ``out``.
    PairingError
        Mismatched sensor sizes, an alignment below ``min_confidence``, no
        complete window in the overlap of the aligned passes.
    ParameterError
        A crop larger than the sensor, lights entirely off the sensor.
    """
    cfg = config
    obs_path, ref_path, out = Path(observation), Path(reference), Path(out)
    obs_src = open_events(obs_path, cfg.sensor_size)
    ref_src = open_events(ref_path, cfg.sensor_size)
    size = obs_src.sensor_size
    if ref_src.sensor_size != size:
        raise PairingError(
            f"{obs_path}: sensor {size[0]}x{size[1]} differs from the reference's "
            f"{ref_src.sensor_size[0]}x{ref_src.sensor_size[1]} ({ref_path}); the two passes "
            "must come from the same camera (use --sensor-size for files that record none)"
        )
    crop = cfg.crop or size
    if crop[0] > size[0] or crop[1] > size[1]:
        raise ParameterError(
            f"crop {crop[0]}x{crop[1]} does not fit the {size[0]}x{size[1]} sensor of "
            f"{obs_path}; choose a smaller crop or none"
        )
    x0, y0 = (size[0] - crop[0]) // 2, (size[1] - crop[1]) // 2
    for light in cfg.lights:
        if not light_mask([light], size).any():
            raise ParameterError(f"light {light} covers no pixel of the {size[0]}x{size[1]} sensor")
    name = cfg.name or obs_path.stem
    if not _NAME.fullmatch(name):
        raise ParameterError(
            f"scene name {name!r} (from {obs_path.name}) is not a plain file name; pass a name"
        )
    manifest_path = out / "manifest.json"
    manifest = _read_manifest(manifest_path)  # refuse a foreign folder before any work
    if manifest is not None:
        others = {k: v for k, v in manifest["scenes"].items() if k != name}
        if others and manifest.get("sensor_size") != list(crop):
            raise PairingError(
                f"{out} holds pairs of {manifest.get('sensor_size')} (width, height); this scene "
                f"would be {crop[0]}x{crop[1]}: use the same crop or another folder"
            )

    obs_scan = scan_recording(obs_src, cfg.refine_bin_us, progress=progress)
    ref_scan = scan_recording(ref_src, cfg.refine_bin_us, progress=progress)
    for path, scan in ((obs_path, obs_scan), (ref_path, ref_scan)):
        if scan.n_events == 0:
            raise EventFileError(path, "holds no events")
    lights = list(cfg.lights)
    detected: list[Circle] = []
    if cfg.detect_light:
        try:
            detected = detect_light_source(ref_scan.counts)
        except ParameterError as exc:
            raise PairingError(f"{ref_path}: cannot detect a light source: {exc}") from None
        lights.extend(detected)

    try:
        alignment = estimate_offset(
            obs_scan.signature,
            ref_scan.signature,
            max_offset_us=cfg.max_offset_us,
            expected_offset_us=cfg.expected_offset_us,
            bin_us=cfg.bin_us,
        )
    except PairingError as exc:
        raise PairingError(f"{obs_path} and {ref_path}: {exc}") from None
    if alignment.confidence < cfg.min_confidence:
        raise PairingError(
            f"{obs_path} and {ref_path}: alignment confidence {alignment.confidence:.3f} is "
            f"below {cfg.min_confidence} ({alignment.describe()}); narrow max_offset around a "
            "known expected offset, or use a non-periodic strobe"
        )
    if alignment.confidence < LOW_CONFIDENCE:
        warnings.warn(
            f"{name}: low alignment confidence {alignment.confidence:.3f} "
            f"({alignment.describe()}); check {out / 'alignment' / (name + '.png')}",
            stacklevel=2,
        )
    shift = round(alignment.offset_us)
    window = cfg.window_us
    overlap_start = max(obs_scan.t_first_us, ref_scan.t_first_us - shift)
    overlap_end = min(obs_scan.t_last_us, ref_scan.t_last_us - shift) + 1
    first = -(-overlap_start // window) * window
    n_windows = max(0, (overlap_end - first) // window)
    if n_windows == 0:
        raise PairingError(
            f"{obs_path} and {ref_path}: after alignment (offset {shift / 1000:.3f} ms) the "
            f"passes overlap for {max(0, overlap_end - overlap_start) / 1000:.1f} ms, which holds "
            f"no complete {window / 1000:g} ms window"
        )

    sources = light_mask(lights, size)
    glare = glare_mask(lights, size, cfg.glare_radius_px)
    noise_est: NoiseEstimate | None = None
    if cfg.noise_rate_hz is None:
        try:
            noise_est = estimate_background_rate(
                obs_scan.counts,
                obs_scan.duration_us,
                on_counts=obs_scan.on_counts,
                exclude=sources | glare,
            )
        except ParameterError as exc:
            raise PairingError(f"{obs_path}: {exc}") from None
        rate, on_fraction = noise_est.rate_hz, noise_est.on_fraction
    else:
        rate, on_fraction = float(cfg.noise_rate_hz), 0.5
    crop_rows = slice(y0, y0 + crop[1])
    crop_cols = slice(x0, x0 + crop[0])
    region = (
        glare[crop_rows, crop_cols]
        if cfg.noise_region == "cleaned"
        else np.ones((crop[1], crop[0]), dtype=bool)
    )

    plot_path = out / "alignment" / f"{name}.png"
    plot_alignment(
        obs_scan.signature,
        ref_scan.signature,
        alignment,
        plot_path,
        expected_offset_us=cfg.expected_offset_us,
    )

    split_dir = out / cfg.split
    from . import __version__

    base_attrs = {
        "scene": name,
        "observation": obs_path.name,
        "reference": ref_path.name,
        "offset_us": float(alignment.offset_us),
        "alignment_confidence": float(alignment.confidence),
        "noise_rate_hz": float(rate),
        "crop": json.dumps([x0, y0, crop[0], crop[1]]),
        "source": "edeflare pair",
        "edeflare_version": __version__,
    }
    name_key = zlib.crc32(name.encode("utf-8"))
    files: list[Path] = []
    entries: list[dict[str, Any]] = []
    totals = {"input": 0, "gt": 0, "removed": 0, "noise": 0}
    obs_windows = obs_src.windows(window, start_us=first, end_us=first + n_windows * window)
    ref_windows = ref_src.windows(
        window, start_us=first + shift, end_us=first + shift + n_windows * window
    )
    with _progress(n_windows, f"pair {name}", progress, unit="window") as bar:
        for k, ((start, obs_w), (_, ref_w)) in enumerate(
            zip(obs_windows, ref_windows, strict=True)
        ):
            ref_w = ref_w.copy()
            ref_w["t"] -= shift
            cleaned = ref_w[~_pixel_mask_of(ref_w, glare)] if lights else ref_w
            inp, _ = center_crop(obs_w, size, crop)
            gt, _ = center_crop(cleaned, size, crop)
            rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, name_key, k]))
            noise = draw_noise(
                crop, rate, start, start + window, mask=region, on_fraction=on_fraction, rng=rng
            )
            gt = merge_events(gt, noise)
            file_name = f"{name}_{k:04d}.h5"
            path = split_dir / file_name
            attrs = {
                **base_attrs,
                "t_start_us": np.int64(start),
                "t_end_us": np.int64(start + window),
                "index": np.int64(k),
                "seed": json.dumps([cfg.seed, name_key, k]),
            }
            streams: dict[str, str] = {}
            if cfg.stream_files:
                for group, events in (("input", inp), ("gt", gt)):
                    write_events(split_dir / group / file_name, events, crop)
                    streams[group] = f"{cfg.split}/{group}/{file_name}"
            write_dsec_groups(path, {"input": inp, "gt": gt}, crop, attrs)
            removed = ref_w.size - cleaned.size
            counts = {"input": inp.size, "gt": gt.size, "removed": removed, "noise": noise.size}
            for key, value in counts.items():
                totals[key] += int(value)
            entry = {
                "file": f"{cfg.split}/{file_name}",
                "scene": name,
                "split": cfg.split,
                "index": k,
                "t_start_us": int(start),
                "t_end_us": int(start + window),
                "events": {key: int(v) for key, v in counts.items()},
                "bytes": path.stat().st_size,
                "sha256": _sha256(path),
            }
            if streams:
                entry["streams"] = streams
            entries.append(entry)
            files.append(path)
            bar.update(1)

    written = {p.name for p in files}
    folders = [split_dir, split_dir / "input", split_dir / "gt"]
    if manifest is not None and name in manifest["scenes"]:
        old_split = manifest["scenes"][name].get("split")
        if isinstance(old_split, str) and old_split != cfg.split:
            old = out / old_split
            _remove_stale([old, old / "input", old / "gt"], name, set())
    _remove_stale(folders, name, written)

    scene = {
        "split": cfg.split,
        "observation": _file_info(obs_src, obs_scan),
        "reference": _file_info(ref_src, ref_scan),
        "alignment": alignment.to_dict(),
        "overlap_us": [int(overlap_start), int(overlap_end)],
        "lights": [s.to_dict() for s in lights],
        "lights_detected": [s.to_dict() for s in detected],
        "lights_in_crop": [s.shifted(-x0, -y0).to_dict() for s in lights],
        "glare_radius_px": float(cfg.glare_radius_px),
        "noise": {
            "rate_hz": float(rate),
            "on_fraction": float(on_fraction),
            "measured": noise_est.to_dict() if noise_est is not None else None,
            "region": cfg.noise_region,
            "region_pixels": int(region.sum()),
        },
        "crop": {"x0": x0, "y0": y0, "width": crop[0], "height": crop[1]},
        "sensor_size": list(size),
        "window_us": window,
        "windows": n_windows,
        "seed": cfg.seed,
        "seed_rule": "numpy.random.SeedSequence([seed, crc32(scene), window index])",
        "events": totals,
        "plot": plot_path.relative_to(out).as_posix(),
        "files": entries,
    }
    scenes = dict(manifest["scenes"]) if manifest is not None else {}
    scenes[name] = scene
    payload = {
        "format": MANIFEST_FORMAT,
        "edeflare_version": __version__,
        "kind": "real paired captures (edeflare pair)",
        "sensor_size": list(crop),
        "scenes": {k: scenes[k] for k in sorted(scenes)},
        "files": [f for k in sorted(scenes) for f in scenes[k]["files"]],
    }
    with atomic_path(manifest_path) as tmp:
        tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return PairReport(
        name,
        alignment,
        tuple(lights),
        float(rate),
        noise_est,
        files,
        manifest_path,
        plot_path,
        scene,
    )
