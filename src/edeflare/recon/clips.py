"""Training clips for the reconstructor: simulated events and the frames that made them.

The synthetic street of :mod:`edeflare.sim.background` renders the intensity
video whose log changes the event simulator turns into events, so every
window's events come with the exact image at the window's end: pairs in
exact correspondence, with no camera or alignment between them. Night
streets (the simulator's default) and a brighter "day" variant of the same
street are drawn half and half.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..events import SensorSize, check_sensor_size, iter_time_windows
from ..sim.background import SceneConfig, SyntheticBackground
from ..voxel import encode

__all__ = ["BURN_IN", "DAY", "NIGHT", "Clip", "centre_image", "draw_clip", "intensity_to_image"]

BURN_IN = 2
"""Windows at the start of a stream that training and scoring leave out: the
network has seen too few events to know the scene."""

NIGHT = SceneConfig(fps=1000.0)
"""The simulator's night street (at 1 kHz: enough for 20 ms windows)."""
DAY = SceneConfig(
    fps=1000.0,
    sky_level=(60.0, 200.0),
    building_level=(30.0, 150.0),
    window_level=(40.0, 220.0),
    road_level=(40.0, 120.0),
    marking_level=(100.0, 255.0),
    lamps=(0, 2),
    noise_rate_hz=(0.01, 0.1),
)
"""The same street by day: bright sky, lit facades and road, fewer lamps."""

_LOG_WHITE = math.log1p(255.0)


def intensity_to_image(intensity: np.ndarray) -> np.ndarray:
    """Map linear intensity (0-255 scale) to the reconstructor's image: ``log1p(I) / log1p(255)``.

    Events see log intensity, so this is the image they can tell apart: a
    lamp at 255 and a sky at 3 both stay visible.

    Examples
    --------
    >>> intensity_to_image(np.array([0.0, 255.0, 1000.0])).tolist()
    [0.0, 1.0, 1.0]
    """
    image = np.log1p(np.maximum(np.asarray(intensity, dtype=np.float64), 0.0)) / _LOG_WHITE
    return np.clip(image, 0.0, 1.0).astype(np.float32)


def centre_image(image: np.ndarray) -> np.ndarray:
    """Shift an image (or each of ``(..., H, W)`` images) to mean 0.5, clipped to ``[0, 1]``.

    Events encode changes of log intensity, never its absolute level: a
    street by day and by night, one a constant factor brighter, give the
    same events. The reconstructor is therefore trained on, and scored
    against, images with their mean log intensity removed.

    Examples
    --------
    >>> centre_image(np.array([[0.7, 0.9]])).tolist()
    [[0.4, 0.6]]
    """
    image = np.asarray(image, dtype=np.float32)
    shifted = image - image.mean(axis=(-2, -1), keepdims=True) + np.float32(0.5)
    return np.clip(shifted, np.float32(0.0), np.float32(1.0))


@dataclass(frozen=True)
class Clip:
    """One simulated clip: per window, the voxel grid and the image at the window's end."""

    voxels: np.ndarray
    """float32 ``(T, bins, H, W)``."""
    images: np.ndarray
    """float32 ``(T, 1, H, W)`` in [0, 1]: :func:`intensity_to_image`, then
    :func:`centre_image`."""


def draw_clip(
    sensor_size: SensorSize,
    windows: int,
    *,
    window_us: int = 20_000,
    bins: int = 5,
    day: bool = False,
    rng: np.random.Generator | int | None = None,
) -> Clip:
    """Simulate one street clip of ``windows`` windows and its ground-truth images.

    Examples
    --------
    >>> clip = draw_clip((32, 24), 3, rng=0)
    >>> clip.voxels.shape, clip.images.shape
    ((3, 5, 24, 32), (3, 1, 24, 32))
    """
    size = check_sensor_size(sensor_size)
    duration = int(windows) * int(window_us)
    background = SyntheticBackground(DAY if day else NIGHT).draw(duration, size, rng=rng)
    assert background.video is not None
    voxels, images = [], []
    for start, events in iter_time_windows(
        background.events, window_us, start_us=0, end_us=duration
    ):
        voxels.append(encode(events, size, start, window_us, bins=bins))
        end = min(start + window_us, duration - 1)
        images.append(centre_image(intensity_to_image(background.video(end)))[None])
    return Clip(np.stack(voxels), np.stack(images))
