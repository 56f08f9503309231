"""The DSEC HDF5 event layout: our own spec-exact reader and writer.

Layout (Gehrig et al., DSEC, 2021)::

    /events/x   uint16   (N,)
    /events/y   uint16   (N,)
    /events/p   uint8    (N,)   1 = ON, 0 = OFF
    /events/t   uint32   (N,)   microseconds relative to t_offset
    /ms_to_idx  uint64   (M,)   t[ms_to_idx[ms]] >= ms*1000 > t[ms_to_idx[ms]-1]
    /t_offset   int64    ()     absolute time of t = 0, microseconds

compressed with Blosc-zstd through :mod:`hdf5plugin`. edeflare adds a root
attribute ``sensor_size = (width, height)``. ``M = t[-1] // 1000 + 1`` so
every millisecond up to the last event has an entry. The reader also finds
events stored under a prefix (e.g. ``/events/left/{x,y,p,t}``) and falls back
to binary search on ``t`` when ``ms_to_idx`` is absent.

Windows are read through ``ms_to_idx`` and a binary search within one
millisecond, so a multi-GB file never loads whole.
"""

from __future__ import annotations

import contextlib
import os
import struct
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import h5py
import hdf5plugin
import numpy as np

from ..errors import EventFileError, EventsError
from ..events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size
from ._atomic import AtomicFile

__all__ = ["DsecReader", "DsecWriter", "read_dsec", "write_dsec", "write_dsec_groups"]

_CHUNK = 1 << 17
_U32_MAX = np.iinfo(np.uint32).max


def _compression() -> dict[str, Any]:
    return dict(hdf5plugin.Blosc(cname="zstd", clevel=3, shuffle=hdf5plugin.Blosc.SHUFFLE))


# What h5py raises on a corrupt file: OSError, RuntimeError ("Object visitation failed",
# "bad heap free list"), KeyError, ValueError or TypeError from inside HDF5.
_H5_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)


@contextlib.contextmanager
def _h5_errors(path: Path, what: str) -> Iterator[None]:
    """Turn h5py's errors on a corrupt file into :class:`EventFileError` naming ``path``."""
    try:
        yield
    except EventFileError:
        raise
    except _H5_ERRORS as exc:
        raise EventFileError(path, f"{what} ({type(exc).__name__}: {exc})") from None


_BLOSC = 32001
# Filters a DSEC file may use: deflate, shuffle, fletcher32, szip, nbit, scaleoffset, and
# hdf5plugin's LZ4, bitshuffle, zstd, Blosc2. Blosc chunks are checked before decoding.
_KNOWN_FILTERS = {1, 2, 3, 4, 5, 6, _BLOSC, 32004, 32008, 32015, 32026}


def _check_chunks(path: Path, name: str, d: h5py.Dataset, raw: Any) -> None:
    """Refuse a dataset whose shape, filters or Blosc chunk headers would crash the decoder.

    A corrupt shape asks for terabytes (MemoryError). Blosc trusts its
    parameters (type size, chunk bytes) and each chunk's 16-byte header;
    corrupt ones make it read or write out of bounds and kill the process
    (SIGSEGV), which no Python code can catch.
    """
    if len(d.shape) != 1:
        raise EventFileError(path, f"dataset {name!r} has shape {d.shape}, not 1-D")
    length = int(d.shape[0])
    file_size = raw.seek(0, os.SEEK_END)
    if d.chunks is None:
        if length * d.dtype.itemsize > file_size:
            raise EventFileError(path, f"dataset {name!r}: {length} values do not fit the file")
    elif length and d.id.get_num_chunks() * d.chunks[0] < length:
        # Writers allocate every chunk; a length beyond them is a corrupt shape.
        raise EventFileError(path, f"dataset {name!r}: length {length} exceeds its stored chunks")
    plist = d.id.get_create_plist()
    blosc = False
    for i in range(plist.get_nfilters()):
        code, _, values, _ = plist.get_filter(i)
        if code not in _KNOWN_FILTERS:
            raise EventFileError(path, f"dataset {name!r} uses unknown filter {code}")
        if code == _BLOSC:
            blosc = True
            if d.chunks is None:
                raise EventFileError(path, f"dataset {name!r}: Blosc filter on unchunked data")
            nbytes = int(np.prod(d.chunks)) * d.dtype.itemsize
            if len(values) < 4 or values[2] != d.dtype.itemsize or values[3] != nbytes:
                raise EventFileError(
                    path, f"dataset {name!r}: corrupt Blosc filter parameters {values!r}"
                )
    if not blosc:
        return
    for i in range(d.id.get_num_chunks()):
        info = d.id.get_chunk_info(i)
        if info.size < 16 or info.byte_offset + info.size > file_size:
            raise EventFileError(path, f"dataset {name!r}: chunk {i} lies outside the file")
        if info.filter_mask:
            continue  # stored without Blosc
        raw.seek(info.byte_offset)
        version, _, _, typesize, n, block, cbytes = struct.unpack("<BBBBIII", raw.read(16))
        if (
            cbytes != info.size
            or n != nbytes
            or typesize != d.dtype.itemsize
            or not 0 < block <= n
            or not 1 <= version <= 5
        ):
            raise EventFileError(path, f"dataset {name!r}: corrupt Blosc header in chunk {i}")


def _find_event_groups(f: h5py.File) -> list[str]:
    found: list[str] = []

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Group) and all(
            isinstance(obj.get(k), h5py.Dataset) for k in ("x", "y", "p", "t")
        ):
            found.append(name)

    f.visititems(visit)
    return sorted(found)


class DsecReader:
    """Random and streaming access to a DSEC-layout HDF5 event file.

    Parameters
    ----------
    path : path-like
        The ``.h5`` file.
    group : str, optional
        Where ``x, y, p, t`` live (e.g. ``"events/left"``); found automatically
        when there is one such group (or one whose path contains ``left``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.h5"
    >>> write_dsec(path, make_events([1000, 2500, 4000], [0, 1, 2], [0, 0, 0], [1, 0, 1]), (3, 1))
    >>> with DsecReader(path) as r:
    ...     r.read_time(2000, 4001)["t"].tolist()
    [2500, 4000]
    """

    def __init__(self, path: str | os.PathLike[str], group: str | None = None) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise EventFileError(self.path, "no such file")
        if self.path.stat().st_size == 0:
            raise EventFileError(self.path, "file is empty")
        try:
            self._file = h5py.File(self.path, "r")
        except _H5_ERRORS as exc:
            raise EventFileError(self.path, f"not a readable HDF5 file ({exc})") from None
        try:
            with _h5_errors(self.path, "corrupt HDF5 file"):
                self._open(group)
        except BaseException:
            self._file.close()
            raise

    def _open(self, group: str | None) -> None:
        f = self._file
        if group is None:
            groups = _find_event_groups(f)
            if not groups:
                raise EventFileError(
                    self.path, "no group with datasets x, y, p, t (not a DSEC event file)"
                )
            if len(groups) > 1:
                left = [g for g in groups if "left" in g.split("/")]
                if len(left) != 1:
                    names = [g.removesuffix("/events") for g in groups]
                    raise EventFileError(
                        self.path,
                        f"several event groups {names}; choose one "
                        "(--group at the command line, group= in Python)",
                    )
                groups = left
            group = groups[0]
        group = group.strip("/")
        if group in f and isinstance(f[group], h5py.Group) and "t" not in f[group]:
            if f"{group}/events" in f:  # "input" for "input/events"
                group = f"{group}/events"
        if group not in f or not isinstance(f[group], h5py.Group):
            raise EventFileError(self.path, f"no event group {group!r}")
        g = f[group]
        self.group = group
        try:
            self._x, self._y, self._p, self._t = (g[k] for k in ("x", "y", "p", "t"))
        except KeyError as exc:
            raise EventFileError(self.path, f"group {group!r} lacks {exc}") from None
        lengths = {d.shape for d in (self._x, self._y, self._p, self._t)}
        if len(lengths) != 1 or len(next(iter(lengths))) != 1:
            raise EventFileError(
                self.path, f"x, y, p, t must be 1-D of one length, got shapes {sorted(lengths)}"
            )
        for name, d in zip("xypt", (self._x, self._y, self._p, self._t), strict=True):
            if d.dtype.kind not in "iu":
                raise EventFileError(self.path, f"events {name} has dtype {d.dtype}, not integer")
        self.n_events = int(self._t.shape[0])
        with open(self.path, "rb") as raw:
            for name, d in zip("xypt", (self._x, self._y, self._p, self._t), strict=True):
                _check_chunks(self.path, f"{group}/{name}", d, raw)
        # ms_to_idx and t_offset: in the group itself or in one of its parents (DSEC: root).
        self._ms_to_idx: np.ndarray | None = None
        self.t_offset = 0
        parts = group.split("/")
        for depth in range(len(parts), -1, -1):
            parent = f["/".join(parts[:depth]) or "/"]
            if self._ms_to_idx is None and isinstance(parent.get("ms_to_idx"), h5py.Dataset):
                with open(self.path, "rb") as raw:
                    _check_chunks(self.path, "ms_to_idx", parent["ms_to_idx"], raw)
                self._ms_to_idx = np.asarray(parent["ms_to_idx"][()], dtype=np.int64)
            if "t_offset" in parent and isinstance(parent.get("t_offset"), h5py.Dataset):
                self.t_offset = int(parent["t_offset"][()])
                break
        self.root_attrs: dict[str, Any] = dict(f.attrs)
        self.recorded_sensor_size: SensorSize | None = None
        if "sensor_size" in f.attrs:
            try:
                self.recorded_sensor_size = check_sensor_size(
                    tuple(int(v) for v in f.attrs["sensor_size"])
                )
            except (EventsError, TypeError, ValueError):
                raise EventFileError(
                    self.path, f"bad sensor_size attribute {f.attrs['sensor_size']!r}"
                ) from None
        if self._ms_to_idx is not None and self.n_events:
            idx = self._ms_to_idx
            if idx.size and (
                idx.min() < 0 or idx.max() > self.n_events or (np.diff(idx) < 0).any()
            ):
                raise EventFileError(self.path, "ms_to_idx is not a valid index into the events")

    # -- context manager ------------------------------------------------------------
    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> DsecReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- access -----------------------------------------------------------------------
    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Events ``start:stop`` (by index) as an :data:`EVENT_DTYPE` array."""
        stop = self.n_events if stop is None else min(int(stop), self.n_events)
        start = max(0, min(int(start), stop))
        out = np.empty(stop - start, dtype=EVENT_DTYPE)
        if stop == start:
            return out
        with _h5_errors(self.path, "corrupt or truncated data"):
            t = self._t[start:stop]
            out["x"] = self._x[start:stop]
            out["y"] = self._y[start:stop]
            p = self._p[start:stop]
        out["t"] = t.astype(np.int64) + self.t_offset
        if p.size and (p.max() > 1 or p.min() < 0):
            # Some writers store OFF as -1; anything else is an error.
            if not np.isin(p, (-1, 0, 1)).all():
                raise EventFileError(self.path, "polarity values other than 0/1 or -1/+1")
            p = p > 0
        out["p"] = p
        return out

    def _t_at(self, i: int) -> int:
        with _h5_errors(self.path, "corrupt or truncated data"):
            return int(self._t[i])

    def index_of(self, t_us: int) -> int:
        """Index of the first event with absolute ``t >= t_us`` (``n_events`` if none)."""
        rel = int(t_us) - self.t_offset
        if self.n_events == 0 or rel <= self._t_at(0):
            return 0
        if rel > self._t_at(self.n_events - 1):
            return self.n_events
        idx = self._ms_to_idx
        if idx is not None and idx.size:
            ms = rel // 1000
            if ms >= idx.size:
                return self.n_events
            lo = int(idx[ms])
            hi = int(idx[ms + 1]) if ms + 1 < idx.size else self.n_events
        else:
            lo, hi = 0, self.n_events
        # Binary search in [lo, hi): read the block whole when small, else bisect the dataset.
        while hi - lo > 65536:
            mid = (lo + hi) // 2
            if self._t_at(mid) < rel:
                lo = mid + 1
            else:
                hi = mid
        with _h5_errors(self.path, "corrupt or truncated data"):
            block = self._t[lo:hi].astype(np.int64)
        return lo + int(np.searchsorted(block, rel, side="left"))

    def time_range(self) -> tuple[int, int] | None:
        """``(first t, last t)`` in absolute microseconds, or None for an empty file."""
        if self.n_events == 0:
            return None
        return self._t_at(0) + self.t_offset, self._t_at(self.n_events - 1) + self.t_offset

    def read_time(self, t_start_us: int, t_end_us: int) -> np.ndarray:
        """Events with ``t_start_us <= t < t_end_us``."""
        lo = self.index_of(t_start_us)
        hi = self.index_of(t_end_us)
        return self.read(lo, max(lo, hi))

    def iter_chunks(self, chunk_events: int = 1 << 20) -> Iterator[np.ndarray]:
        """Yield consecutive blocks of at most ``chunk_events`` events."""
        for start in range(0, self.n_events, chunk_events):
            yield self.read(start, start + chunk_events)


def read_dsec(
    path: str | os.PathLike[str], group: str | None = None
) -> tuple[np.ndarray, SensorSize | None]:
    """Read a whole DSEC file: ``(events, recorded sensor size or None)``."""
    with DsecReader(path, group) as reader:
        return reader.read(), reader.recorded_sensor_size


class _StreamGroup:
    """The datasets of one event stream inside an open HDF5 group, appended chunk by chunk.

    Raises ``ValueError`` with a user-facing message on out-of-order chunks or
    times that do not fit; the callers add the file name.
    """

    def __init__(self, group: h5py.Group, t_offset_us: int | None) -> None:
        comp = _compression()
        events = group.create_group("events")
        self._group = group
        self._ds = {
            name: events.create_dataset(
                name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(_CHUNK,), **comp
            )
            for name, dtype in (("x", "<u2"), ("y", "<u2"), ("p", "u1"), ("t", "<u4"))
        }
        self._ms = group.create_dataset(
            "ms_to_idx", shape=(0,), maxshape=(None,), dtype="<u8", chunks=(8192,), **comp
        )
        self.t_offset = t_offset_us
        self.n_events = 0
        self._last_t: int | None = None

    def append(self, events: np.ndarray) -> None:
        if events.size == 0:
            return
        t = events["t"]
        if self._last_t is not None and int(t[0]) < self._last_t:
            raise ValueError(
                f"chunk starts at t={int(t[0])} before the previous chunk's end {self._last_t}"
            )
        if self.t_offset is None:
            self.t_offset = int(t[0])
        rel = t - self.t_offset
        if rel[0] < 0 or rel[-1] > _U32_MAX:
            raise ValueError(
                f"relative times must fit uint32 µs (0..{_U32_MAX}, about 71 minutes) from "
                f"t_offset={self.t_offset}; got [{int(rel[0])}, {int(rel[-1])}]"
            )
        n0, n1 = self.n_events, self.n_events + events.size
        for name in ("x", "y", "p"):
            self._ds[name].resize((n1,))
            self._ds[name][n0:n1] = events[name]
        self._ds["t"].resize((n1,))
        self._ds["t"][n0:n1] = rel.astype(np.uint32)
        # ms_to_idx entries for every millisecond up to this chunk's last event.
        m0 = self._ms.shape[0]
        m1 = int(rel[-1]) // 1000 + 1
        if m1 > m0:
            bounds = np.arange(m0, m1, dtype=np.int64) * 1000
            self._ms.resize((m1,))
            self._ms[m0:m1] = n0 + np.searchsorted(rel, bounds, side="left")
        self.n_events = n1
        self._last_t = int(t[-1])

    def finish(self) -> None:
        self._group.create_dataset("t_offset", data=np.int64(self.t_offset or 0))


class DsecWriter:
    """Append events chunk by chunk to a DSEC file written atomically.

    The file appears at ``path`` only when :meth:`close` succeeds (or the
    ``with`` block ends without error); ``ms_to_idx`` is built incrementally.

    Parameters
    ----------
    path : path-like
        Target ``.h5`` file.
    sensor_size : (width, height)
        Stored as the root attribute ``sensor_size``; events are checked against it.
    t_offset_us : int, optional
        Absolute time of relative ``t = 0``; defaults to the first event's time
        (0 for an empty stream).
    atomic : bool
        Write to a temporary file and move it into place on :meth:`close`
        (default). With False, write ``path`` directly (for callers that
        manage atomicity themselves).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.h5"
    >>> with DsecWriter(path, (4, 4)) as w:
    ...     w.append(make_events([5_000], [1], [2], [1]))
    ...     w.append(make_events([7_500], [3], [0], [0]))
    >>> with DsecReader(path) as r:
    ...     r.t_offset, r.n_events
    (5000, 2)
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        sensor_size: SensorSize,
        t_offset_us: int | None = None,
        *,
        atomic: bool = True,
    ) -> None:
        self.path = Path(path)
        self.sensor_size = check_sensor_size(sensor_size)
        self._atomic: AtomicFile | None = None
        self._closed = False
        try:
            self._atomic = AtomicFile(self.path) if atomic else None
            self._file = h5py.File(self.path if self._atomic is None else self._atomic.tmp, "w")
            self._file.attrs["sensor_size"] = np.asarray(self.sensor_size, dtype=np.int64)
            self._stream = _StreamGroup(self._file, t_offset_us)
        except OSError as exc:
            self._abort()
            raise EventFileError(self.path, f"cannot write ({exc})") from None
        except BaseException:
            self._abort()
            raise

    @property
    def n_events(self) -> int:
        """Events written so far."""
        return self._stream.n_events

    @property
    def t_offset(self) -> int | None:
        """The file's ``t_offset`` (None until the first event when not given)."""
        return self._stream.t_offset

    def append(self, events: np.ndarray) -> None:
        """Append a sorted chunk whose times do not precede the previous chunk's."""
        try:
            check_events(events, self.sensor_size)
            self._stream.append(events)
        except ValueError as exc:  # EventsError is a ValueError too
            self._abort()
            raise EventFileError(self.path, f"cannot write events: {exc}") from None

    def close(self) -> None:
        """Finish the file and move it into place."""
        if self._closed:
            return
        self._stream.finish()
        self._file.close()
        self._closed = True
        if self._atomic is not None:
            self._atomic.commit()

    def _abort(self) -> None:
        """Drop the temporary file; the target is left as it was."""
        if self._closed:
            return
        self._closed = True
        if hasattr(self, "_file"):
            self._file.close()
        if self._atomic is not None:
            self._atomic.discard()

    def __enter__(self) -> DsecWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self._abort()


def write_dsec_groups(
    path: str | os.PathLike[str],
    streams: dict[str, np.ndarray],
    sensor_size: SensorSize,
    attrs: dict[str, object] | None = None,
    datasets: Mapping[str, np.ndarray] | None = None,
) -> None:
    """Write several streams to one file, each in the DSEC layout under its own group.

    ``streams["input"]`` lands in ``/input/events/{x,y,p,t}``,
    ``/input/ms_to_idx`` and ``/input/t_offset``; read it back with
    ``DsecReader(path, group="input/events")``. Root attributes: ``sensor_size``
    plus ``attrs`` (strings or numbers). ``datasets`` adds other arrays by
    path (e.g. ``"frames/t_us"``), compressed like the events. Written atomically.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "pair.h5"
    >>> ev = make_events([10, 20], [0, 1], [0, 0], [1, 0])
    >>> write_dsec_groups(path, {"input": ev, "gt": ev[:1]}, (2, 1), {"seed": 7})
    >>> with DsecReader(path, group="gt/events") as r:
    ...     r.n_events, r.recorded_sensor_size
    (1, (2, 1))
    """
    path = Path(path)
    sensor_size = check_sensor_size(sensor_size)
    atomic: AtomicFile | None = None
    try:
        atomic = AtomicFile(path)
        with h5py.File(atomic.tmp, "w") as f:
            f.attrs["sensor_size"] = np.asarray(sensor_size, dtype=np.int64)
            for key, value in (attrs or {}).items():
                f.attrs[key] = value
            for name, events in streams.items():
                try:
                    check_events(events, sensor_size)
                    stream = _StreamGroup(f.create_group(name), None)
                    stream.append(events)
                    stream.finish()
                except ValueError as exc:
                    raise EventFileError(path, f"stream {name!r}: {exc}") from None
            for name, array in (datasets or {}).items():
                array = np.asarray(array)
                chunked = array.ndim > 0 and array.size > 0
                f.create_dataset(name, data=array, **(_compression() if chunked else {}))
        atomic.commit()
    except OSError as exc:
        raise EventFileError(path, f"cannot write ({exc})") from None
    finally:
        if atomic is not None:
            atomic.discard()


def write_dsec(
    path: str | os.PathLike[str],
    events: np.ndarray,
    sensor_size: SensorSize,
    t_offset_us: int | None = None,
) -> None:
    """Write a whole stream to a DSEC file (atomically). See :class:`DsecWriter`."""
    with DsecWriter(path, sensor_size, t_offset_us) as writer:
        writer.append(events)
