"""Paired voxel windows for training and validation.

A *sequence file* (:mod:`edeflare.io.sequence`, the owner of the layout)
holds (at least) the groups ``input`` (flare-corrupted events) and ``gt``
(ground truth), each in the DSEC layout, the root attribute ``sensor_size``
and ``t_start_us`` / ``t_end_us`` (the sequence span; otherwise the span of
its events). A dataset folder holds ``train/`` and ``test/`` folders of them.

:class:`PairedWindows` cuts every sequence into aligned windows (default
20 ms) and returns ``(input, target)`` voxel grids ``(1, bins, H, W)``,
optionally randomly cropped and flipped. Files without a ``gt`` group (the
``dsec-flare`` recipe's real windows) are refused by
:func:`~edeflare.io.sequence.check_paired`
with a message saying what they are for. Augmentations are drawn from a
generator seeded by ``(seed, epoch, index)``, so a sample is the same on any
worker, rank or resume.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import EventFileError
from ..events import SensorSize, window_start_for
from ..io.dsec import DsecReader
from ..io.sequence import sequence_span
from ..voxel import encode

__all__ = ["PairedWindows", "WindowRef", "sequence_windows"]


@dataclass(frozen=True)
class WindowRef:
    """One window of one sequence file (of ``sensor_size``; ``None``: not recorded here)."""

    path: Path
    start_us: int
    sensor_size: SensorSize | None = None


def sequence_windows(
    paths: Sequence[str | os.PathLike[str]],
    window_us: int = 20_000,
    groups: Sequence[str] = ("input", "gt"),
    *,
    mixed_sizes: bool = False,
) -> tuple[list[WindowRef], SensorSize]:
    """Aligned windows of every sequence and the common sensor size.

    Windows start at the multiple of ``window_us`` at or below the sequence
    start and cover it to its end. Sequences of another sensor size are an
    error, unless ``mixed_sizes``: then each window carries its own size and
    the size returned is the smallest width and height among them (the
    largest crop every window allows).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec_groups
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> ev = make_events([100, 25_000], [1, 2], [1, 2], [1, 0])
    >>> write_dsec_groups(d / "a.h5", {"input": ev, "gt": ev}, (8, 6))
    >>> write_dsec_groups(d / "b.h5", {"input": ev, "gt": ev}, (6, 9))
    >>> refs, size = sequence_windows([d / "a.h5", d / "b.h5"], mixed_sizes=True)
    >>> [(r.start_us, r.sensor_size) for r in refs], size
    ([(0, (8, 6)), (20000, (8, 6)), (0, (6, 9)), (20000, (6, 9))], (6, 6))
    """
    refs: list[WindowRef] = []
    common: SensorSize | None = None
    for p in paths:
        path = Path(p)
        found = sequence_span(path, groups)
        if found is None:
            continue
        size, start, end = found
        if common is None:
            common = size
        elif size != common:
            if not mixed_sizes:
                raise EventFileError(path, f"sensor size {size} differs from {common}")
            common = (min(common[0], size[0]), min(common[1], size[1]))
        first = window_start_for(start, window_us)
        refs.extend(WindowRef(path, s, size) for s in range(first, end, window_us))
    if common is None:
        raise EventFileError(Path(paths[0]) if paths else Path("."), "no events in any sequence")
    return refs, common


class PairedWindows:
    """A map-style dataset of ``(input, target)`` voxel grids, each ``(1, bins, H, W)`` float32.

    Parameters
    ----------
    paths : sequence of path-like
        Sequence files.
    window_us, bins : int
        Window length and time bins (paper: 20 ms, 8).
    crop : (height, width), optional
        Random crop of this size (training on CPU); None keeps the full sensor.
        Sequences may be of several sensor sizes (each window is encoded at
        its own; :attr:`sensor_size` is then the smallest width and height);
        batches of them need a crop no larger than that.
    flip : bool
        Random horizontal and vertical flips.
    time_shift : bool
        Random shift of the window's start by a whole number of bins, ``0`` to
        ``bins - 1`` (the shifted window is this window's last bins followed by
        the next window's first ones; a sequence's last window is not
        shifted). Windows of a recording start at an arbitrary phase of what
        it shows (a lamp's 100 Hz flicker, a source's motion), so a model
        should not learn where in the window things happen: without the shift
        every training window starts where its sequence does.
    polarity_flip : bool
        Random swap of ON and OFF (both grids negated) in half the windows.
        Which polarity leads a moving light's edge, and which one its pixels
        keep firing as they settle, differs between sensors and scenes: a
        brightening edge fires ON, yet the Prophesee Gen3 blob of the real
        recordings leads with OFF events and settles in ON ones.
    seed : int
        Seeds the augmentations together with the epoch and the index.
    precompute : bool
        Encode every window once, up front, and keep the grids in memory as
        int16 counts (``2 * bins * H * W * 2`` bytes per window: 2.9 MB at
        346x260, 9.8 MB at 640x480), so epochs after the first read no files.
        Counts that do not fit int16 are an error.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io.dsec import write_dsec_groups
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "seq.h5"
    >>> ev = make_events([100, 25_000], [1, 2], [1, 2], [1, 0])
    >>> write_dsec_groups(p, {"input": ev, "gt": ev[:1]}, (4, 4))
    >>> ds = PairedWindows([p])
    >>> len(ds), ds[0][0].shape, float(ds[1][0].sum()), float(ds[1][1].sum())
    (2, (1, 8, 4, 4), -1.0, 0.0)
    """

    def __init__(
        self,
        paths: Sequence[str | os.PathLike[str]],
        *,
        window_us: int = 20_000,
        bins: int = 8,
        crop: tuple[int, int] | None = None,
        flip: bool = False,
        time_shift: bool = False,
        polarity_flip: bool = False,
        seed: int = 0,
        precompute: bool = False,
        input_group: str = "input",
        target_group: str = "gt",
    ) -> None:
        self.window_us, self.bins = int(window_us), int(bins)
        self.groups = (input_group, target_group)
        self.windows, self.sensor_size = sequence_windows(
            paths, window_us, self.groups, mixed_sizes=True
        )
        width, height = self.sensor_size
        self.sizes = sorted({ref.sensor_size for ref in self.windows})  # type: ignore[type-var]
        what = "the sensor" if len(self.sizes) == 1 else "the smallest of the sensors'"
        if crop is not None and (crop[0] > height or crop[1] > width):
            raise ValueError(f"crop {crop} (height, width) exceeds {what} {width}x{height}")
        self.crop = crop
        self.flip = flip
        self.time_shift = time_shift
        self.polarity_flip = polarity_flip
        # the window that continues each one in its sequence, or -1 (time_shift)
        self._next = np.full(len(self.windows), -1, dtype=np.int64)
        for i, (a, b) in enumerate(itertools.pairwise(self.windows)):
            if a.path == b.path and b.start_us == a.start_us + self.window_us:
                self._next[i] = i + 1
        self.seed = int(seed)
        self.epoch = 0
        self._readers: dict[tuple[Path, str], DsecReader] = {}
        self._cache: list[np.ndarray] | None = None
        if precompute:
            cache = []
            for i in range(len(self.windows)):
                pair = np.stack(self._encode(i))
                if pair.size and np.abs(pair).max() > np.iinfo(np.int16).max:
                    raise ValueError(f"window {i}: a cell exceeds int16; use precompute=False")
                cache.append(pair.astype(np.int16))
            self._cache = cache

    def __len__(self) -> int:
        return len(self.windows)

    def set_epoch(self, epoch: int) -> None:
        """Change the augmentation draws (call once per epoch)."""
        self.epoch = int(epoch)

    def _reader(self, path: Path, group: str) -> DsecReader:
        key = (path, group)
        if key not in self._readers:  # opened lazily, once per worker process
            self._readers[key] = DsecReader(path, group=f"{group}/events")
        return self._readers[key]

    def grids(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Uncropped ``(input, target)`` grids ``(bins, H, W)`` of window ``index``."""
        if self._cache is not None:
            pair = self._cache[index].astype(np.float32)
            return pair[0], pair[1]
        return self._encode(index)

    def target_events(self, index: int) -> np.ndarray:
        """The ground-truth events of window ``index`` (through the dataset's open readers)."""
        return self._events(index, self.groups[1])

    def input_events(self, index: int) -> np.ndarray:
        """The input events of window ``index`` (through the dataset's open readers)."""
        return self._events(index, self.groups[0])

    def _events(self, index: int, group: str) -> np.ndarray:
        ref = self.windows[index]
        reader = self._reader(ref.path, group)
        return reader.read_time(ref.start_us, ref.start_us + self.window_us)

    def _encode(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        ref = self.windows[index]
        out = []
        for group in self.groups:
            events = self._reader(ref.path, group).read_time(
                ref.start_us, ref.start_us + self.window_us
            )
            size = ref.sensor_size or self.sensor_size
            out.append(encode(events, size, ref.start_us, self.window_us, self.bins))
        return out[0], out[1]

    def __getitem__(self, key: int | tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Window ``key`` at the current epoch, or ``(index, epoch)`` (for samplers)."""
        if isinstance(key, tuple):
            return self.item(*key)
        return self.item(key, self.epoch)

    def item(self, index: int, epoch: int) -> tuple[np.ndarray, np.ndarray]:
        """Window ``index`` with the augmentation draws of ``epoch`` (stateless)."""
        x, y = self.grids(index)
        rng = np.random.default_rng((self.seed, int(epoch), int(index)))
        top = left = 0
        if self.crop is not None:
            top = int(rng.integers(0, x.shape[1] - self.crop[0] + 1))
            left = int(rng.integers(0, x.shape[2] - self.crop[1] + 1))
        flips = (rng.random() < 0.5, rng.random() < 0.5) if self.flip else (False, False)
        # drawn last, so the draws above are those of a dataset without the shift
        shift = int(rng.integers(0, self.bins)) if self.time_shift else 0
        negate = bool(rng.random() < 0.5) if self.polarity_flip else False  # drawn last too
        if shift and self._next[index] >= 0:
            nx, ny = self.grids(int(self._next[index]))
            x = np.concatenate([x[shift:], nx[:shift]])
            y = np.concatenate([y[shift:], ny[:shift]])
        if self.crop is not None:
            ch, cw = self.crop
            x = x[:, top : top + ch, left : left + cw]
            y = y[:, top : top + ch, left : left + cw]
        if flips[0]:
            x, y = x[:, :, ::-1], y[:, :, ::-1]
        if flips[1]:
            x, y = x[:, ::-1, :], y[:, ::-1, :]
        if negate:
            x, y = -x, -y
        return np.ascontiguousarray(x)[None], np.ascontiguousarray(y)[None]

    def __getstate__(self) -> dict[str, object]:  # open HDF5 handles do not pickle
        state = self.__dict__.copy()
        state["_readers"] = {}
        return state
