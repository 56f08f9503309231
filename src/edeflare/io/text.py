"""``.npz`` archives and plain-text ``.txt`` / ``.csv`` event files.

- ``.npz``: arrays ``t`` (int64 µs), ``x``, ``y``, ``p`` (1 = ON, 0 = OFF;
  -1/+1 and bool accepted on reading) and scalars ``width``, ``height``;
  read and written streaming (one chunk of events in memory), never pickled.
- ``.txt``: one event per line, ``t x y p`` separated by spaces. An optional
  first line ``W H`` gives the sensor size (the rpg/ESIM convention). ``t`` is
  integer microseconds; if it is written with a decimal point it is read as
  seconds (the rpg convention) and rounded to microseconds.
- ``.csv``: comma-separated ``t,x,y,p`` with an optional header naming the
  columns (``t``, ``x``, ``y``, and ``p``/``on``/``polarity``, in any order;
  faery's ``x@W,y@H`` form records the sensor size). Written by faery.

We read CSV ourselves rather than through faery because faery's reader
silently clamps decreasing timestamps, hiding unsorted input, and requires
a fixed column order.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import tokenize
import zipfile
import zlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO

import numpy as np

from ..errors import EventFileError, EventsError
from ..events import EVENT_DTYPE, SensorSize, make_events

__all__ = ["open_npz", "open_text", "write_npz", "write_txt"]

_TEXT_CHUNK_LINES = 1 << 18  # lines per chunk: the parse holds a few copies of a chunk


_NPZ_CHUNK = 1 << 20  # events per chunk when streaming an archive
_NPZ_FIELDS = ("t", "x", "y", "p")
# What a corrupt archive raises from zipfile, zlib or numpy's header parser.
# numpy parses a .npy header with tokenize and ast: TokenError, SyntaxError.
_ZIP_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    KeyError,
    SyntaxError,
    tokenize.TokenError,
    zipfile.BadZipFile,
    zlib.error,
    NotImplementedError,
)


def _npy_header(path: Path, member: IO[bytes], name: str) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise EventFileError(path, f"npz array {name!r} has unsupported .npy version {version}")
    if dtype.hasobject or dtype.kind not in "biuf" or (fortran and len(shape) > 1):
        raise EventFileError(path, f"npz array {name!r} has dtype {dtype}, not numbers")
    return tuple(shape), dtype


def open_npz(
    path: Path, sensor_size: SensorSize | None = None
) -> tuple[SensorSize | None, Iterator[np.ndarray]]:
    """Open an ``.npz`` archive: ``(recorded sensor size or None, chunk iterator)``.

    The arrays are decompressed and decoded ``2**20`` events at a time, so a
    large archive never loads whole.
    """
    recorded = None
    try:
        with zipfile.ZipFile(path) as archive:
            names = {n[: -len(".npy")] for n in archive.namelist() if n.endswith(".npy")}
            missing = [k for k in _NPZ_FIELDS if k not in names]
            if missing:
                raise EventFileError(path, f"npz lacks arrays {missing} (has {sorted(names)})")
            if "width" in names and "height" in names:
                dims = []
                for k in ("width", "height"):
                    with archive.open(f"{k}.npy") as member:
                        value = np.lib.format.read_array(member, allow_pickle=False)
                    if value.size != 1 or value.dtype.kind not in "iu":
                        raise EventFileError(path, f"npz {k} is not one integer: {value!r}")
                    dims.append(int(value.reshape(())))
                recorded = (dims[0], dims[1])
    except EventFileError:
        raise
    except _ZIP_ERRORS as exc:
        raise EventFileError(path, f"not a readable npz archive ({exc})") from None

    def chunks() -> Iterator[np.ndarray]:
        try:
            with contextlib.ExitStack() as stack:
                archive = stack.enter_context(zipfile.ZipFile(path))
                members, dtypes, lengths = [], [], set()
                for k in _NPZ_FIELDS:
                    member = stack.enter_context(archive.open(f"{k}.npy"))
                    shape, dtype = _npy_header(path, member, k)
                    if len(shape) != 1:
                        raise EventFileError(path, f"npz array {k!r} has shape {shape}, not 1-D")
                    members.append(member)
                    dtypes.append(dtype)
                    lengths.add(shape[0])
                if len(lengths) != 1:
                    raise EventFileError(
                        path, f"npz arrays t, x, y, p differ in length: {sorted(lengths)}"
                    )
                remaining = lengths.pop()
                while remaining:
                    n = min(remaining, _NPZ_CHUNK)
                    arrays = []
                    for k, member, dtype in zip(_NPZ_FIELDS, members, dtypes, strict=True):
                        data = member.read(n * dtype.itemsize)
                        if len(data) != n * dtype.itemsize:
                            raise EventFileError(path, f"npz array {k!r} is truncated")
                        arrays.append(np.frombuffer(data, dtype=dtype))
                    remaining -= n
                    try:
                        events = make_events(*arrays)
                    except EventsError as exc:
                        raise EventFileError(path, str(exc)) from None
                    yield events
        except EventFileError:
            raise
        except _ZIP_ERRORS as exc:
            problem = f"corrupt npz archive ({type(exc).__name__}: {exc})"
            raise EventFileError(path, problem) from None

    return recorded, chunks()


# A fixed member date: the archive's bytes depend on the events only (reruns are identical).
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def _zip_member(archive: zipfile.ZipFile, name: str) -> IO[bytes]:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    return archive.open(info, "w", force_zip64=True)


def write_npz(
    tmp_path: Path, chunks: Iterable[np.ndarray], sensor_size: SensorSize, *, target: Path
) -> None:
    """Write ``t, x, y, p, width, height`` to a compressed ``.npz``, streaming.

    The fields are spooled to raw files beside ``tmp_path`` while the chunks
    arrive (the ``.npy`` headers need the final length), then deflated into
    the archive block by block: memory stays bounded by one chunk. The
    archive reads with :func:`numpy.load` like one from
    :func:`numpy.savez_compressed`.
    """
    spools = {k: tmp_path.with_name(f"{tmp_path.name}.{k}") for k in _NPZ_FIELDS}
    n = 0
    try:
        with contextlib.ExitStack() as stack:
            files = {k: stack.enter_context(open(v, "wb")) for k, v in spools.items()}
            for events in chunks:
                if events.size:
                    for k in _NPZ_FIELDS:
                        files[k].write(np.ascontiguousarray(events[k]).tobytes())
                    n += events.size
        with zipfile.ZipFile(tmp_path, "w", allowZip64=True) as archive:
            for k in _NPZ_FIELDS:
                header = {
                    "descr": np.lib.format.dtype_to_descr(EVENT_DTYPE[k]),
                    "fortran_order": False,
                    "shape": (n,),
                }
                with _zip_member(archive, f"{k}.npy") as member, open(spools[k], "rb") as raw:
                    np.lib.format.write_array_header_1_0(member, header)
                    shutil.copyfileobj(raw, member, 1 << 22)
                spools[k].unlink()
            for k, value in (("width", sensor_size[0]), ("height", sensor_size[1])):
                with _zip_member(archive, f"{k}.npy") as member:
                    np.lib.format.write_array(member, np.asarray(value, dtype=np.int64))
    finally:
        for spool in spools.values():
            with contextlib.suppress(FileNotFoundError):
                spool.unlink()


def _columns_from_header(path: Path, header: str) -> tuple[list[int], SensorSize | None]:
    names = [h.strip().lower() for h in header.split(",")]
    size: list[int | None] = [None, None]
    cleaned = []
    for name in names:
        base, _, dim = name.partition("@")
        if dim:
            try:
                size["xy".index(base)] = int(dim)
            except ValueError:
                raise EventFileError(path, f"bad column {name!r} in CSV header") from None
        cleaned.append({"on": "p", "polarity": "p", "pol": "p", "timestamp": "t"}.get(base, base))
    try:
        order = [cleaned.index(k) for k in "txyp"]
    except ValueError:
        raise EventFileError(
            path, f"CSV header {header.strip()!r} must name columns t, x, y and p (or on)"
        ) from None
    recorded = (size[0], size[1]) if size[0] and size[1] else None
    return order, recorded  # type: ignore[return-value]


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def open_text(
    path: Path, sensor_size: SensorSize | None = None
) -> tuple[SensorSize | None, Iterator[np.ndarray]]:
    """Open a ``.txt`` or ``.csv`` file: ``(recorded sensor size or None, chunk iterator)``."""
    is_csv = path.suffix.lower() == ".csv"
    delimiter = "," if is_csv else None
    with open(path, encoding="utf-8", errors="replace") as f:
        first = f.readline()
        skip = 0
        recorded: SensorSize | None = None
        order = [0, 1, 2, 3]
        tokens = first.replace(",", " ").split()
        if first.startswith("#"):
            skip = 1
        elif tokens and not all(_is_number(t) for t in tokens):
            if not is_csv:
                raise EventFileError(path, f"first line {first.strip()!r} is not 't x y p' numbers")
            order, recorded = _columns_from_header(path, first)
            skip = 1
        elif len(tokens) == 2:
            recorded = (int(float(tokens[0])), int(float(tokens[1])))
            skip = 1
        data_line = first if skip == 0 else f.readline()
        seconds = (
            "." in data_line.replace(",", " ").split()[order[0]] if data_line.strip() else False
        )

    def chunks() -> Iterator[np.ndarray]:
        with open(path, encoding="utf-8", errors="replace") as f:
            for _ in range(skip):
                f.readline()
            last_t: int | None = None
            line_no = skip + 1
            while True:
                block = _read_block(f)
                if not block:
                    break
                try:
                    table = np.loadtxt(
                        io.StringIO(block), delimiter=delimiter, dtype=np.float64, ndmin=2
                    )
                except ValueError as exc:
                    raise EventFileError(
                        path, f"malformed line near line {line_no}: {exc}"
                    ) from None
                if table.shape[1] < 4:
                    raise EventFileError(path, f"need 4 columns t x y p, found {table.shape[1]}")
                t = table[:, order[0]]
                if seconds:
                    t = np.round(t * 1e6)
                try:
                    events = make_events(
                        t, table[:, order[1]], table[:, order[2]], table[:, order[3]]
                    )
                except EventsError as exc:
                    raise EventFileError(path, f"{exc} (lines from {line_no})") from None
                if last_t is not None and events.size and events["t"][0] < last_t:
                    raise EventFileError(path, f"timestamps are not sorted near line {line_no}")
                if events.size:
                    last_t = int(events["t"][-1])
                line_no += len(table)
                yield events

    return recorded, chunks()


def _read_block(f: io.TextIOBase) -> str:
    lines = []
    for _ in range(_TEXT_CHUNK_LINES):
        line = f.readline()
        if not line:
            break
        if line.strip():
            lines.append(line)
    return "".join(lines)


def write_txt(
    tmp_path: Path, chunks: Iterable[np.ndarray], sensor_size: SensorSize, *, target: Path
) -> None:
    """Write ``W H`` then one ``t x y p`` line per event."""
    with open(tmp_path, "w", encoding="utf-8") as f:
        f.write(f"{sensor_size[0]} {sensor_size[1]}\n")
        for events in chunks:
            if events.size:
                table = np.column_stack(
                    [events["t"], events["x"], events["y"], events["p"]]
                ).astype(np.int64)
                np.savetxt(f, table, fmt="%d")
