"""``.npz`` archives and plain-text ``.txt`` / ``.csv`` event files.

- ``.npz``: arrays ``t`` (int64 µs), ``x``, ``y``, ``p`` (1 = ON, 0 = OFF;
  -1/+1 and bool accepted on reading) and scalars ``width``, ``height``;
  loaded with ``allow_pickle=False``.
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

import io
import zipfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from ..errors import EventFileError, EventsError
from ..events import EVENT_DTYPE, SensorSize, make_events

__all__ = ["open_npz", "open_text", "write_npz", "write_txt"]

_TEXT_CHUNK_LINES = 1 << 20


def open_npz(
    path: Path, sensor_size: SensorSize | None = None
) -> tuple[SensorSize | None, Iterator[np.ndarray]]:
    """Open an ``.npz`` archive: ``(recorded sensor size or None, one-chunk iterator)``."""

    def load(names: tuple[str, ...]) -> dict[str, np.ndarray]:
        try:
            with np.load(path, allow_pickle=False) as archive:
                missing = [k for k in "txyp" if k not in archive.files]
                if missing:
                    raise EventFileError(
                        path, f"npz lacks arrays {missing} (has {sorted(archive.files)})"
                    )
                return {k: archive[k] for k in names if k in archive.files}
        except EventFileError:
            raise
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise EventFileError(path, f"not a readable npz archive ({exc})") from None

    meta = load(("width", "height"))
    recorded = None
    if "width" in meta and "height" in meta:
        recorded = (int(meta["width"]), int(meta["height"]))

    def chunks() -> Iterator[np.ndarray]:
        arrays = load(("t", "x", "y", "p"))
        try:
            yield make_events(arrays["t"], arrays["x"], arrays["y"], arrays["p"])
        except EventsError as exc:
            raise EventFileError(path, str(exc)) from None

    return recorded, chunks()


def write_npz(
    tmp_path: Path, chunks: Iterable[np.ndarray], sensor_size: SensorSize, *, target: Path
) -> None:
    """Write ``t, x, y, p, width, height`` to a compressed ``.npz``."""
    parts = [c for c in chunks if c.size]
    events = np.concatenate(parts) if parts else np.zeros(0, EVENT_DTYPE)
    with open(tmp_path, "wb") as f:
        np.savez_compressed(
            f,
            t=events["t"],
            x=events["x"],
            y=events["y"],
            p=events["p"],
            width=np.int64(sensor_size[0]),
            height=np.int64(sensor_size[1]),
        )


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
