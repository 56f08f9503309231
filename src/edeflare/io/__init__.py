"""Read and write event files of every common format, chosen by suffix.

==========  ==========================================  ======  =====
suffix      format                                      read    write
==========  ==========================================  ======  =====
``.h5``     DSEC HDF5 (:mod:`edeflare.io.dsec`)           yes     yes
``.raw``    Prophesee EVT 2.0 / 2.1 / 3.0 (faery)         yes     yes
``.dat``    Prophesee/Chronocam DAT TD (own codec)        yes     yes
``.aedat4`` iniVation AEDAT 4 (faery)                     yes     yes
``.es``     Event Stream (faery)                          yes     yes
``.csv``    ``t,x,y,p`` text                              yes     yes
``.npz``    numpy archive ``t, x, y, p, width, height``   yes     yes
``.txt``    ``t x y p`` per line                          yes     yes
==========  ==========================================  ======  =====

The sensor size comes from the file where it is recorded, else from the
``sensor_size`` argument, else from the events (``max + 1``, with a warning).
Every write is atomic, and every problem raises
:class:`~edeflare.errors.EventFileError` naming the file.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from ..errors import EventFileError, EventsError, UnknownFormatError
from ..events import (
    EVENT_DTYPE,
    SensorSize,
    check_events,
    check_sensor_size,
    concat_events,
    iter_chunk_windows,
    window_start_for,
)
from ._atomic import AtomicFile
from .dat import open_dat, write_dat
from .dsec import DsecReader, DsecWriter
from .faery_formats import open_faery, write_faery
from .text import open_npz, open_text, write_npz, write_txt

__all__ = [
    "EventSource",
    "Recording",
    "format_of",
    "iter_windows",
    "list_formats",
    "open_events",
    "read_events",
    "write_event_chunks",
    "write_events",
]

Opener = Callable[[Path, "SensorSize | None"], "tuple[SensorSize | None, Iterator[np.ndarray]]"]


@dataclasses.dataclass(frozen=True)
class _Format:
    name: str
    suffixes: tuple[str, ...]
    opener: Opener | None  # None: DSEC, handled by DsecReader
    writer: Callable[..., None]


def _write_dsec(
    tmp: Path, chunks: Iterable[np.ndarray], sensor_size: SensorSize, *, target: Path
) -> None:
    try:
        with DsecWriter(tmp, sensor_size, atomic=False) as writer:
            for events in chunks:
                writer.append(events)
    except EventFileError as exc:
        if exc.path != str(tmp):
            raise
        raise EventFileError(target, exc.problem) from None  # name the target, not the temp


_FORMATS: tuple[_Format, ...] = (
    _Format("DSEC HDF5", (".h5", ".hdf5"), None, _write_dsec),
    _Format("Prophesee EVT", (".raw",), open_faery, write_faery),
    _Format("Prophesee DAT", (".dat",), open_dat, write_dat),
    _Format("AEDAT 4", (".aedat4",), open_faery, write_faery),
    _Format("Event Stream", (".es",), open_faery, write_faery),
    _Format("CSV", (".csv",), open_text, write_faery),
    _Format("numpy npz", (".npz",), open_npz, write_npz),
    _Format("text", (".txt",), open_text, write_txt),
)


def list_formats() -> list[str]:
    """Suffixes edeflare reads and writes.

    Examples
    --------
    >>> ".h5" in list_formats()
    True
    """
    return [s for f in _FORMATS for s in f.suffixes]


def _format_for(path: Path) -> _Format:
    """The format of an event file by its suffix (a folder is an error, whatever its name)."""
    if path.is_dir():
        raise EventFileError(path, "is a folder, not an event file")
    suffix = path.suffix.lower()
    for fmt in _FORMATS:
        if suffix in fmt.suffixes:
            return fmt
    raise UnknownFormatError(
        path, f"unknown event file suffix {suffix!r}; known: {', '.join(list_formats())}"
    )


def format_of(path: str | os.PathLike[str]) -> str:
    """Human-readable format name for a path, by suffix.

    Examples
    --------
    >>> format_of("drive.raw")
    'Prophesee EVT'
    """
    return _format_for(Path(path)).name


class Recording(tuple):
    """``(events, sensor_size)`` as returned by :func:`read_events`; unpacks like a tuple."""

    __slots__ = ()

    def __new__(cls, events: np.ndarray, sensor_size: SensorSize) -> Recording:
        return super().__new__(cls, (events, sensor_size))

    @property
    def events(self) -> np.ndarray:
        """The event stream (:data:`~edeflare.events.EVENT_DTYPE`)."""
        return self[0]

    @property
    def sensor_size(self) -> SensorSize:
        """``(width, height)``."""
        return self[1]


class EventSource:
    """An opened event file: its format, sensor size, chunks and windows.

    Parameters
    ----------
    path : path-like
        Any file with a known suffix (see :func:`list_formats`).
    sensor_size : (width, height), optional
        Overrides the size recorded in the file; required in practice for
        files that record none (``.csv``, ``.txt``, some ``.raw`` and ``.dat``),
        else it is inferred as ``max + 1`` with a warning.
    group : str, optional
        HDF5 files only: the event group to read when a file holds several,
        e.g. ``"input"`` or ``"gt"`` of a paired sequence file (``"input"`` is
        short for ``"input/events"``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.npz"
    >>> write_events(path, make_events([0, 25_000], [1, 2], [1, 2], [1, 0]), (4, 4))
    >>> src = EventSource(path)
    >>> src.sensor_size, [len(w) for _, w in src.windows(20_000)]
    ((4, 4), [1, 1])
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        sensor_size: SensorSize | None = None,
        *,
        group: str | None = None,
    ) -> None:
        self.path = Path(path)
        self._format = _format_for(self.path)
        self.format = self._format.name
        if group is not None and self._format.opener is not None:
            raise EventFileError(
                self.path, f"a group ({group!r}) applies to HDF5 files only, not {self.format}"
            )
        self.group = group
        if not self.path.is_file():
            raise EventFileError(self.path, "no such file")
        if self.path.stat().st_size == 0:
            raise EventFileError(self.path, "file is empty")
        if sensor_size is not None:
            try:
                sensor_size = check_sensor_size(sensor_size)
            except EventsError as exc:
                raise EventFileError(self.path, str(exc)) from None
        self._given_size = sensor_size
        self._recorded_size: SensorSize | None
        if self._format.opener is None:
            with DsecReader(self.path, group=self.group) as reader:
                self._recorded_size = reader.recorded_sensor_size
                self.n_events: int | None = reader.n_events
        else:
            self._recorded_size, chunks = self._format.opener(self.path, sensor_size)
            del chunks  # opened only to read the header; generators hold nothing yet
            self.n_events = None
        self._inferred_size: SensorSize | None = None

    # -- sensor size ------------------------------------------------------------------
    @property
    def recorded_sensor_size(self) -> SensorSize | None:
        """The size the file itself records, or None."""
        return self._recorded_size

    @property
    def sensor_size_source(self) -> str:
        """Where :attr:`sensor_size` comes from: ``"option"``, ``"file"`` or ``"inferred"``."""
        if self._given_size is not None:
            return "option"
        return "file" if self._recorded_size is not None else "inferred"

    @property
    def sensor_size(self) -> SensorSize:
        """``(width, height)``: given, else recorded, else ``max + 1`` over the file (warns)."""
        if self._given_size is not None:
            return self._given_size
        if self._recorded_size is not None:
            return self._recorded_size
        if self._inferred_size is None:
            max_x = max_y = -1
            for events in self._raw_chunks():
                if events.size:
                    max_x = max(max_x, int(events["x"].max()))
                    max_y = max(max_y, int(events["y"].max()))
            if max_x < 0:
                raise EventFileError(
                    self.path, "records no sensor size and holds no events; pass sensor_size"
                )
            self._inferred_size = (max_x + 1, max_y + 1)
            warnings.warn(
                f"{self.path}: no sensor size recorded; using {max_x + 1}x{max_y + 1} "
                "(max + 1). Pass sensor_size / --sensor-size WxH to set it.",
                stacklevel=2,
            )
        return self._inferred_size

    # -- time -------------------------------------------------------------------------------
    def first_time_us(self) -> int | None:
        """Absolute time of the first event, the recording's start (None for an empty file).

        DSEC files read one value; other formats decode their first chunk only.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from edeflare.events import make_events
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.csv"
        >>> events = make_events([11_200_000, 11_300_000], [1, 2], [1, 2], [1, 0])
        >>> write_events(path, events, (4, 4))
        >>> EventSource(path).first_time_us()
        11200000
        """
        if self._format.opener is None:
            with DsecReader(self.path, group=self.group) as reader:
                span = reader.time_range()
            return None if span is None else span[0]
        for events in self.chunks():
            return int(events["t"][0])
        return None

    def time_span_us(self) -> tuple[int, int] | None:
        """``(first t, last t)`` in absolute microseconds, or None for an empty file.

        DSEC files read two values; other formats are streamed once.
        """
        if self._format.opener is None:
            with DsecReader(self.path, group=self.group) as reader:
                return reader.time_range()
        first = last = None
        for events in self.chunks():
            if first is None:
                first = int(events["t"][0])
            last = int(events["t"][-1])
        return None if first is None or last is None else (first, last)

    # -- data ---------------------------------------------------------------------------
    def _raw_chunks(self, chunk_events: int = 1 << 20) -> Iterator[np.ndarray]:
        if self._format.opener is None:
            with DsecReader(self.path, group=self.group) as reader:
                yield from reader.iter_chunks(chunk_events)
        else:
            yield from self._format.opener(self.path, self._given_size)[1]

    def chunks(self, chunk_events: int = 1 << 20) -> Iterator[np.ndarray]:
        """Yield validated chunks (sorted within and across chunks, on the sensor)."""
        size = self.sensor_size
        last_t: int | None = None
        for events in self._raw_chunks(chunk_events):
            try:
                check_events(events, size)
            except EventsError as exc:
                raise EventFileError(self.path, str(exc)) from None
            if events.size:
                if last_t is not None and int(events["t"][0]) < last_t:
                    raise EventFileError(
                        self.path,
                        f"timestamps are not sorted: t={int(events['t'][0])} after t={last_t}",
                    )
                last_t = int(events["t"][-1])
                yield events

    def read(self) -> np.ndarray:
        """All events of the file in one array."""
        if self._format.opener is None:  # DSEC knows its length: read into one array
            size = self.sensor_size
            with DsecReader(self.path, group=self.group) as reader:
                events = reader.read()
            try:
                return check_events(events, size)
            except EventsError as exc:
                raise EventFileError(self.path, str(exc)) from None
        parts = list(self.chunks())
        if not parts:
            return np.zeros(0, dtype=EVENT_DTYPE)
        return parts[0] if len(parts) == 1 else concat_events(parts)

    def windows(
        self,
        window_us: int,
        *,
        start_us: int | None = None,
        end_us: int | None = None,
    ) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(window_start_us, events)`` over aligned half-open windows, empty ones too.

        ``start_us`` defaults to the multiple of ``window_us`` at or below the
        first event; windows continue until the last event (or ``end_us``).
        DSEC files are read window by window through ``ms_to_idx``; other
        formats are decoded chunk by chunk. Memory stays bounded by one
        chunk plus one window.
        """
        window_us = int(window_us)
        if window_us <= 0:
            raise EventsError(f"window_us must be positive, got {window_us}")
        if self._format.opener is None:
            yield from self._dsec_windows(window_us, start_us, end_us)
            return
        yield from iter_chunk_windows(self.chunks(), window_us, start_us=start_us, end_us=end_us)

    def _dsec_windows(
        self, window_us: int, start_us: int | None, end_us: int | None
    ) -> Iterator[tuple[int, np.ndarray]]:
        size = self.sensor_size
        with DsecReader(self.path, group=self.group) as reader:
            span = reader.time_range()
            if span is None and (start_us is None or end_us is None):
                return
            if start_us is None:
                start_us = window_start_for(span[0], window_us)  # type: ignore[index]
            if end_us is None:
                end_us = span[1] + 1  # type: ignore[index]
            lo = reader.index_of(start_us)
            cur = start_us
            while cur < end_us:
                hi = reader.index_of(cur + window_us)
                events = reader.read(lo, hi)
                try:
                    check_events(events, size)
                except EventsError as exc:
                    raise EventFileError(self.path, str(exc)) from None
                yield cur, events
                lo = hi
                cur += window_us


def open_events(
    path: str | os.PathLike[str],
    sensor_size: SensorSize | None = None,
    *,
    group: str | None = None,
) -> EventSource:
    """Open an event file of any known format. See :class:`EventSource`."""
    return EventSource(path, sensor_size, group=group)


def read_events(path: str | os.PathLike[str], sensor_size: SensorSize | None = None) -> Recording:
    """Read a whole event file: ``events, sensor_size = read_events(path)``.

    Parameters
    ----------
    path : path-like
        A file with a known suffix (see :func:`list_formats`).
    sensor_size : (width, height), optional
        Overrides or supplies the sensor size.

    Returns
    -------
    Recording
        ``(events, sensor_size)``; also ``.events`` and ``.sensor_size``.

    Raises
    ------
    EventFileError
        Unknown suffix, missing/empty/corrupt file, unsorted timestamps,
        events outside the sensor.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.h5"
    >>> write_events(path, make_events([10, 20], [0, 1], [0, 1], [1, 0]), (2, 2))
    >>> events, size = read_events(path)
    >>> events["t"].tolist(), size
    ([10, 20], (2, 2))
    """
    source = EventSource(path, sensor_size)
    events = source.read()
    return Recording(events, source.sensor_size)


def iter_windows(
    path: str | os.PathLike[str],
    window_us: int,
    *,
    sensor_size: SensorSize | None = None,
    start_us: int | None = None,
    end_us: int | None = None,
) -> Iterator[tuple[int, np.ndarray]]:
    """Stream ``(window_start_us, events)`` from a file. See :meth:`EventSource.windows`."""
    return EventSource(path, sensor_size).windows(window_us, start_us=start_us, end_us=end_us)


def write_event_chunks(
    path: str | os.PathLike[str],
    chunks: Iterable[np.ndarray],
    sensor_size: SensorSize,
    *,
    evt_version: str = "evt2",
) -> int:
    """Write a stream of sorted chunks atomically; return the number of events written.

    Each chunk is validated (dtype, sorted within and across chunks, on the
    sensor) before it reaches the file; on any error the target is left
    untouched.

    Parameters
    ----------
    evt_version : {"evt2", "evt3"}
        Encoding of ``.raw`` files. EVT 2.0 (default) spans up to 4.77 hours;
        EVT 3.0 is more compact but, as faery writes it, must span less than
        16.8 s.
    """
    path = Path(path)
    fmt = _format_for(path)
    try:
        sensor_size = check_sensor_size(sensor_size)
    except EventsError as exc:
        raise EventFileError(path, str(exc)) from None
    if evt_version not in ("evt2", "evt3"):
        raise EventFileError(path, f"evt_version must be evt2 or evt3, got {evt_version!r}")
    count = 0

    def validated() -> Iterator[np.ndarray]:
        nonlocal count
        last_t: int | None = None
        for events in chunks:
            try:
                check_events(events, sensor_size)
            except EventsError as exc:
                raise EventFileError(path, f"cannot write: {exc}") from None
            if not events.size:
                continue
            if last_t is not None and int(events["t"][0]) < last_t:
                raise EventFileError(path, "cannot write: chunks are not in time order")
            last_t = int(events["t"][-1])
            count += events.size
            yield events

    atomic: AtomicFile | None = None
    try:
        atomic = AtomicFile(path)
        kwargs = {"evt_version": evt_version} if fmt.suffixes == (".raw",) else {}
        fmt.writer(atomic.tmp, validated(), sensor_size, target=path, **kwargs)
        atomic.commit()
    except OSError as exc:
        raise EventFileError(path, f"cannot write ({exc})") from None
    finally:
        if atomic is not None:
            atomic.discard()
    return count


def write_events(
    path: str | os.PathLike[str],
    events: np.ndarray,
    sensor_size: SensorSize,
    *,
    evt_version: str = "evt2",
) -> None:
    """Write an event stream to ``path`` (format by suffix), atomically.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.raw"
    >>> write_events(path, make_events([5, 9], [3, 4], [1, 2], [1, 0]), (640, 480))
    >>> read_events(path).events["x"].tolist()
    [3, 4]
    """
    write_event_chunks(path, [events], sensor_size, evt_version=evt_version)
