"""Helpers and constants shared by the :mod:`edeflare.realworld` modules."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import EdeflareError, ParameterError
from ..events import SensorSize, check_sensor_size

MANIFEST_FORMAT = "edeflare-pairs/1"
LOW_CONFIDENCE = 0.1
"""Alignments below this confidence are reported with a warning."""


class PairingError(EdeflareError, ValueError):
    """Two recordings cannot be paired as asked (the message names the files and says why)."""


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float)):
        raise ParameterError(f"{name} must be a positive integer, got {value!r}")
    if isinstance(value, float) and not value.is_integer():
        raise ParameterError(f"{name} must be a whole number of µs, got {value!r}")
    if int(value) <= 0:
        raise ParameterError(f"{name} must be positive, got {value!r}")
    return int(value)


def _check_mask(mask: Any, sensor_size: SensorSize | None) -> tuple[np.ndarray, SensorSize]:
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != bool:
        raise ParameterError(f"mask must be a boolean (H, W) array, got {mask.dtype} {mask.shape}")
    size = (mask.shape[1], mask.shape[0])
    if sensor_size is not None and check_sensor_size(sensor_size) != size:
        raise ParameterError(f"mask shape {mask.shape} (H, W) does not match sensor {sensor_size}")
    return mask, size


def _progress(total: int | None, desc: str, enabled: bool, unit: str = "ev") -> Any:
    from .._progress import progress_bar

    return progress_bar(
        total=total,
        enabled=enabled,
        desc=desc,
        unit=unit,
        unit_scale=unit == "ev",
        leave=False,
        dynamic_ncols=True,
    )


def _pixel_mask_of(events: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return mask[events["y"], events["x"]]
