"""Reconstruct images from events with the recurrent network, window by window.

:class:`Reconstructor` keeps the network's state between windows, so a
recording is reconstructed as it streams; :func:`reconstruct_events` does a
whole stream in memory and :func:`reconstruct_file` writes a video.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
import torch

from ..errors import ParameterError
from ..events import SensorSize, check_sensor_size, iter_time_windows, window_start_for
from ..voxel import encode
from .weights import load_reconstructor

__all__ = ["Reconstructor", "reconstruct_events", "reconstruct_file"]


class Reconstructor:
    """Events to images in ``[0, 1]`` (log intensity), one window at a time.

    Parameters
    ----------
    weights : path-like, optional
        A reconstructor weights file; default the bundled ``firenet``.
    device : str or torch.device
        Where the network runs.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> rec = Reconstructor()
    >>> image = rec.step(make_events([10, 20], [1, 2], [1, 1], [1, 0]), (8, 6), 0)
    >>> image.shape, image.dtype.name, bool(((image >= 0) & (image <= 1)).all())
    ((6, 8), 'float32', True)
    """

    def __init__(
        self, weights: str | os.PathLike[str] | None = None, *, device: str | torch.device = "cpu"
    ) -> None:
        self.model, self.card = load_reconstructor(weights, device)
        self.device = torch.device(device)
        self.window_us = self.card.window_us
        self._state: tuple[torch.Tensor, torch.Tensor] | None = None
        self._shape: tuple[int, int] | None = None

    def reset(self) -> None:
        """Forget the state: the next window starts a new stream."""
        self._state = None
        self._shape = None

    @torch.inference_mode()
    def step(self, events: np.ndarray, sensor_size: SensorSize, window_start_us: int) -> np.ndarray:
        """The image at the end of the window ``[start, start + window_us)`` of ``events``."""
        width, height = check_sensor_size(sensor_size)
        if self._shape is not None and self._shape != (height, width):
            raise ParameterError(
                f"sensor size {sensor_size} differs from this stream's {self._shape[::-1]}; "
                "call reset() between streams"
            )
        self._shape = (height, width)
        grid = encode(events, (width, height), window_start_us, self.window_us, self.card.bins)
        voxels = torch.from_numpy(grid)[None].to(self.device)
        image, self._state = self.model(voxels, self._state)
        return image[0, 0].float().cpu().numpy()

    def frames(
        self, windows: Iterable[tuple[int, np.ndarray]], sensor_size: SensorSize
    ) -> Iterator[tuple[int, np.ndarray]]:
        """``(window end µs, image)`` for each ``(window start, events)`` of a stream."""
        for start, events in windows:
            yield int(start) + self.window_us, self.step(events, sensor_size, start)


def reconstruct_events(
    events: np.ndarray,
    sensor_size: SensorSize,
    *,
    start_us: int | None = None,
    end_us: int | None = None,
    weights: str | os.PathLike[str] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Images at the end of every window of a stream: ``(times_us (T,), images (T, H, W))``.

    Windows are the reconstructor's (20 ms for the bundled one), aligned to
    ``start_us`` (default: the window holding the first event).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> times, images = reconstruct_events(make_events([0, 30_000], [0, 1], [0, 0], [1, 1]), (4, 3))
    >>> times.tolist(), images.shape
    ([20000, 40000], (2, 3, 4))
    """
    rec = Reconstructor(weights)
    if start_us is None and events.size:
        start_us = window_start_for(int(events["t"][0]), rec.window_us)
    out = list(
        rec.frames(
            iter_time_windows(events, rec.window_us, start_us=start_us, end_us=end_us), sensor_size
        )
    )
    width, height = check_sensor_size(sensor_size)
    if not out:
        return np.zeros(0, np.int64), np.zeros((0, height, width), np.float32)
    return np.array([t for t, _ in out], np.int64), np.stack([im for _, im in out])


def reconstruct_file(
    in_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    sensor_size: SensorSize | None = None,
    group: str | None = None,
    weights: str | os.PathLike[str] | None = None,
    fps: float | None = None,
    progress: bool | None = None,
) -> int:
    """Reconstruct a recording into a gray ``.mp4`` or ``.gif``, streamed; returns the frame count.

    One image per window of the reconstructor (20 ms: 50 frames per second
    of recording); ``fps`` defaults to real time. ``group``: the event group
    of an HDF5 file holding several (e.g. ``"input"`` of a sequence file).
    """
    from .._progress import progress_bar
    from ..io import open_events
    from ..viz import save_animation

    out_path = Path(out_path)
    if out_path.suffix.lower() not in (".mp4", ".gif"):
        raise ParameterError(f"{out_path}: the video must be .mp4 or .gif")
    src = open_events(in_path, sensor_size, group=group)
    rec = Reconstructor(weights)
    count = 0

    def gray() -> Iterator[np.ndarray]:
        nonlocal count
        with progress_bar(
            total=src.n_events,
            enabled=progress,
            unit="ev",
            unit_scale=True,
            leave=False,
            desc="reconstruct",
        ) as bar:

            def windows() -> Iterator[tuple[int, np.ndarray]]:
                for start, events in src.windows(rec.window_us):
                    bar.update(events.size)
                    yield start, events

            for _, image in rec.frames(windows(), src.sensor_size):
                count += 1
                g = np.clip(np.round(image * 255.0), 0, 255).astype(np.uint8)
                yield np.repeat(g[:, :, None], 3, axis=2)

    save_animation(out_path, gray(), fps=fps or 1e6 / rec.window_us)
    return count
