"""edeflare: remove lens flare from event-camera data (E-Deflare).

The public surface re-exported here is what most users need; every module
documents its own in ``__all__``.

Examples
--------
>>> import edeflare
>>> ev = edeflare.make_events([0, 10], [1, 2], [3, 4], [1, 0])
>>> edeflare.encode(ev, (8, 8), 0, 20_000).shape
(8, 8, 8)
"""

from __future__ import annotations

import os as _os

import numba as _numba

# numba's default threading layer here is GNU OpenMP, which kills any child process
# forked after a parallel kernel ran (data-loader workers, dataset-generation pools).
# The workqueue layer is fork-safe; users can still choose with NUMBA_THREADING_LAYER.
if "NUMBA_THREADING_LAYER" not in _os.environ:
    _numba.config.THREADING_LAYER = "workqueue"

from ._version import __version__
from .deflare import create_method, deflare, deflare_file, list_methods
from .errors import (
    EdeflareError,
    EventFileError,
    EventsError,
    ParameterError,
    UnknownFormatError,
)
from .events import (
    EVENT_DTYPE,
    center_crop,
    check_events,
    crop,
    iter_time_windows,
    make_events,
    merge_events,
    slice_time,
    sort_events,
)
from .io import iter_windows, open_events, read_events, write_event_chunks, write_events
from .voxel import decode, encode, encode_polarity

__all__ = [
    "EVENT_DTYPE",
    "EdeflareError",
    "EventFileError",
    "EventsError",
    "ParameterError",
    "UnknownFormatError",
    "__version__",
    "center_crop",
    "check_events",
    "create_method",
    "crop",
    "decode",
    "deflare",
    "deflare_file",
    "encode",
    "encode_polarity",
    "iter_time_windows",
    "iter_windows",
    "list_methods",
    "make_events",
    "merge_events",
    "open_events",
    "read_events",
    "slice_time",
    "sort_events",
    "write_event_chunks",
    "write_events",
]
