"""Prophesee/Chronocam ``.dat`` TD files: our own numpy codec.

faery refuses DAT files whose event type byte is 0x00 ("Event2d", written by
the ATIS/Chronocam tools and found in N-CARS and tonic's samples) and reads
only type 0x0C ("CD"). Both share one layout, so we decode them ourselves,
read in chunks::

    % text header lines (``% Width 304``, ``% Height 240``, ``% Version 2``...)
    uint8 event type, uint8 event size (8)
    per event: uint32 t (µs), uint32 data

with ``x = data & 0x3FFF``, ``y = (data >> 14) & 0x3FFF``, ``p = data >> 28``
(version 2; version 1 packs ``x`` in 9 bits, ``y`` in 8 bits and ``p`` in
bit 17). Times are 32-bit and wrap after 71.6 minutes; the reader unwraps
them, the writer stores ``t - t0`` with ``% t0`` in the header.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from ..errors import EventFileError
from ..events import EVENT_DTYPE, SensorSize

__all__ = ["open_dat", "write_dat"]

_RECORD = np.dtype([("t", "<u4"), ("data", "<u4")])
_CHUNK = 1 << 20


def _parse_header(path: Path) -> tuple[dict[str, str], int, int]:
    """``(header fields, event type, offset of the first record)``."""
    fields: dict[str, str] = {}
    with open(path, "rb") as f:
        while True:
            pos = f.tell()
            if f.read(1) != b"%":
                f.seek(pos)
                break
            line = f.readline()
            if not line.endswith(b"\n"):
                raise EventFileError(path, "truncated header")
            text = line.decode("latin-1").rstrip("\r\n")
            if not text.isprintable() or not text.isascii():
                raise EventFileError(
                    path, f"corrupt header: line {len(fields) + 1} holds non-printable bytes"
                )
            key, _, value = text.strip().partition(" ")
            fields[key.lower()] = value.strip()
        type_size = f.read(2)
        if len(type_size) < 2:
            raise EventFileError(path, "no event type/size bytes after the header")
        offset = f.tell()
    event_type, event_size = type_size[0], type_size[1]
    if event_type not in (0x00, 0x0C) or event_size != 8:
        raise EventFileError(
            path,
            f"unsupported DAT event type {event_type:#04x} / size {event_size} (want TD, 8 bytes)",
        )
    return fields, event_type, offset


def open_dat(
    path: Path, sensor_size: SensorSize | None = None
) -> tuple[SensorSize | None, Iterator[np.ndarray]]:
    """Open a DAT file: ``(recorded sensor size or None, chunk iterator)``."""
    fields, _, offset = _parse_header(path)
    recorded: SensorSize | None = None
    if "width" in fields and "height" in fields:
        try:
            recorded = (int(fields["width"]), int(fields["height"]))
        except ValueError:
            raise EventFileError(path, "bad Width/Height in header") from None
    version = fields.get("version", "2").strip()
    try:
        t0 = int(fields.get("t0", "0") or 0)
    except ValueError:
        raise EventFileError(path, f"corrupt header: bad t0 {fields['t0']!r}") from None
    body = path.stat().st_size - offset
    if body % _RECORD.itemsize:
        raise EventFileError(
            path, f"truncated: {body} bytes of events is not a multiple of {_RECORD.itemsize}"
        )
    n = body // _RECORD.itemsize

    def chunks() -> Iterator[np.ndarray]:
        wraps = 0
        last = None
        # Read block by block rather than through a memory map: a map's pages
        # stay in the resident set, which then grows with the file.
        with open(path, "rb") as f:
            f.seek(offset)
            for start in range(0, n, _CHUNK):
                block = np.fromfile(f, dtype=_RECORD, count=min(_CHUNK, n - start))
                if block.size < min(_CHUNK, n - start):
                    raise EventFileError(path, "truncated while reading")
                t32 = block["t"].astype(np.int64)
                data = block["data"]
                # unwrap 32-bit time: each large backwards jump is one wrap
                prev = t32[0] if last is None else last
                jumps = np.diff(t32, prepend=prev) < -(1 << 31)
                t = t32 + ((wraps + np.cumsum(jumps)) << 32)
                wraps += int(jumps.sum())
                last = int(t32[-1])
                out = np.empty(block.size, dtype=EVENT_DTYPE)
                out["t"] = t + t0
                if version == "1":
                    out["x"] = data & 0x1FF
                    out["y"] = (data >> 9) & 0xFF
                    out["p"] = (data >> 17) & 1
                else:
                    out["x"] = data & 0x3FFF
                    out["y"] = (data >> 14) & 0x3FFF
                    pol = data >> 28
                    if pol.size and pol.max() > 1:
                        raise EventFileError(path, "polarity nibble other than 0/1: not a TD file?")
                    out["p"] = pol
                yield out

    return recorded, chunks()


def write_dat(
    tmp_path: Path, chunks: Iterable[np.ndarray], sensor_size: SensorSize, *, target: Path
) -> None:
    """Write a version-2 CD DAT file with ``% Width``, ``% Height`` and ``% t0`` header lines."""
    width, height = sensor_size
    if width > 1 << 14 or height > 1 << 14:
        raise EventFileError(target, "DAT stores coordinates in 14 bits (max 16384)")
    chunk_iter = iter(chunks)
    first = next((c for c in chunk_iter if c.size), None)
    t0 = 0 if first is None else int(first["t"][0])
    header = (
        "% Data file containing CD events.\n% Version 2\n"
        f"% Width {width}\n% Height {height}\n% t0 {t0}\n"
    ).encode()
    with open(tmp_path, "wb") as f:
        f.write(header)
        f.write(bytes([0x0C, 8]))
        if first is None:
            return
        for events in _chain(first, chunk_iter):
            rel = events["t"] - t0
            if rel.size and (rel.min() < 0 or rel.max() >= 1 << 32):
                raise EventFileError(target, "DAT stores 32-bit times: span must be under 71.6 min")
            rec = np.empty(events.size, dtype=_RECORD)
            rec["t"] = rel
            rec["data"] = (
                events["x"].astype(np.uint32)
                | (events["y"].astype(np.uint32) << 14)
                | (events["p"].astype(np.uint32) << 28)
            )
            rec.tofile(f)


def _chain(first: np.ndarray, rest: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
    yield first
    yield from rest
