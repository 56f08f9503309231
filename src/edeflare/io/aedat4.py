"""Checks of an AEDAT 4 container before faery decodes it.

faery's Rust decoder turns the header's XML description into a Python
string; when that text is not valid UTF-8 the conversion fails inside a
destructor and the Rust runtime aborts the whole process (SIGABRT, exit
134), which no Python code can catch. So we read the header ourselves
first and refuse what would abort.

Layout (iniVation, AEDAT 4.0)::

    "#!AER-DAT4.0\\r\\n"          14 bytes of magic
    int32 header_size             little-endian
    IOHeader                      a flatbuffer of header_size bytes:
        compression: int32        0 none, 1 LZ4, 2 LZ4 high, 3 zstd, 4 zstd high
        dataTablePosition: int64  -1 if absent
        infoNode: string          the XML description of the streams
    packets ...                   int32 stream id, int32 size, size bytes
"""

from __future__ import annotations

import os
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

from ..errors import EventFileError

__all__ = ["check_aedat4_container"]

MAGIC = b"#!AER-DAT4.0\r\n"
_MAX_HEADER = 1 << 24  # 16 MiB: a description of a few streams is a few KiB


def _u32(buf: bytes, pos: int, what: str, path: Path) -> int:
    if pos < 0 or pos + 4 > len(buf):
        raise EventFileError(path, f"corrupt AEDAT 4 header: {what} lies outside the header")
    return int(struct.unpack_from("<I", buf, pos)[0])


def check_aedat4_container(path: str | os.PathLike[str]) -> str:
    """Check an AEDAT 4 file's magic and header; return its XML description.

    Parameters
    ----------
    path : path-like
        The ``.aedat4`` file.

    Returns
    -------
    str
        The header's XML description of the streams.

    Raises
    ------
    EventFileError
        Not AEDAT 4 (bad magic), a header that does not fit in the file, a
        flatbuffer whose offsets point outside it, an unknown compression, a
        data-table position outside the file, or a description that is not
        UTF-8 or not well-formed XML.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io import write_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "ev.aedat4"
    >>> write_events(path, make_events([0, 5], [1, 2], [1, 2], [1, 0]), (4, 4))
    >>> check_aedat4_container(path).startswith("<dv")
    True
    >>> _ = path.write_bytes(b"#!AER-DAT4.0\\r\\n\\x08\\x00\\x00\\x00" + bytes(8))
    >>> check_aedat4_container(path)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
      ...
    edeflare.errors.EventFileError: ...: corrupt AEDAT 4 header: ...
    """
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as f:
        magic = f.read(len(MAGIC))
        if magic != MAGIC:
            raise EventFileError(path, "not an AEDAT 4 file (no '#!AER-DAT4.0' magic)")
        raw = f.read(4)
        if len(raw) < 4:
            raise EventFileError(path, "truncated AEDAT 4 header")
        (header_size,) = struct.unpack("<i", raw)
        if header_size < 8 or header_size > _MAX_HEADER:
            raise EventFileError(path, f"corrupt AEDAT 4 header: size {header_size}")
        buf = f.read(header_size)
    if len(buf) < header_size:
        raise EventFileError(path, "truncated AEDAT 4 header")
    # Flatbuffer: root table offset, its vtable, then each field by the vtable's offsets.
    table = _u32(buf, 0, "root table", path)
    soffset = struct.unpack_from("<i", buf, table)[0] if table + 4 <= len(buf) else None
    if soffset is None:
        raise EventFileError(path, "corrupt AEDAT 4 header: root table lies outside the header")
    vtable = table - soffset
    if vtable < 0 or vtable + 4 > len(buf):
        raise EventFileError(path, "corrupt AEDAT 4 header: vtable lies outside the header")
    vt_size, _ = struct.unpack_from("<HH", buf, vtable)
    if vt_size < 4 or vt_size % 2 or vtable + vt_size > len(buf):
        raise EventFileError(path, f"corrupt AEDAT 4 header: vtable of {vt_size} bytes")
    fields = struct.unpack_from(f"<{(vt_size - 4) // 2}H", buf, vtable + 4)

    def field(k: int) -> int | None:
        return table + fields[k] if k < len(fields) and fields[k] else None

    pos = field(0)
    if pos is not None:
        if pos + 4 > len(buf):
            raise EventFileError(path, "corrupt AEDAT 4 header: compression lies outside it")
        compression = struct.unpack_from("<i", buf, pos)[0]
        if compression not in range(5):
            raise EventFileError(path, f"corrupt AEDAT 4 header: unknown compression {compression}")
    pos = field(1)
    if pos is not None:
        if pos + 8 > len(buf):
            raise EventFileError(path, "corrupt AEDAT 4 header: data table lies outside it")
        table_pos = struct.unpack_from("<q", buf, pos)[0]
        if table_pos != -1 and not 0 <= table_pos < size:
            raise EventFileError(
                path,
                f"corrupt or truncated AEDAT 4 file: its data table at byte {table_pos} "
                f"lies beyond its end ({size} bytes)",
            )
    pos = field(2)
    if pos is None:
        raise EventFileError(path, "corrupt AEDAT 4 header: no stream description")
    start = pos + _u32(buf, pos, "description", path)
    length = _u32(buf, start, "description", path)
    if start + 4 + length > len(buf):
        raise EventFileError(path, "corrupt AEDAT 4 header: description runs past the header")
    try:
        text = buf[start + 4 : start + 4 + length].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EventFileError(
            path, f"corrupt AEDAT 4 header: description is not UTF-8 (byte {exc.start})"
        ) from None
    try:
        ET.fromstring(text)
    except ET.ParseError as exc:
        raise EventFileError(
            path, f"corrupt AEDAT 4 header: description is not well-formed XML ({exc})"
        ) from None
    return text
