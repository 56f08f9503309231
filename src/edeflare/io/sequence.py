"""Sequence files: the one owner of their layout (paired datasets, real pairs, DSEC windows).

A *sequence file* is one HDF5 file holding several event streams, each in the
DSEC layout under its own group (:func:`edeflare.io.dsec.write_dsec_groups`):

- ``input``: the flare-corrupted events (always);
- ``gt``: the ground truth (paired sequences; a ``dsec-flare`` window has none);
- ``flare``, ``light``, ``background``: the pure streams of a simulated sample
  (optional, so other compositions can be rebuilt);

optionally ``frames/t_us`` and ``frames/intensity`` (float16 ``(T, H, W)``):
the clean scene's intensity image (0-255 scale) at the given instants, the
ground truth of reconstructions (simulated test sets, :func:`read_frames`);
and root attributes ``sensor_size`` and ``t_start_us`` / ``t_end_us`` (the
span ``[t_start_us, t_end_us)``; its aligned windows start at ``t_start_us``;
without them the span is that of the events), plus the writer's provenance
(recipe, seed, script, ...). A dataset folder holds such files (``*.h5``),
e.g. ``train/`` and ``test/``.

Writers: :func:`edeflare.data.generate.write_sequence` (simulated datasets) and
:func:`edeflare.realworld.pair_recordings` (real pairs). Readers:
:mod:`edeflare.data.pairs` (training windows), :mod:`edeflare.eval.benchmark`.

Examples
--------
>>> import tempfile, pathlib
>>> from edeflare.events import make_events
>>> path = pathlib.Path(tempfile.mkdtemp()) / "seq.h5"
>>> ev = make_events([10, 20], [0, 1], [0, 0], [1, 0])
>>> write_sequence(path, {"input": ev, "gt": ev[:1]}, (2, 1),
...                {"t_start_us": 0, "t_end_us": 40_000})
>>> inp, gt, size, start, end = read_sequence(path)
>>> inp.size, gt.size, size, start, end
(2, 1, (2, 1), 0, 40000)
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..errors import EventFileError, ParameterError
from ..events import SensorSize
from .dsec import DsecReader, write_dsec_groups

__all__ = [
    "GROUPS",
    "check_paired",
    "file_sha256",
    "list_sequences",
    "read_frames",
    "read_sequence",
    "sequence_counts",
    "sequence_span",
    "write_sequence",
]

GROUPS = ("input", "gt", "gt_full", "flare", "light", "background")
"""Event groups a sequence file may hold, in the order they are written (``gt_full``:
the simulator's own ground truth where ``gt`` is a keep-only target,
:mod:`edeflare.sim.sensing`)."""


def write_sequence(
    path: str | os.PathLike[str],
    streams: Mapping[str, np.ndarray],
    sensor_size: SensorSize,
    attrs: Mapping[str, Any],
    frames: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Write a sequence file atomically: ``streams`` (group -> events) and root ``attrs``.

    ``attrs`` must hold ``t_start_us`` and ``t_end_us`` (stored as int64); the
    other attributes are the writer's provenance, stored in the order given.
    ``frames``: ``(times_us (T,), images (T, H, W))``, the clean scene's
    intensity images (stored as float16).

    Raises
    ------
    ParameterError
        A group not in :data:`GROUPS`, no ``input`` group, or no valid span.
    """
    unknown = [g for g in streams if g not in GROUPS]
    if unknown or "input" not in streams:
        raise ParameterError(
            f"a sequence file holds an 'input' group and others of {GROUPS}, got {list(streams)}"
        )
    if "t_start_us" not in attrs or "t_end_us" not in attrs:
        raise ParameterError("a sequence file records its span: attrs need t_start_us, t_end_us")
    start, end = int(attrs["t_start_us"]), int(attrs["t_end_us"])
    if end <= start:
        raise ParameterError(f"need t_end_us > t_start_us, got [{start}, {end})")
    stored = dict(attrs)
    stored["t_start_us"], stored["t_end_us"] = np.int64(start), np.int64(end)
    datasets = None
    if frames is not None:
        times, images = np.asarray(frames[0], dtype=np.int64), np.asarray(frames[1])
        width, height = sensor_size
        if times.ndim != 1 or images.shape != (times.size, height, width):
            raise ParameterError(
                f"frames must be (T,) times and (T, {height}, {width}) images, "
                f"got {times.shape} and {images.shape}"
            )
        if not np.isfinite(images).all():
            raise ParameterError("frames hold NaN or infinite values")
        datasets = {"frames/t_us": times, "frames/intensity": images.astype(np.float16)}
    write_dsec_groups(path, dict(streams), sensor_size, stored, datasets)


def read_frames(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """The clean scene's images of a sequence: ``(times_us, float32 (T, H, W))``, or None.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "seq.h5"
    >>> ev = make_events([10], [0], [0], [1])
    >>> write_sequence(path, {"input": ev}, (2, 1), {"t_start_us": 0, "t_end_us": 20},
    ...                frames=([20], np.full((1, 1, 2), 3.0)))
    >>> times, images = read_frames(path)
    >>> times.tolist(), images.tolist()
    ([20], [[[3.0, 3.0]]])
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            if "frames" not in f:
                return None
            times = np.asarray(f["frames/t_us"][()], dtype=np.int64)
            images = np.asarray(f["frames/intensity"][()], dtype=np.float32)
    except (OSError, KeyError, ValueError, RuntimeError) as exc:
        raise EventFileError(path, f"cannot read its frames ({exc})") from None
    if images.ndim != 3 or images.shape[0] != times.size:
        raise EventFileError(
            path, f"frames of shape {images.shape} do not match {times.size} times"
        )
    return times, images


def list_sequences(folder: str | os.PathLike[str]) -> list[Path]:
    """Sequence files (``*.h5``) of a folder, sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise EventFileError(folder, "no such dataset folder")
    files = sorted(p for p in folder.glob("*.h5") if not p.name.startswith("."))
    if not files:
        raise EventFileError(folder, "holds no sequence files (*.h5)")
    return files


def check_paired(path: str | os.PathLike[str], groups: Sequence[str] = ("input", "gt")) -> None:
    """Raise :class:`~edeflare.errors.EventFileError` unless the file holds every event group.

    A sequence without ground truth (e.g. a ``dsec-flare`` window, ``input``
    only) gets a message that says what it can be used for instead.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec_groups
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "real.h5"
    >>> write_dsec_groups(p, {"input": make_events([0], [0], [0], [1])}, (2, 2))
    >>> check_paired(p)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.EventFileError: ...real.h5: holds no 'gt' events (no ground truth: ...
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            missing = [g for g in groups if not isinstance(f.get(f"{g}/events"), h5py.Group)]
    except OSError as exc:
        raise EventFileError(path, f"not a readable HDF5 file ({exc})") from None
    if missing == ["gt"]:
        raise EventFileError(
            path,
            "holds no 'gt' events (no ground truth: a real sequence such as a dsec-flare "
            "window, for qualitative evaluation); de-flare its input with `edeflare deflare` "
            "and look at it with `edeflare view` instead",
        )
    if missing:
        raise EventFileError(path, f"holds no {missing} event group(s); not a paired sequence")


def _no_size(path: Path) -> SensorSize:
    raise EventFileError(path, "records no sensor_size attribute")


def sequence_span(
    path: str | os.PathLike[str], groups: Sequence[str] = ("input", "gt")
) -> tuple[SensorSize, int, int] | None:
    """Sensor size and span ``[start, end)`` of a sequence (None when it holds no events).

    The recorded ``t_start_us`` / ``t_end_us``, else the span of the groups' events.
    """
    path = Path(path)
    check_paired(path, groups)
    starts, ends = [], []
    size: SensorSize | None = None
    for group in groups:
        with DsecReader(path, group=f"{group}/events") as reader:
            size = size or reader.recorded_sensor_size
            attrs = reader.root_attrs
            span = reader.time_range()
        if "t_start_us" in attrs and "t_end_us" in attrs:
            return size or _no_size(path), int(attrs["t_start_us"]), int(attrs["t_end_us"])
        if span is not None:
            starts.append(span[0])
            ends.append(span[1] + 1)
    if size is None:
        _no_size(path)
    if not starts:
        return None
    return size, min(starts), max(ends)  # type: ignore[return-value]


def read_sequence(path: str | os.PathLike[str]) -> tuple[Any, Any, tuple[int, int], int, int]:
    """``(input events, gt events, sensor_size, t_start_us, t_end_us)`` of a paired sequence."""
    check_paired(path)
    with DsecReader(path, group="input/events") as reader:
        inp = reader.read()
        size = reader.recorded_sensor_size
        attrs = reader.root_attrs
        span = reader.time_range()
    with DsecReader(path, group="gt/events") as reader:
        gt = reader.read()
        gt_span = reader.time_range()
    if "t_start_us" in attrs and "t_end_us" in attrs:
        start, end = int(attrs["t_start_us"]), int(attrs["t_end_us"])
    else:
        spans = [s for s in (span, gt_span) if s is not None]
        start = min(s[0] for s in spans) if spans else 0
        end = max(s[1] for s in spans) + 1 if spans else 0
    return inp, gt, size, start, end  # type: ignore[return-value]


def sequence_counts(path: str | os.PathLike[str]) -> tuple[dict[str, int], dict[str, Any]]:
    """Events per group and the root attributes of a sequence file (for manifests)."""
    with h5py.File(path, "r") as f:
        counts = {g: int(f[g]["events/t"].shape[0]) for g in GROUPS if g in f}
        attrs = dict(f.attrs)
    return counts, attrs


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes (hex), read in 1 MiB blocks (manifests record it)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
