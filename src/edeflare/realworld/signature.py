"""Polarity signatures: ON/OFF counts per time bin, from events in memory or a pass over a file."""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, check_events, check_sensor_size
from ..io import EventSource, open_events
from ._common import _check_mask, _positive_int, _progress


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
