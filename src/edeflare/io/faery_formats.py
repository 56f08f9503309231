"""Prophesee ``.raw`` (EVT 2.0 / 2.1 / 3.0), iniVation ``.aedat4`` and ``.es`` through faery.

faery's Rust decoders are correct on the real recordings we test against
(unlike expelliarmus, which mis-decodes EVT 3.0 timestamps after the 24-bit
wrap) and stream in chunks. Here we add what faery leaves to its caller:
the sensor size of Prophesee files whose header records none, file-naming
errors, and conversion to :data:`edeflare.events.EVENT_DTYPE`.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from pathlib import Path

import faery
import numpy as np

from ..errors import EventFileError
from ..events import EVENT_DTYPE, SensorSize
from .aedat4 import check_aedat4_container

__all__ = ["RawHeader", "open_faery", "read_raw_header", "write_faery"]

# Sensor sizes of Prophesee plugins whose files carry no geometry in the header.
_PLUGIN_SIZES: tuple[tuple[str, SensorSize], ...] = (
    ("gen3_fx3", (640, 480)),
    ("gen31", (640, 480)),
    ("gen3", (640, 480)),
    ("gen41", (1280, 720)),
    ("imx636", (1280, 720)),
    ("gen4", (1280, 720)),
    ("imx646", (1280, 720)),
    ("imx8", (1280, 720)),
    ("genx320", (320, 320)),
    ("imx67", (320, 320)),
)

# faery 0.7's EVT 3.0 encoder advances TIME_HIGH in jumps that its decoder (and other
# readers) cannot follow across the 24-bit wrap, so a written stream must span less
# than 2**24 µs (16.8 s). Real camera files, which emit every TIME_HIGH, read fine.
_EVT3_MAX_SPAN_US = 1 << 24
# EVT 2.0 keeps 34 bits of microseconds (28-bit TIME_HIGH of 64 µs): 4.77 hours.
_EVT2_MAX_SPAN_US = 1 << 34
# A header line is printable ASCII ('%' lines of Prophesee's tools are).
_PRINTABLE = re.compile(r"%[\x20-\x7e\t]*")
_SPAN_LIMITS = {"evt3": (_EVT3_MAX_SPAN_US, "16.8 s"), "evt2": (_EVT2_MAX_SPAN_US, "4.77 h")}


def _faery_failed(exc: BaseException) -> bool:
    """True for errors raised by faery itself, including Rust panics (a BaseException)."""
    return not isinstance(exc, (KeyboardInterrupt, SystemExit, GeneratorExit))


class RawHeader:
    """What a Prophesee ``%`` header says: EVT version and sensor size (or None)."""

    def __init__(self, lines: list[str]) -> None:
        self.lines = lines
        self.version: str | None = None
        self.sensor_size: SensorSize | None = None
        self.plugin: str | None = None
        self.problem: str | None = None  # the first sign of a corrupt header, if any
        for number, line in enumerate(lines, start=1):
            body = line.lstrip("%").strip()
            key, _, value = body.partition(" ")
            value = value.strip()
            if self.problem is None and not _PRINTABLE.fullmatch(line):
                self.problem = f"header line {number} holds non-printable bytes: {line[:60]!r}"
            if key == "evt":
                self.version = {"2.0": "evt2", "2.1": "evt2.1", "3.0": "evt3"}.get(value)
                if self.version is None and self.problem is None:
                    self.problem = f"header line {number}: unknown EVT version {value!r}"
            elif key == "format":
                fmt = value.split(";")[0].strip().upper()
                self.version = {"EVT2": "evt2", "EVT21": "evt2.1", "EVT3": "evt3"}.get(
                    fmt, self.version
                )
                width = re.search(r"width=(\d+)", value)
                height = re.search(r"height=(\d+)", value)
                if width and height:
                    self.sensor_size = (int(width.group(1)), int(height.group(1)))
            elif key == "geometry":
                m = re.fullmatch(r"(\d{1,5})x(\d{1,5})", value)
                if m:
                    self.sensor_size = (int(m.group(1)), int(m.group(2)))
                elif self.problem is None:
                    self.problem = f"header line {number}: malformed geometry {value!r}"
            elif key == "plugin_name":
                self.plugin = value
        if self.sensor_size is None and self.plugin is not None:
            for token, size in _PLUGIN_SIZES:
                if token in self.plugin:
                    self.sensor_size = size
                    break


def read_raw_header(path: Path) -> RawHeader:
    """Parse the ``%`` lines at the start of a Prophesee ``.raw`` file."""
    lines: list[str] = []
    with open(path, "rb") as f:
        while True:
            pos = f.tell()
            first = f.read(1)
            if first != b"%":
                f.seek(pos)
                break
            line = f.readline()
            if not line.endswith(b"\n"):
                raise EventFileError(path, "truncated header")
            lines.append("%" + line.decode("latin-1").rstrip("\r\n"))
            if line.strip() == b"end":  # '% end' closes newer headers
                break
    return RawHeader(lines)


def _to_events(chunk: np.ndarray) -> np.ndarray:
    out = np.empty(chunk.size, dtype=EVENT_DTYPE)
    out["t"] = chunk["t"]
    out["x"] = chunk["x"]
    out["y"] = chunk["y"]
    out["p"] = chunk["on"]
    return out


def _to_faery(events: np.ndarray) -> np.ndarray:
    out = np.empty(events.size, dtype=faery.EVENTS_DTYPE)
    out["t"] = events["t"]
    out["x"] = events["x"]
    out["y"] = events["y"]
    out["on"] = events["p"].astype(bool)
    return out


def open_faery(
    path: Path, sensor_size: SensorSize | None
) -> tuple[SensorSize | None, Iterator[np.ndarray]]:
    """Open a faery-readable file: ``(recorded sensor size or None, chunk iterator)``.

    ``sensor_size`` overrides what the file records (needed for ``.raw``
    files whose header has no geometry and no known plugin).
    """
    suffix = path.suffix.lower()
    recorded: SensorSize | None = None
    kwargs: dict[str, object] = {}
    if suffix == ".raw":
        header = read_raw_header(path)
        if not header.lines:
            raise EventFileError(path, "no Prophesee '%' header: not an EVT .raw file")
        if header.problem is not None:
            raise EventFileError(path, f"corrupt Prophesee header: {header.problem}")
        if header.version is None:
            raise EventFileError(
                path, "header names no EVT version ('% evt 2.0|3.0' or '% format')"
            )
        recorded = header.sensor_size
        kwargs["version_fallback"] = header.version
        # Decoding needs some size; with none known, accept any coordinate and infer later.
        kwargs["dimensions_fallback"] = sensor_size or recorded or (65535, 65535)
    elif suffix == ".aedat4":
        check_aedat4_container(path)  # what would abort faery's decoder is refused here
    try:
        decoder = faery.events_stream_from_file(path, **kwargs)  # type: ignore[arg-type]
        if suffix != ".raw":
            recorded = tuple(int(v) for v in decoder.dimensions())  # type: ignore[assignment]
    except BaseException as exc:  # faery raises bare Exception, RuntimeError or Rust panics
        if not _faery_failed(exc):
            raise
        raise EventFileError(path, f"cannot decode ({exc})") from None

    def chunks() -> Iterator[np.ndarray]:
        try:
            for chunk in decoder:
                yield _to_events(chunk)
        except EventFileError:
            raise
        except BaseException as exc:
            if not _faery_failed(exc):
                raise
            raise EventFileError(path, f"corrupt or truncated data ({exc})") from None

    return recorded, chunks()


def write_faery(
    tmp_path: Path,
    chunks: Iterable[np.ndarray],
    sensor_size: SensorSize,
    *,
    target: Path,
    evt_version: str = "evt2",
) -> None:
    """Write chunks with faery to ``tmp_path`` (whose suffix picks the format).

    ``.raw`` keeps absolute time (t0 in the header); ``.es`` has no offset
    field, so its times start at the first event (as faery writes them).
    """
    suffix = target.suffix.lower()
    first: list[int] = []
    upstream: list[BaseException] = []  # an error of the caller's chunks, not of faery

    def converted() -> Iterator[np.ndarray]:
        try:
            yield from _converted()
        except BaseException as exc:
            upstream.append(exc)
            raise

    def _converted() -> Iterator[np.ndarray]:
        for events in chunks:
            if events.size == 0:
                continue
            t = events["t"]
            if t[0] < 0:
                raise EventFileError(target, f"{suffix} cannot store negative timestamps")
            if not first:
                first.append(int(t[0]))
            if suffix == ".raw" and int(t[-1]) - first[0] >= _SPAN_LIMITS[evt_version][0]:
                limit = _SPAN_LIMITS[evt_version][1]
                raise EventFileError(
                    target,
                    f"{evt_version.upper()} output must span less than {limit}; this stream "
                    f"spans {(int(t[-1]) - first[0]) / 1e6:.1f} s. Use evt2 (4.77 h) or .h5",
                )
            yield _to_faery(events)

    kwargs: dict[str, object] = {}
    if suffix == ".raw":
        kwargs["version"] = evt_version
    try:
        faery.file_encoder.events_to_file(
            converted(),
            tmp_path,
            dimensions=sensor_size,
            zero_t0=True,
            use_write_suffix=False,
            file_type={".raw": "evt", ".aedat4": "aedat", ".es": "es", ".csv": "csv"}[suffix],
            **kwargs,  # type: ignore[arg-type]
        )
    except BaseException as exc:
        if upstream:  # raised where it arose (a method's bug stays a bug, not a file error)
            raise upstream[0] from None
        if isinstance(exc, EventFileError) or not _faery_failed(exc):
            raise
        raise EventFileError(target, f"cannot write ({exc})") from None
