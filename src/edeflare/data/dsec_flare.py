r"""DSEC-Flare: the paper's curated real sequences, cut from the user's own DSEC copy.

The paper (App. A.4) picks left-camera (640x480) DSEC sequences where lens
flare is severe, in two groups (:data:`DSEC_FLARE_SEQUENCES`):

- periodic streetlight flare: ``zurich_city_03_a``, ``zurich_city_10_b``,
  ``zurich_city_12_a``;
- complex urban flare: ``zurich_city_09_c``, ``zurich_city_09_d``.

They have no ground truth: they serve qualitative evaluation. This module
finds them in a local DSEC folder (nothing is downloaded) and cuts 100 ms
windows from them. A :class:`WindowSpec` asks for ``count`` consecutive
windows centred on a time (seconds on the file's own time axis, i.e. after
its ``t_offset``; None: the middle of the recording). The defaults
(:data:`DEFAULT_WINDOWS`) are three windows around 7.6 s of ``03_a`` and
around 26 s of ``09_c``, where the paper shows its examples, and three
windows in the middle of each of the three others (the paper gives no times
for them; choose your own).

Layouts found under the root, for each sequence ``<seq>``::

    <root>/<seq>/events/left/events.h5           (+ rectify_map.h5 beside it)
    <root>/{train,test}/<seq>/events/left/events.h5      (train_events.zip ...)
    <root>/{train_events,test_events}/<seq>/events/left/events.h5
    <root>/<seq>/events_left/events.h5           (<seq>_events_left.zip)
    <root>/<seq>_events_left/events.h5

A window's events keep their pixels (or are rectified with
``rectify_map.h5`` when asked: each event moves to its rounded rectified
position, and events that leave the sensor are dropped) and get times
relative to the window start, so a window spans ``[0, duration)`` like a
simulated sequence; the absolute DSEC time of ``t = 0`` is recorded.

Examples
--------
>>> [w.sequence for w in DEFAULT_WINDOWS][:2]
['zurich_city_03_a', 'zurich_city_09_c']
>>> len(expand_windows(DEFAULT_WINDOWS))
15
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from ..errors import EdeflareError, EventFileError, ParameterError
from ..events import SensorSize, check_sensor_size
from ..io.dsec import DsecReader
from .kinds import KindSequence, register_kind

if TYPE_CHECKING:  # pragma: no cover
    from .recipe import Recipe

__all__ = [
    "DEFAULT_WINDOWS",
    "DSEC_FLARE_SEQUENCES",
    "DsecFlareConfig",
    "DsecFlareError",
    "DsecWindow",
    "WindowSpec",
    "dsec_sequence",
    "expand_windows",
    "find_dsec_sequences",
    "parse_window",
    "read_window",
]

DSEC_FLARE_SEQUENCES: dict[str, str] = {
    "zurich_city_03_a": "periodic streetlight flare",
    "zurich_city_10_b": "periodic streetlight flare",
    "zurich_city_12_a": "periodic streetlight flare",
    "zurich_city_09_c": "complex urban flare",
    "zurich_city_09_d": "complex urban flare",
}
"""The paper's DSEC-Flare sequences and their flare category."""


class DsecFlareError(EdeflareError, ValueError):
    """DSEC-Flare cannot be extracted as asked (the message says why and what to do)."""


@dataclass(frozen=True)
class WindowSpec:
    """``count`` consecutive windows of one sequence, centred on ``center_s`` (None: mid-file).

    Examples
    --------
    >>> WindowSpec("zurich_city_03_a", 7.6).count
    3
    """

    sequence: str
    center_s: float | None = None
    count: int = 3

    def __post_init__(self) -> None:
        if not isinstance(self.sequence, str) or not self.sequence or "/" in self.sequence:
            raise ParameterError(f"a DSEC sequence name is needed, got {self.sequence!r}")
        if self.center_s is not None:
            try:
                center = float(self.center_s)
            except (TypeError, ValueError):
                raise ParameterError(
                    f"center_s must be seconds or None, got {self.center_s!r}"
                ) from None
            if not math.isfinite(center) or center < 0:
                raise ParameterError(f"center_s must be >= 0 seconds, got {self.center_s!r}")
            object.__setattr__(self, "center_s", center)
        if isinstance(self.count, bool) or not isinstance(self.count, (int, np.integer)):
            raise ParameterError(f"count must be an int >= 1, got {self.count!r}")
        if self.count < 1:
            raise ParameterError(f"count must be an int >= 1, got {self.count!r}")
        object.__setattr__(self, "count", int(self.count))


DEFAULT_WINDOWS: tuple[WindowSpec, ...] = (
    WindowSpec("zurich_city_03_a", 7.6),
    WindowSpec("zurich_city_09_c", 26.0),
    WindowSpec("zurich_city_10_b"),
    WindowSpec("zurich_city_12_a"),
    WindowSpec("zurich_city_09_d"),
)
"""Three 100 ms windows around 7.6 s of 03_a and 26 s of 09_c (the paper's examples), and
three in the middle of each other sequence (no times in the paper)."""


def parse_window(text: str) -> WindowSpec:
    """Parse ``SEQ``, ``SEQ:CENTER_S`` or ``SEQ:CENTER_S:COUNT`` (``mid`` for the middle).

    Examples
    --------
    >>> parse_window("zurich_city_10_b:12.5:2")
    WindowSpec(sequence='zurich_city_10_b', center_s=12.5, count=2)
    >>> parse_window("zurich_city_12_a:mid").center_s is None
    True
    """
    parts = text.split(":")
    if not 1 <= len(parts) <= 3 or not parts[0]:
        raise ParameterError(f"a window must look like SEQ[:CENTER_S[:COUNT]], got {text!r}")
    center: float | None = None
    count = 3
    try:
        if len(parts) > 1 and parts[1] not in ("", "mid"):
            center = float(parts[1])
        if len(parts) > 2:
            count = int(parts[2])
    except ValueError:
        raise ParameterError(
            f"a window must look like SEQ[:CENTER_S[:COUNT]] (seconds, windows), got {text!r}"
        ) from None
    return WindowSpec(parts[0], center, count)


@dataclass(frozen=True)
class DsecFlareConfig:
    """Where DSEC lives and which windows to cut.

    Parameters
    ----------
    root : str, optional
        The local DSEC folder (see the module docstring for the layouts).
    windows : tuple of WindowSpec
    rectify : bool
        Move events to their rectified positions with ``rectify_map.h5``.

    Examples
    --------
    >>> c = DsecFlareConfig.from_dict({"windows": [["zurich_city_03_a", 7.6, 1]]})
    >>> c.windows
    (WindowSpec(sequence='zurich_city_03_a', center_s=7.6, count=1),)
    >>> DsecFlareConfig.from_dict(c.to_dict()) == c
    True
    """

    root: str | None = None
    windows: tuple[WindowSpec, ...] = DEFAULT_WINDOWS
    rectify: bool = False

    def __post_init__(self) -> None:
        if self.root is not None:
            object.__setattr__(self, "root", os.fspath(self.root))
        windows = tuple(self.windows)
        if not windows or not all(isinstance(w, WindowSpec) for w in windows):
            raise ParameterError("windows must be a non-empty sequence of WindowSpec")
        object.__setattr__(self, "windows", windows)
        if not isinstance(self.rectify, bool):
            raise ParameterError(f"rectify must be a bool, got {self.rectify!r}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> DsecFlareConfig:
        """Build from a mapping (windows as ``[sequence, center_s, count]`` lists)."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"the dsec config must be a mapping, got {type(data).__name__}")
        unknown = sorted(set(data) - {"root", "windows", "rectify"})
        if unknown:
            raise ParameterError(
                f"unknown dsec key(s) {unknown}; valid keys: ['rectify', 'root', 'windows']"
            )
        d = dict(data)
        if "windows" in d:
            try:
                d["windows"] = tuple(
                    w if isinstance(w, WindowSpec) else WindowSpec(*w) for w in d["windows"]
                )
            except TypeError:
                raise ParameterError(
                    f"windows must be [sequence, center_s, count] lists, got {d['windows']!r}"
                ) from None
        return cls(**d)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "root": self.root,
            "windows": [[w.sequence, w.center_s, w.count] for w in self.windows],
            "rectify": self.rectify,
        }

    @property
    def sequences(self) -> list[str]:
        """The sequences the windows come from, in order of first appearance."""
        return list(dict.fromkeys(w.sequence for w in self.windows))


def expand_windows(windows: Sequence[WindowSpec]) -> list[tuple[WindowSpec, int]]:
    """One ``(spec, k)`` per output window: the ``k``-th window of ``spec``, in order."""
    return [(w, k) for w in windows for k in range(w.count)]


def _candidates(root: Path, sequence: str) -> list[Path]:
    bases = [root] + [root / b for b in ("train", "test", "train_events", "test_events")]
    paths = []
    for base in bases:
        paths.append(base / sequence / "events" / "left" / "events.h5")
        paths.append(base / sequence / "events_left" / "events.h5")
    paths.append(root / f"{sequence}_events_left" / "events.h5")
    return paths


def find_dsec_sequences(
    root: str | os.PathLike[str], sequences: Sequence[str] = tuple(DSEC_FLARE_SEQUENCES)
) -> dict[str, Path]:
    """The left-camera ``events.h5`` of each sequence under ``root``.

    Raises :class:`DsecFlareError` naming the sequences found and missing (and
    where they were looked for) unless every one is there.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> f = root / "train" / "zurich_city_03_a" / "events" / "left" / "events.h5"
    >>> f.parent.mkdir(parents=True); _ = f.write_bytes(b"")
    >>> find_dsec_sequences(root, ["zurich_city_03_a"])["zurich_city_03_a"] == f
    True
    """
    root = Path(root)
    if not root.is_dir():
        raise EventFileError(root, "no such folder (the local DSEC download)")
    found: dict[str, Path] = {}
    for seq in sequences:
        hit = next((p for p in _candidates(root, seq) if p.is_file()), None)
        if hit is not None:
            found[seq] = hit
    missing = [s for s in sequences if s not in found]
    if missing:
        raise DsecFlareError(
            f"{root}: found {len(found)} of the {len(sequences)} DSEC-Flare sequences "
            f"(found: {', '.join(found) or 'none'}; missing: {', '.join(missing)}). "
            f"Looked for <seq>/events/left/events.h5, train|test/<seq>/events/left/events.h5 "
            "and <seq>/events_left/events.h5. Unpack the missing sequences' left events "
            "there, or choose windows of the sequences you have (--dsec-window SEQ:SECONDS)."
        )
    return found


@dataclass(frozen=True)
class DsecWindow:
    """One extracted window: where it comes from (stored as the file's ``script``).

    Attributes
    ----------
    sequence : str
    file : str
        The events file, relative to the DSEC root.
    start_us : int
        Window start on the file's time axis (after ``t_offset``).
    t_offset_us : int
        The file's ``t_offset``: the absolute DSEC time of a window event is
        ``t + t_offset_us + start_us``.
    duration_us : int
    rectified : bool
    category : str
    """

    sequence: str
    file: str
    start_us: int
    t_offset_us: int
    duration_us: int
    rectified: bool
    category: str

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            "kind": "dsec",
            "sequence": self.sequence,
            "category": self.category,
            "file": self.file,
            "start_us": self.start_us,
            "t_offset_us": self.t_offset_us,
            "duration_us": self.duration_us,
            "rectified": self.rectified,
        }

    def to_json(self) -> str:
        """The provenance as JSON text."""
        return json.dumps(self.to_dict(), indent=1, sort_keys=True)


def _rectify(events: np.ndarray, path: Path, size: SensorSize) -> np.ndarray:
    width, height = size
    map_path = path.with_name("rectify_map.h5")
    if not map_path.is_file():
        raise EventFileError(map_path, "no such file; rectification needs DSEC's rectify_map.h5")
    try:
        with h5py.File(map_path, "r") as f:
            rmap = f["rectify_map"][()]
    except (OSError, KeyError) as exc:
        raise EventFileError(map_path, f"not a DSEC rectify map ({exc})") from None
    if rmap.shape != (height, width, 2):
        raise EventFileError(
            map_path, f"rectify_map has shape {rmap.shape}, expected ({height}, {width}, 2)"
        )
    xy = np.rint(rmap[events["y"], events["x"]]).astype(np.int64)
    keep = (xy[:, 0] >= 0) & (xy[:, 0] < width) & (xy[:, 1] >= 0) & (xy[:, 1] < height)
    out = events[keep]
    out["x"] = xy[keep, 0]
    out["y"] = xy[keep, 1]
    return out


def read_window(
    path: str | os.PathLike[str],
    spec: WindowSpec,
    k: int,
    *,
    duration_us: int = 100_000,
    sensor_size: SensorSize = (640, 480),
    rectify: bool = False,
) -> tuple[np.ndarray, int, int]:
    """Window ``k`` of ``spec`` from a DSEC ``events.h5``.

    Returns
    -------
    (events, start_us, t_offset_us)
        Events with times relative to the window start (in ``[0, duration_us)``),
        the window start on the file's time axis and the file's ``t_offset``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "events.h5"
    >>> t = np.arange(0, 1_000_000, 1000)
    >>> write_dsec(p, make_events(t, t % 8, t % 6, t % 2), (8, 6), t_offset_us=0)
    >>> ev, start, _ = read_window(p, WindowSpec("s", 0.5, 1), 0, sensor_size=(8, 6))
    >>> start, ev.size, int(ev["t"][0]), int(ev["t"][-1])
    (450000, 100, 0, 99000)
    """
    path = Path(path)
    size = check_sensor_size(sensor_size)
    with DsecReader(path) as reader:
        span = reader.time_range()
        offset = reader.t_offset
        if span is None:
            raise EventFileError(path, "holds no events")
        first, last = span[0] - offset, span[1] - offset
        center_us = (first + last) / 2 if spec.center_s is None else spec.center_s * 1e6
        start = round((center_us - spec.count * duration_us / 2) / 1000) * 1000 + k * duration_us
        if start + duration_us <= first or start > last:
            raise DsecFlareError(
                f"{path}: window [{start / 1e6:.3f}, {(start + duration_us) / 1e6:.3f}) s of "
                f"{spec.sequence} lies outside its recording [{first / 1e6:.3f}, "
                f"{last / 1e6:.3f}] s; choose another centre (--dsec-window SEQ:SECONDS)"
            )
        events = reader.read_time(offset + start, offset + start + duration_us)
    if events.size and (events["x"].max() >= size[0] or events["y"].max() >= size[1]):
        raise EventFileError(
            path,
            f"events reach x={int(events['x'].max())}, y={int(events['y'].max())}, beyond the "
            f"sensor {size[0]}x{size[1]}; give the right sensor size (--sensor-size WxH)",
        )
    if rectify:
        events = _rectify(events, path, size)
    events["t"] -= offset + start
    return events, start, offset


def dsec_sequence(
    config: DsecFlareConfig,
    index: int,
    *,
    duration_us: int = 100_000,
    sensor_size: SensorSize = (640, 480),
    name: str = "dsec-flare",
) -> tuple[dict[str, np.ndarray], DsecWindow, dict[str, Any], dict[str, float]]:
    """Window ``index`` of a DSEC-Flare config: ``({"input": events}, provenance, background,
    seconds)``. There is no ground truth; the file holds the ``input`` group only.

    ``name`` is the recipe's, for the error when ``config.root`` is unset.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec
    >>> root = pathlib.Path(tempfile.mkdtemp())
    >>> f = root / "zurich_city_09_c" / "events" / "left" / "events.h5"
    >>> t = np.arange(0, 2_000_000, 500)
    >>> write_dsec(f, make_events(t, t % 64, t % 48, t % 2), (64, 48))
    >>> cfg = DsecFlareConfig(root=str(root), windows=(WindowSpec("zurich_city_09_c", 1.0, 2),))
    >>> streams, window, _, _ = dsec_sequence(cfg, 1, sensor_size=(64, 48))
    >>> list(streams), window.start_us, streams["input"].size
    (['input'], 1000000, 200)
    """
    t0 = time.perf_counter()
    cfg = config
    if cfg.root is None:
        raise DsecFlareError(
            f"recipe {name!r} needs the local DSEC folder: --dsec-root PATH "
            "(or recipe.replace(dsec=DsecFlareConfig(root=...)))"
        )
    spec, k = expand_windows(cfg.windows)[index]
    path = find_dsec_sequences(cfg.root, [spec.sequence])[spec.sequence]
    events, start, offset = read_window(
        path,
        spec,
        k,
        duration_us=duration_us,
        sensor_size=sensor_size,
        rectify=cfg.rectify,
    )
    window = DsecWindow(
        sequence=spec.sequence,
        file=path.relative_to(cfg.root).as_posix(),
        start_us=int(start),
        t_offset_us=int(offset),
        duration_us=int(duration_us),
        rectified=cfg.rectify,
        category=DSEC_FLARE_SEQUENCES.get(spec.sequence, "other"),
    )
    background = {"kind": "recorded", "file": window.file, "start_us": window.start_us}
    return {"input": events}, window, background, {"background": time.perf_counter() - t0}


def _check(recipe: Recipe) -> None:
    """Find the recipe's DSEC files before a run (errors surface early)."""
    if recipe.config.root is None:
        raise DsecFlareError(
            f"recipe {recipe.name!r} needs the local DSEC folder: --dsec-root PATH "
            "(or recipe.replace(dsec=DsecFlareConfig(root=...)))"
        )
    find_dsec_sequences(recipe.config.root, recipe.config.sequences)


def _identity(config: dict[str, Any]) -> dict[str, Any]:
    """The same DSEC data anywhere gives the same dataset: the root is not recorded."""
    return {**config, "root": None}


@register_kind(
    "dsec",
    config_field="dsec",
    config_type=DsecFlareConfig,
    test_only=True,
    count=lambda config: len(expand_windows(config.windows)),
    check=_check,
    identity=_identity,
    cli_options=("--dsec-root", "--dsec-window", "--rectify"),
)
def _make_sequence(recipe: Recipe, index: int, source: Any = None) -> KindSequence:
    """The ``"dsec"`` kind: :func:`dsec_sequence` of the recipe's ``dsec`` config."""
    streams, window, background, seconds = dsec_sequence(
        recipe.config,
        index,
        duration_us=recipe.duration_us,
        sensor_size=recipe.sensor_size,
        name=recipe.name,
    )
    return KindSequence(streams, window, background, seconds)
