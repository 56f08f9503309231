"""edeflare: remove lens flare from event-camera data (E-Deflare).

The public surface re-exported here is what most users need; every module
documents its own in ``__all__``. Names load lazily (as scikit-image's face
does): ``import edeflare`` imports nothing heavy and changes no setting; the
first use of a name imports its module.

- read and write: :func:`read_events`, :func:`write_events`, :func:`open_events`, ...
- de-flare: :func:`deflare`, :func:`deflare_file`, :func:`deflare_files` (a folder),
  :func:`create_method`, :func:`list_methods`;
- evaluate: :func:`evaluate_events` (the paper's metrics over aligned segments);
- simulate: :func:`simulate_pair` (one input / ground-truth pair of a flare script);
- models: :func:`create_model`, :func:`list_models` (E-DeflareNet presets; needs torch);
- reconstruct: :func:`reconstruct_events` (images from events, the bundled
  recurrent reconstructor) and :func:`reconstruct_file` (a video).

Examples
--------
>>> import edeflare
>>> ev = edeflare.make_events([0, 10], [1, 2], [3, 4], [1, 0])
>>> edeflare.encode(ev, (8, 8), 0, 20_000).shape
(8, 8, 8)
>>> edeflare.evaluate_events(ev, ev, (8, 8)).means["chamfer"]
0.0
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

# name -> module (relative to this package) that defines it
_LAZY: dict[str, str] = {
    "create_method": "methods",
    "deflare": "methods",
    "deflare_file": "methods",
    "deflare_files": "methods",
    "list_methods": "methods",
    "EdeflareError": "errors",
    "EventFileError": "errors",
    "EventsError": "errors",
    "ParameterError": "errors",
    "UnknownFormatError": "errors",
    "EVENT_DTYPE": "events",
    "center_crop": "events",
    "check_events": "events",
    "crop": "events",
    "iter_time_windows": "events",
    "make_events": "events",
    "merge_events": "events",
    "slice_time": "events",
    "sort_events": "events",
    "iter_windows": "io",
    "open_events": "io",
    "read_events": "io",
    "write_event_chunks": "io",
    "write_events": "io",
    "decode": "voxel",
    "encode": "voxel",
    "encode_polarity": "voxel",
    "evaluate_events": "eval.evaluate",
    "simulate_pair": "sim.pair",
    "create_model": "models",
    "list_models": "models",
    "reconstruct_events": "recon.infer",
    "reconstruct_file": "recon.infer",
}

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
    "create_model",
    "crop",
    "decode",
    "deflare",
    "deflare_file",
    "deflare_files",
    "encode",
    "encode_polarity",
    "evaluate_events",
    "iter_time_windows",
    "iter_windows",
    "list_methods",
    "list_models",
    "make_events",
    "merge_events",
    "open_events",
    "read_events",
    "reconstruct_events",
    "reconstruct_file",
    "simulate_pair",
    "slice_time",
    "sort_events",
    "write_event_chunks",
    "write_events",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from .errors import (
        EdeflareError,
        EventFileError,
        EventsError,
        ParameterError,
        UnknownFormatError,
    )
    from .eval.evaluate import evaluate_events
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
    from .methods import create_method, deflare, deflare_file, deflare_files, list_methods
    from .models import create_model, list_models
    from .recon.infer import reconstruct_events, reconstruct_file
    from .sim.pair import simulate_pair
    from .voxel import decode, encode, encode_polarity
