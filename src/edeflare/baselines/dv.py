"""dv-processing's noise filters (iniVation) as de-flaring baselines.

Users of event cameras already run these background-activity filters; on
real lens flare, which is mostly *sparse* scattered events around a light,
they are strong baselines. Three filters of ``dv_processing.noise`` are
offered, with dv-processing's own defaults:

=================  ==========================================================================
``fastdecay``      ``FastDecayNoiseFilter``: a decaying event count on a grid of
                   ``subdivision_factor`` x ``subdivision_factor`` pixel cells; an event is
                   kept when its cell's count (half-life ``half_life_us``) exceeds
                   ``noise_threshold``. Defaults 10 ms, 4, 6.
``bafilter``       ``BackgroundActivityNoiseFilter``: keep an event when one of its 8
                   neighbours had an event in the last ``duration_us`` (default 2 ms).
``knoise``         ``KNoiseFilter``: the O(N) memory k-noise filter of Khodamoradi &
                   Kastner, support window ``time_delta_us`` (default 1 ms).
=================  ==========================================================================

The filters are C++ state machines: :class:`DvFilter` keeps one alive across
chunks, so feeding a stream chunk by chunk gives the same output as one pass.
Chunks are handed over as arrays, without a per-event Python loop: dv-processing
2.0's Python binding builds event stores only event by event, so a chunk is
written to a temporary ``.aedat4`` file by faery (Rust) and read back by
dv-processing's own reader (C++); the round trip is exact and costs about
0.05 s per million events.

dv-processing is optional: ``pip install 'edeflare[dv]'``. It is imported
when a filter is first used, with a :class:`~edeflare.errors.DependencyError`
naming the extra when it is missing.

References
----------
iniVation dv-processing 2.0, ``dv::noise`` (https://dv-processing.inivation.com).
A. Khodamoradi and R. Kastner, "O(N)-Space Spatiotemporal Filter for Reducing
Noise in Neuromorphic Vision Sensors", IEEE TETC 2018.
"""

from __future__ import annotations

import datetime
import math
import os
import tempfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import DependencyError, ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size

__all__ = ["DV_FILTERS", "DvFilter", "dv_filter", "dv_filter_parameters", "import_dv"]

_DV_DTYPE = np.dtype([("timestamp", "<i8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")])

# filter name -> (dv_processing.noise class, {our parameter: (dv argument, default, kind)})
DV_FILTERS: dict[str, tuple[str, dict[str, tuple[str, Any, str]]]] = {
    "fastdecay": (
        "FastDecayNoiseFilter",
        {
            "half_life_us": ("halfLife", 10_000, "us"),
            "subdivision_factor": ("subdivisionFactor", 4, "int"),
            "noise_threshold": ("noiseThreshold", 6.0, "float"),
        },
    ),
    "bafilter": (
        "BackgroundActivityNoiseFilter",
        {"duration_us": ("backgroundActivityDuration", 2_000, "us")},
    ),
    "knoise": ("KNoiseFilter", {"time_delta_us": ("timeDelta", 1_000, "us")}),
}


def import_dv() -> Any:
    """Import ``dv_processing``, or raise a :class:`DependencyError` naming the extra.

    Examples
    --------
    >>> dv = import_dv()  # doctest: +SKIP
    """
    try:
        import dv_processing
    except ImportError:
        raise DependencyError(
            "the dv filters need dv-processing: pip install 'edeflare[dv]' "
            "(or pip install 'dv-processing>=2')"
        ) from None
    return dv_processing


def dv_filter_parameters(name: str) -> dict[str, Any]:
    """The parameters of a dv filter and their defaults.

    Examples
    --------
    >>> dv_filter_parameters("bafilter")
    {'duration_us': 2000}
    """
    if name not in DV_FILTERS:
        raise ParameterError(f"unknown dv filter {name!r}; valid: {', '.join(DV_FILTERS)}")
    return {k: spec[1] for k, spec in DV_FILTERS[name][1].items()}


def _check_params(name: str, params: Mapping[str, Any]) -> dict[str, Any]:
    specs = DV_FILTERS[name][1]
    unknown = [k for k in params if k not in specs]
    if unknown:
        raise ParameterError(
            f"dv filter {name!r} has no parameter {', '.join(map(repr, unknown))}; "
            f"valid: {', '.join(specs)}"
        )
    out = dv_filter_parameters(name)
    for key, value in params.items():
        kind = specs[key][2]
        if kind in ("us", "int"):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ParameterError(f"{key} must be a positive int, got {value!r}")
            out[key] = int(value)
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ParameterError(f"{key} must be a number, got {value!r}")
            if not (math.isfinite(float(value)) and float(value) > 0):
                raise ParameterError(f"{key} must be a positive finite number, got {value!r}")
            out[key] = float(value)
    return out


class DvFilter:
    """One dv-processing noise filter over one stream, fed chunk by chunk.

    Parameters
    ----------
    sensor_size : (width, height)
    name : str
        ``"fastdecay"``, ``"bafilter"`` or ``"knoise"`` (see the module docstring).
    **params
        The filter's parameters (:func:`dv_filter_parameters`); others are rejected.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> f = DvFilter((8, 8), "bafilter")  # doctest: +SKIP
    >>> ev = make_events([10_000, 10_100, 10_200], [3, 4, 7], [3, 3, 0], [1, 1, 1])
    >>> f.filter(ev)["x"].tolist()  # the second has a neighbour 100 us before  # doctest: +SKIP
    [4]
    """

    def __init__(self, sensor_size: SensorSize, name: str = "fastdecay", **params: Any) -> None:
        if name not in DV_FILTERS:
            raise ParameterError(f"unknown dv filter {name!r}; valid: {', '.join(DV_FILTERS)}")
        self.sensor_size = check_sensor_size(sensor_size)
        self.name = name
        self.params = _check_params(name, params)
        self._dv = import_dv()
        cls_name, specs = DV_FILTERS[name]
        kwargs: dict[str, Any] = {}
        for key, value in self.params.items():
            arg, _, kind = specs[key]
            kwargs[arg] = datetime.timedelta(microseconds=value) if kind == "us" else value
        self._filter = getattr(self._dv.noise, cls_name)(self.sensor_size, **kwargs)
        # dv-processing's pixel maps start at time 0, as the original's do: times are
        # handed over as they are (shifted only if the stream starts before 0).
        self._t0: int | None = None

    def filter(self, events: np.ndarray) -> np.ndarray:
        """Filter the next sorted chunk (later than the previous ones); returns the kept events."""
        if events.size == 0:
            return np.zeros(0, dtype=EVENT_DTYPE)
        if self._t0 is None:
            self._t0 = min(0, int(events["t"][0]))
        kept = self._run(events)
        out = np.empty(kept.size, dtype=EVENT_DTYPE)
        out["t"] = kept["timestamp"] + self._t0
        out["x"] = kept["x"]
        out["y"] = kept["y"]
        out["p"] = kept["polarity"]
        return out

    def _run(self, events: np.ndarray) -> np.ndarray:
        import faery

        chunk = np.empty(events.size, dtype=faery.EVENTS_DTYPE)
        chunk["t"] = events["t"] - self._t0
        chunk["x"] = events["x"]
        chunk["y"] = events["y"]
        chunk["on"] = events["p"].astype(bool)
        parts = []
        with tempfile.TemporaryDirectory(prefix="edeflare-dv-") as folder:
            path = os.path.join(folder, "chunk.aedat4")
            faery.file_encoder.events_to_file(
                iter([chunk]),
                path,
                dimensions=self.sensor_size,
                zero_t0=False,
                use_write_suffix=False,
                file_type="aedat",
            )
            reader = self._dv.io.MonoCameraRecording(path)
            while True:
                batch = reader.getNextEventBatch()
                if batch is None:
                    break
                self._filter.accept(batch)
                parts.append(self._filter.generateEvents().numpy())
            del reader  # closes the file before the folder goes
        if not parts:
            return np.zeros(0, dtype=_DV_DTYPE)
        return np.concatenate(parts)


def dv_filter(
    events: np.ndarray, sensor_size: SensorSize, name: str = "fastdecay", **params: Any
) -> np.ndarray:
    """Run a dv-processing noise filter over a whole stream (one pass).

    Parameters
    ----------
    events : numpy.ndarray
        Sorted events.
    sensor_size : (width, height)
    name : str
        ``"fastdecay"``, ``"bafilter"`` or ``"knoise"``.
    **params
        The filter's parameters (:func:`dv_filter_parameters`).

    Returns
    -------
    numpy.ndarray
        The kept events, a new sorted array (a subset of ``events``).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([10_000, 10_100, 10_200], [3, 4, 7], [3, 3, 0], [1, 1, 1])
    >>> dv_filter(ev, (8, 8), "bafilter")["x"].tolist()  # doctest: +SKIP
    [4]
    """
    check_events(events, sensor_size)
    return DvFilter(sensor_size, name, **params).filter(events)
