"""The references without a filter: ``raw`` (the input) and ``voxel`` (the codec alone)."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np

from .._registry import cli_option
from ..errors import ParameterError
from ..events import check_sensor_size
from ..voxel import decode, encode
from .base import Method, Streamer, param_values, register_method
from .windows import WindowStreamer

__all__ = ["RawMethod", "VoxelMethod", "VoxelParams"]


class _CopyStreamer(Streamer):
    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return events.copy()


class RawMethod(Method):
    """The input unchanged (a copy): the reference with no de-flaring."""

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        return _CopyStreamer()


@dataclasses.dataclass(frozen=True)
class VoxelParams:
    """The ``voxel`` method's parameters (paper: 20 ms, 8 bins)."""

    cli_title: ClassVar[str] = "voxel (paper: 20 ms, 8 bins)"

    window_us: int = dataclasses.field(
        default=20_000,
        metadata=cli_option(
            "--voxel-window-ms", "voxel window", metavar="MS", unit="ms", type=float
        ),
    )
    bins: int = dataclasses.field(
        default=8, metadata=cli_option("--voxel-bins", "temporal bins", metavar="N")
    )


class VoxelMethod(Method):
    """Voxel Transform: the E-DeflareNet codec with the network bypassed (``f = 0``)."""

    def __init__(self, window_us: int, bins: int) -> None:
        for label, v, lo in (("window_us", window_us, 1), ("bins", bins, 1)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ParameterError(f"{label} must be a positive int, got {v!r}")
        if window_us < bins:
            raise ParameterError(f"window_us ({window_us}) must be at least bins ({bins})")
        super().__init__(window_us=int(window_us), bins=int(bins))
        self.window_us = int(window_us)
        self.bins = int(bins)

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        size = check_sensor_size(sensor_size)
        gen = np.random.default_rng(rng)
        w, bins = self.window_us, self.bins

        def transform(batch: list[tuple[int, np.ndarray]], _span: object) -> list[np.ndarray]:
            return [decode(encode(ev, size, s, w, bins), s, w, rng=gen) for s, ev in batch]

        return WindowStreamer(w, transform)


@register_method("raw")
def _make_raw() -> Method:
    return RawMethod()


@register_method("voxel", params=VoxelParams)
def _make_voxel(**params: Any) -> Method:
    return VoxelMethod(**param_values(VoxelParams(**params)))
