"""De-flaring methods behind one registry, and streaming de-flaring of files.

Every method, learned or classical, is a callable
``method(events, sensor_size, *, rng=None) -> events`` made by name:

>>> import edeflare
>>> edeflare.list_methods()  # doctest: +NORMALIZE_WHITESPACE
['dv-bafilter', 'dv-fastdecay', 'dv-knoise', 'efr', 'model', 'pfd-a', 'pfd-b', 'raw',
 'voxel']
>>> pfd_b = edeflare.create_method("pfd-b", window_us=25_000)

============  =========================================================================
``model``     a trained E-DeflareNet (:mod:`edeflare.models`), the bundled one by default
``raw``       identity (the input, copied): the "no de-flaring" reference
``voxel``     Voxel Transform: 20 ms windows, encode 8 bins, decode (seeded); the
              paper's "null network" control
``efr``       EFR linear comb filter (:mod:`edeflare.baselines.efr`), paper settings
``pfd-a``     PFD with ``score_select = 1`` (:mod:`edeflare.baselines.pfd`)
``pfd-b``     PFD with ``score_select = 0``
``dv-*``      dv-processing's noise filters (:mod:`edeflare.baselines.dv`, the ``dv``
              extra): ``dv-fastdecay``, ``dv-bafilter``, ``dv-knoise``, their defaults
============  =========================================================================

:func:`deflare_file` streams any readable file through any method window by
window with bounded memory and writes any writable format atomically.
Stateful methods (EFR, PFD) carry their state across windows, so the result
equals one pass over the whole file. New methods join with
:func:`register_method` (a factory whose keyword parameters are the method's
parameters; :func:`create_method` rejects any other name).
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import math
import os
import sys
import time
import types
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from tqdm import tqdm

from ._registry import Registry, cli_option
from .baselines.efr import EFRFilter, EFRParams, efr_bias, efr_delays
from .baselines.pfd import PFDFilter, PFDParams
from .errors import ParameterError
from .events import (
    EVENT_DTYPE,
    SensorSize,
    check_events,
    check_sensor_size,
    concat_events,
    select_events,
    window_start_for,
)
from .voxel import decode, encode

__all__ = [
    "METHODS",
    "DeflareStats",
    "Method",
    "ModelParams",
    "StreamRun",
    "Streamer",
    "VoxelParams",
    "create_method",
    "deflare",
    "deflare_file",
    "list_methods",
    "register_method",
]

MethodFactory = Callable[..., "Method"]
METHODS: Registry[MethodFactory] = Registry("method")
"""The registered methods: name -> factory (with its parameter dataclass, where declared)."""
_EMPTY = np.zeros(0, dtype=EVENT_DTYPE)
# Held outputs are re-sorted once at least this many (and as many as already held) arrived.
_REORDER_BATCH = 1 << 16


# ---------------------------------------------------------------------------------------
# The method interface


class Streamer:
    """A method's state over one stream: feed windows in time order, then flush.

    ``process(events, until_us)`` receives the next sorted events, all before
    ``until_us``, with the promise that every later event is at or after
    ``until_us``; it returns the outputs that became final. ``ordered``
    streamers return sorted outputs, each call's at or after the previous
    call's; others (EFR, whose outputs are stamped in the past) return them in
    emission order and tell, through :meth:`safe_time_us`, the time before
    which no later output can fall.
    """

    ordered: bool = True

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        """Consume sorted events (all ``< until_us``); return the outputs now final."""
        raise NotImplementedError

    def flush(self) -> np.ndarray:
        """End of stream: return the outputs still held."""
        return _EMPTY.copy()

    def safe_time_us(self, until_us: int) -> int:
        """No output of a later call will be earlier than this (unordered streamers)."""
        return int(until_us)


class Method:
    """A de-flaring method: ``method(events, sensor_size, *, rng=None) -> events``.

    Subclasses implement :meth:`streamer`; the one-pass call is the same
    streamer fed the whole stream, so the two always agree. Methods whose
    original computes something over the whole input first (EFR's bias) set
    ``needs_prepass`` and implement :meth:`prepare`.
    """

    name: str = ""
    needs_prepass: bool = False

    def __init__(self, **params: Any) -> None:
        self.params = params

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{type(self).__name__}({args})"

    def prepare(self, chunks: Iterable[np.ndarray], sensor_size: SensorSize) -> Any:
        """A first pass over the whole input (only when ``needs_prepass``)."""
        return None

    def streamer(
        self,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None = None,
        prepared: Any = None,
    ) -> Streamer:
        """A fresh state for one stream on ``sensor_size``."""
        raise NotImplementedError

    def __call__(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None = None,
    ) -> np.ndarray:
        """De-flare a whole stream in memory; returns a new sorted stream."""
        check_events(events, sensor_size)
        size = check_sensor_size(sensor_size)
        prepared = self.prepare([events], size) if self.needs_prepass else None
        streamer = self.streamer(size, rng=rng, prepared=prepared)
        until = int(events["t"][-1]) + 1 if events.size else 0
        parts = [streamer.process(events, until), streamer.flush()]
        out = concat_events(parts)
        if not streamer.ordered:
            out = out[np.argsort(out["t"], kind="stable")]
        return out


def register_method(
    name: str, factory: MethodFactory | None = None, *, params: type | None = None
) -> Any:
    """Register a method factory under ``name`` (usable as a decorator).

    The factory returns a :class:`Method`. Its parameters are the fields of
    ``params`` (a frozen dataclass declared next to the algorithm, whose
    ``cli`` metadata also makes the command-line options), else its keyword
    parameters. Registering a name twice is an error.

    Examples
    --------
    >>> @register_method("doc-identity")
    ... def _make(scale: int = 1) -> Method:
    ...     return create_method("raw")
    >>> "doc-identity" in list_methods()
    True
    >>> register_method("doc-identity", _make)
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: method 'doc-identity' is already registered
    >>> _unregister("doc-identity")
    """

    def decorate(fn: MethodFactory) -> MethodFactory:
        if not callable(fn):
            raise ParameterError(f"the factory of method {name!r} must be callable")
        return METHODS.register(name, fn, params=params)

    if not isinstance(name, str) or not name:
        raise ParameterError(f"a method name must be a non-empty string, got {name!r}")
    return decorate if factory is None else decorate(factory)


def _unregister(name: str) -> None:
    """Remove a registered method (for tests and examples)."""
    METHODS.unregister(name)


def list_methods() -> list[str]:
    """Names of the registered methods, sorted.

    Examples
    --------
    >>> "efr" in list_methods()
    True
    """
    return METHODS.names()


def create_method(name: str, **params: Any) -> Method:
    """Make a method by name with its parameters.

    Raises
    ------
    ParameterError
        (a ``ValueError``) for an unknown name or parameter, listing the valid
        ones, or an invalid value.

    Examples
    --------
    >>> create_method("efr", frequency_hz=100)  # doctest: +ELLIPSIS
    EFRMethod(frequency_hz=100, rho1=0.6, ...)
    >>> create_method("efr", frequency=100)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: method 'efr' has no parameter 'frequency'; valid: ...
    """
    method = METHODS.create(name, **params)
    if not isinstance(method, Method):
        raise ParameterError(f"the factory of method {name!r} returned {type(method).__name__}")
    method.name = name
    return method


def method_parameters(name: str) -> dict[str, Any]:
    """The parameters of a registered method and their defaults.

    Examples
    --------
    >>> method_parameters("voxel")
    {'window_us': 20000, 'bins': 8}
    """
    return METHODS.parameters(name)


def _values(params: Any) -> dict[str, Any]:
    """The fields of a parameter dataclass as a dict (arrays not copied)."""
    return {f.name: getattr(params, f.name) for f in dataclasses.fields(params)}


def deflare(
    events: np.ndarray,
    sensor_size: SensorSize,
    method: str | Method,
    *,
    rng: np.random.Generator | int | None = None,
    **params: Any,
) -> np.ndarray:
    """De-flare an in-memory stream with a method given by name (and parameters) or object.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5_000, 30_000], [1, 2, 3], [0, 0, 0], [1, 0, 1])
    >>> deflare(ev, (4, 1), "efr", frequency_hz=50)["t"].tolist()  # all in the warm-up
    [0, 5000]
    """
    if isinstance(method, Method):
        if params:
            raise ParameterError("pass parameters either to create_method or here, not both")
        m = method
    else:
        m = create_method(method, **params)
    return m(events, sensor_size, rng=rng)


# ---------------------------------------------------------------------------------------
# The registered methods


class _CopyStreamer(Streamer):
    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return events.copy()


class RawMethod(Method):
    """The input unchanged (a copy): the reference with no de-flaring."""

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        return _CopyStreamer()


class _WindowStreamer(Streamer):
    """Aligned windows of ``window_us`` through a batch ``transform``, in window order.

    ``transform(batch, span)`` maps a list of complete ``(window_start, events)``
    windows to their outputs; windows without input events are skipped.
    ``span`` is ``(first, end)``: the time of the stream's first event and,
    once the stream is known to have ended (at :meth:`flush`), one past its
    last event, else None. A transform that synthesises events (the model)
    keeps them inside it: the sensor recorded nothing outside. The window
    holding the latest event is kept back until a later event or the end
    shows whether the stream ends in it.
    """

    def __init__(
        self,
        window_us: int,
        transform: Callable[
            [list[tuple[int, np.ndarray]], tuple[int, int | None]], list[np.ndarray]
        ],
    ) -> None:
        self.window_us = window_us
        self.transform = transform
        self.pending = _EMPTY
        self.start: int | None = None
        self.first_t: int | None = None

    def _windows(self, until_us: int | None) -> np.ndarray:
        batch = []
        end_t = None
        if self.pending.size:
            last = int(self.pending["t"][-1]) + 1
            if until_us is None:
                end_t = last
            else:  # hold the window of the last event: it may be the stream's last
                until_us = min(until_us, last)
        # the times once, contiguous: searching the records' strided field copies it
        # on every call, quadratic in a long in-memory stream
        t = np.ascontiguousarray(self.pending["t"])
        i = 0
        while i < t.size:
            if self.start is None or t[i] >= self.start + self.window_us:
                self.start = window_start_for(int(t[i]), self.window_us)
            end = self.start + self.window_us
            if until_us is not None and end > until_us:
                break
            k = int(np.searchsorted(t, end, side="left"))
            batch.append((self.start, self.pending[i:k]))
            i = k
            self.start = end
        self.pending = self.pending[i:]
        if not batch or self.first_t is None:
            return _EMPTY.copy()
        out = self.transform(batch, (self.first_t, end_t))
        return concat_events(out) if out else _EMPTY.copy()

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        if events.size:
            if self.first_t is None:
                self.first_t = int(events["t"][0])
            self.pending = concat_events([self.pending, events]) if self.pending.size else events
        return self._windows(until_us)

    def flush(self) -> np.ndarray:
        return self._windows(None)


class _TwoViewStreamer(Streamer):
    """A mask model's keep decisions from two windowings of the stream, averaged.

    View 0 cuts the stream into aligned windows of ``window_us``, view 1 into
    the same windows delayed by ``shift_us``. ``logits(batch)`` gives per-event
    keep logits for a list of ``(window_start, events)``; an event is kept
    where the mean of its two logits exceeds ``cut``. Events are emitted once
    both of their windows are complete, so outputs lag the input by up to a
    window plus the shift.
    """

    def __init__(
        self,
        window_us: int,
        shift_us: int,
        logits: Callable[[list[tuple[int, np.ndarray]]], list[np.ndarray]],
        cut: float,
        batch_windows: int,
    ) -> None:
        self.window_us = window_us
        self.delays = (0, shift_us)
        self.logits = logits
        self.cut = cut
        self.batch_windows = batch_windows
        self.pending = _EMPTY  # events not yet emitted
        # per view, the logits of the first pending events (those whose window is done)
        self.done: list[np.ndarray] = [np.zeros(0), np.zeros(0)]

    def _batches(self, view: int, until_us: int | None) -> list[list[tuple[int, np.ndarray]]]:
        """The view's complete windows not yet judged, in network batches."""
        w, delay = self.window_us, self.delays[view]
        events = self.pending[self.done[view].size :]
        t = np.ascontiguousarray(events["t"])  # searched once per window: no strided copies
        windows = []
        i = 0
        while i < events.size:
            start = (int(t[i]) + delay) // w * w - delay
            end = start + w
            if until_us is not None and end > until_us:
                break
            k = int(np.searchsorted(t, end, side="left"))
            windows.append((start, events[i:k]))
            i = k
        step = self.batch_windows
        return [windows[j : j + step] for j in range(0, len(windows), step)]

    def _judge(self, batches: list[list[tuple[int, np.ndarray]]]) -> list[np.ndarray]:
        return [v for batch in batches for v in self.logits(batch)]

    def _advance(self, until_us: int | None) -> None:
        work = [self._batches(view, until_us) for view in (0, 1)]
        if work[0] and work[1]:
            # the two views are independent: the second runs on another core (the
            # per-event kernels and the network release the GIL); the results do not
            # depend on it
            with concurrent.futures.ThreadPoolExecutor(1) as pool:
                second = pool.submit(self._judge, work[1])
                values = [self._judge(work[0]), second.result()]
        else:
            values = [self._judge(w) for w in work]
        self.done = [np.concatenate([d, *v]) for d, v in zip(self.done, values, strict=True)]

    def _emit(self) -> np.ndarray:
        n = min(v.size for v in self.done)
        keep = (self.done[0][:n] + self.done[1][:n]) / 2 > self.cut
        out = select_events(self.pending[:n], keep)
        self.pending = self.pending[n:]
        self.done = [v[n:] for v in self.done]
        return out

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        if events.size:
            self.pending = concat_events([self.pending, events]) if self.pending.size else events
        self._advance(until_us)
        return self._emit()

    def flush(self) -> np.ndarray:
        self._advance(None)
        return self._emit()


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


@dataclasses.dataclass(frozen=True)
class ModelParams:
    """The ``model`` method's parameters (see :class:`ModelMethod`)."""

    cli_title: ClassVar[str] = "model (E-DeflareNet)"

    weights: str | os.PathLike[str] | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--model",
            "weights (.safetensors), an exported .onnx file, or the name of a bundled model",
            metavar="PATH",
            type=Path,
            convert=str,
            default_text="the bundled night model; 'eflare' names the other one",
        ),
    )
    decoder: str = dataclasses.field(
        default="keep",
        metadata=cli_option(
            "--decoder",
            "keep: edit the input's own events; paper: resample the grid",
            choices=("keep", "paper"),
        ),
    )
    device: str = dataclasses.field(
        default="auto", metadata=cli_option("--device", "auto, cpu, cuda, cuda:1")
    )
    batch_windows: int = dataclasses.field(
        default=4,
        metadata=cli_option("--batch-windows", "20 ms windows per network call", metavar="N"),
    )
    seed: int = 0
    keep_threshold: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--keep-threshold",
            "mask models: keep an event above this keep probability (lower keeps more)",
            metavar="P",
            type=float,
            default_text="the model card's",
        ),
    )
    ghost_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--ghost-shift",
            "mask models: lower the keep logit by this much for the sparse events where a "
            "reflective ghost of the window's lights can be (the lights reflected through the "
            "sensor's centre; 0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    halo_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--halo-shift",
            "mask models: lower the keep logit by this much in the halo of the window's lights "
            "(from just outside each light to six of its radii, at most a fifth of the sensor's "
            "width; 0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    streak_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--streak-shift",
            "mask models: lower the keep logit by this much on the diffraction spikes of the "
            "window's lights (saturated radial runs in opposite pairs; 0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    light_free_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--light-free-shift",
            "mask models: raise the keep logit by this much in the windows without a light "
            "(flare needs a bright source; 0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    light_free_support: int | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--light-free-support",
            "mask models: the light-free shift raises only the events with at least this many "
            "other events of their window in their 5x5 square (a night lamp too slow for the "
            "light test scatters isolated events; 0: every event)",
            metavar="N",
            type=int,
            default_text="the model card's",
        ),
    )
    light_free_crowding: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--light-free-crowding",
            "mask models: with a light-free support, the isolated events still get the "
            "light-free shift unless they crowd, more of them within a sixth of the "
            "sensor's smaller side than the window's median density allows by this many "
            "Poisson standard deviations (scattered light lies around its source, background "
            "activity evenly; 0: no isolated event gets it)",
            metavar="Z",
            type=float,
            default_text="the model card's",
        ),
    )
    scatter_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--scatter-shift",
            "mask models, with a light-free support and crowding: in a window without a "
            "light, where crowded isolated events are a share of all (the scattered light "
            "of a lamp too slow for the light test), lower them by this much, raise the "
            "dense events (the lamp) by this much more, and give the sparser ones (its "
            "bloom) no light-free shift (0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    far_shift: float | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--far-shift",
            "mask models: raise the keep logit by this much for the events far from every "
            "light of their window (beyond 0.3 of the sensor's width and 8 of the light's "
            "radii, and not where the lights' ghosts can be nor on their spikes: flare lies "
            "around its source; 0: off)",
            metavar="LOGIT",
            type=float,
            default_text="the model card's",
        ),
    )
    runtime: str = dataclasses.field(
        default="auto",
        metadata=cli_option(
            "--runtime",
            "what runs the network: auto (ONNX Runtime for .onnx files, and for mask models "
            "on CPU where the onnx extra is installed; else torch), torch, onnx (exports the "
            "weights in memory; needs the onnx extra)",
            choices=("auto", "torch", "onnx"),
        ),
    )
    phase_shift_us: int | None = dataclasses.field(
        default=None,
        metadata=cli_option(
            "--phase-shift-ms",
            "mask models: judge each event in the aligned windows and in windows delayed by "
            "this much, keeping it where the mean of the two keep logits passes (0: aligned "
            "windows only, half the work)",
            metavar="MS",
            unit="ms",
            type=float,
            default_text="a quarter of the model's window (5 ms)",
        ),
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

        return _WindowStreamer(w, transform)


class _EFRStreamer(Streamer):
    ordered = False

    def __init__(self, filt: EFRFilter) -> None:
        self.filter = filt

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return self.filter.process(events)

    def safe_time_us(self, until_us: int) -> int:
        return self.filter.safe_time_us(until_us)


class EFRMethod(Method):
    """EFR (see :class:`~edeflare.baselines.efr.EFRFilter`); the bias comes from a first pass."""

    def __init__(
        self,
        frequency_hz: float,
        rho1: float,
        merge_us: int,
        threshold: float,
        bias: np.ndarray | None,
        min_bias_events: int,
        keep_warmup: bool | None,
        shift_back: bool,
    ) -> None:
        super().__init__(
            frequency_hz=frequency_hz,
            rho1=rho1,
            merge_us=merge_us,
            threshold=threshold,
            bias=bias,
            min_bias_events=min_bias_events,
            keep_warmup=keep_warmup,
            shift_back=shift_back,
        )
        efr_delays(frequency_hz)
        if isinstance(min_bias_events, bool) or not isinstance(min_bias_events, (int, np.integer)):
            raise ParameterError(f"min_bias_events must be an int, got {min_bias_events!r}")
        if min_bias_events < 0:
            raise ParameterError(f"min_bias_events must be >= 0, got {min_bias_events!r}")
        # Validates every other value now, rather than at the first window.
        EFRFilter(
            (1, 1),
            frequency_hz,
            rho1,
            merge_us,
            threshold,
            keep_warmup=keep_warmup,
            shift_back=shift_back,
        )
        self.needs_prepass = bias is None

    def __repr__(self) -> str:
        shown = {k: v for k, v in self.params.items() if k != "bias"}
        shown["bias"] = "map" if self.params["bias"] is not None else None
        return "EFRMethod(" + ", ".join(f"{k}={v!r}" for k, v in shown.items()) + ")"

    def prepare(self, chunks: Iterable[np.ndarray], sensor_size: SensorSize) -> np.ndarray:
        """The bias map over the whole input (the original's first pass)."""
        return efr_bias(chunks, sensor_size, self.params["min_bias_events"])

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        p = self.params
        bias = p["bias"] if p["bias"] is not None else prepared
        filt = EFRFilter(
            sensor_size,
            p["frequency_hz"],
            p["rho1"],
            p["merge_us"],
            p["threshold"],
            bias=bias,
            keep_warmup=p["keep_warmup"],
            shift_back=p["shift_back"],
        )
        return _EFRStreamer(filt)


class _PFDStreamer(Streamer):
    def __init__(self, filt: PFDFilter) -> None:
        self.filter = filt

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return self.filter.filter(events)


class PFDMethod(Method):
    """PFD-A or PFD-B (see :class:`~edeflare.baselines.pfd.PFDFilter`)."""

    def __init__(self, score: str, **params: Any) -> None:
        super().__init__(**params)
        self.score = score
        PFDFilter((1, 1), score=score, **params)  # validate now

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        return _PFDStreamer(PFDFilter(sensor_size, score=self.score, **self.params))


class ModelMethod(Method):
    """A trained E-DeflareNet (see :class:`~edeflare.models.infer.ModelDeflarer`).

    ``weights=None`` takes the package's default model
    (:data:`~edeflare.models.infer.DEFAULT_MODEL`, ``"night"``), a name without a
    suffix a bundled one (``"eflare"``: ``assets/eflare.safetensors``, the
    voxel-to-voxel model of the uncalibrated simulator). Windows are the
    model's own (its card's ``window_us``, 20 ms) and are batched
    ``batch_windows`` at a time; decoding is seeded by ``(seed, window start)``.

    A mask model judges each event twice: in the aligned windows and in windows
    delayed by ``phase_shift_us`` (default: a quarter window, 5 ms), and keeps
    it where the mean of its two keep logits passes the threshold. Where a
    recording's windows start relative to what it shows is chance, and one
    windowing can flatter or wrong a model: on the DAVIS346 flicker lamps the
    default model alone removes 84 % of the flare with windows at one phase and
    36 % a quarter window later (the lamps flicker at 100 Hz: a 10 ms shift
    would see them at the same phase again, 5 ms at the opposite one; at 120 Hz
    it is 0.6 of a period). Two views cost twice the network work; ``0``
    keeps one. Voxel-to-voxel models use one windowing.
    """

    def __init__(
        self,
        weights: str | os.PathLike[str] | None,
        decoder: str,
        device: str,
        batch_windows: int,
        seed: int,
        runtime: str = "auto",
        keep_threshold: float | None = None,
        phase_shift_us: int | None = None,
        ghost_shift: float | None = None,
        halo_shift: float | None = None,
        streak_shift: float | None = None,
        light_free_shift: float | None = None,
        light_free_support: int | None = None,
        light_free_crowding: float | None = None,
        scatter_shift: float | None = None,
        far_shift: float | None = None,
    ) -> None:
        from .models.ghosts import check_ghost_shift, check_logit_shift, check_support
        from .models.halos import check_halo_shift
        from .models.infer import DECODERS, RUNTIMES, resolve_weights
        from .models.streaks import check_streak_shift
        from .models.weights import read_card

        if decoder not in DECODERS:
            raise ParameterError(f"decoder must be one of {DECODERS}, got {decoder!r}")
        if runtime not in RUNTIMES:
            raise ParameterError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
        if keep_threshold is not None and not 0.0 < keep_threshold < 1.0:
            raise ParameterError(f"keep_threshold must be in (0, 1), got {keep_threshold!r}")
        if ghost_shift is not None:
            ghost_shift = check_ghost_shift(ghost_shift)
        if halo_shift is not None:
            halo_shift = check_halo_shift(halo_shift)
        if streak_shift is not None:
            streak_shift = check_streak_shift(streak_shift)
        if light_free_shift is not None:
            light_free_shift = check_logit_shift(light_free_shift, "light_free_shift")
        if light_free_support is not None:
            light_free_support = check_support(light_free_support, "light_free_support")
        if light_free_crowding is not None:
            light_free_crowding = check_logit_shift(light_free_crowding, "light_free_crowding")
        if scatter_shift is not None:
            scatter_shift = check_logit_shift(scatter_shift, "scatter_shift")
        if far_shift is not None:
            far_shift = check_logit_shift(far_shift, "far_shift")
        if (
            isinstance(batch_windows, bool)
            or not isinstance(batch_windows, int)
            or batch_windows < 1
        ):
            raise ParameterError(f"batch_windows must be a positive int, got {batch_windows!r}")
        path = resolve_weights(weights)
        self.card = read_card(path)  # fails now on a missing or foreign file
        mask = self.card.preset.startswith("mask.")
        if phase_shift_us is None:
            phase_shift_us = self.card.window_us // 4 if mask else 0
        if (
            isinstance(phase_shift_us, bool)
            or not isinstance(phase_shift_us, (int, np.integer))
            or not 0 <= phase_shift_us < self.card.window_us
        ):
            raise ParameterError(
                f"phase_shift_us must be an int in [0, {self.card.window_us}) (the model's "
                f"window), got {phase_shift_us!r}"
            )
        if phase_shift_us and not mask:
            raise ParameterError(
                f"phase_shift_us needs a mask model; {path} is a {self.card.preset} "
                "(voxel-to-voxel): give 0"
            )
        super().__init__(
            weights=str(path),
            decoder=decoder,
            device=device,
            batch_windows=batch_windows,
            seed=seed,
            runtime=runtime,
            keep_threshold=keep_threshold,
            phase_shift_us=int(phase_shift_us),
            ghost_shift=ghost_shift,
            halo_shift=halo_shift,
            streak_shift=streak_shift,
            light_free_shift=light_free_shift,
            light_free_support=light_free_support,
            light_free_crowding=light_free_crowding,
            scatter_shift=scatter_shift,
            far_shift=far_shift,
        )
        # One loaded (and, with ONNX Runtime, exported and warmed) network per seed,
        # shared by every stream of this method: a benchmark opens one per sequence.
        self._deflarers: dict[int, Any] = {}

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        from .models.infer import ModelDeflarer

        p = self.params
        seed = p["seed"] if rng is None or not isinstance(rng, (int, np.integer)) else int(rng)
        if seed not in self._deflarers:
            self._deflarers[seed] = ModelDeflarer(
                p["weights"],
                decoder=p["decoder"],
                device=p["device"],
                batch_windows=p["batch_windows"],
                seed=seed,
                runtime=p["runtime"],
                keep_threshold=p["keep_threshold"],
                ghost_shift=p["ghost_shift"],
                halo_shift=p["halo_shift"],
                streak_shift=p["streak_shift"],
                light_free_shift=p["light_free_shift"],
                light_free_support=p["light_free_support"],
                light_free_crowding=p["light_free_crowding"],
                scatter_shift=p["scatter_shift"],
                far_shift=p["far_shift"],
            )
        deflarer = self._deflarers[seed]
        size = check_sensor_size(sensor_size)
        deflarer.warm_up(size)
        if p["phase_shift_us"]:
            from .models.flaremask import keep_logit_threshold

            return _TwoViewStreamer(
                deflarer.window_us,
                p["phase_shift_us"],
                lambda batch: deflarer.window_logits(batch, size),
                keep_logit_threshold(deflarer.keep_threshold),
                deflarer.batch_windows,
            )

        def transform(
            batch: list[tuple[int, np.ndarray]], span: tuple[int, int | None]
        ) -> list[np.ndarray]:
            return [ev for _, ev in deflarer.windows(batch, size, span_us=span)]

        return _WindowStreamer(deflarer.window_us, transform)


@register_method("model", params=ModelParams)
def _make_model(**params: Any) -> Method:
    return ModelMethod(**_values(ModelParams(**params)))


@register_method("raw")
def _make_raw() -> Method:
    return RawMethod()


@register_method("efr", params=EFRParams)
def _make_efr(**params: Any) -> Method:
    return EFRMethod(**_values(EFRParams(**params)))


def _pfd_factory(score: str) -> MethodFactory:
    def make(**params: Any) -> Method:
        return PFDMethod(score, **_values(PFDParams(**params)))

    make.__name__ = f"_make_pfd_{score.lower()}"
    return make


register_method("pfd-a", _pfd_factory("A"), params=PFDParams)
register_method("pfd-b", _pfd_factory("B"), params=PFDParams)


@register_method("voxel", params=VoxelParams)
def _make_voxel(**params: Any) -> Method:
    return VoxelMethod(**_values(VoxelParams(**params)))


class _DvStreamer(Streamer):
    def __init__(self, filt: Any) -> None:
        self.filter = filt

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return self.filter.filter(events)


class DvMethod(Method):
    """A dv-processing noise filter (see :mod:`edeflare.baselines.dv`; needs the ``dv`` extra)."""

    def __init__(self, filter_name: str, **params: Any) -> None:
        from .baselines.dv import _check_params

        super().__init__(**_check_params(filter_name, params))  # validate now
        self.filter_name = filter_name

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        from .baselines.dv import DvFilter

        return _DvStreamer(DvFilter(sensor_size, self.filter_name, **self.params))


@register_method("dv-fastdecay")
def _make_dv_fastdecay(
    half_life_us: int = 10_000, subdivision_factor: int = 4, noise_threshold: float = 6.0
) -> Method:
    return DvMethod(
        "fastdecay",
        half_life_us=half_life_us,
        subdivision_factor=subdivision_factor,
        noise_threshold=noise_threshold,
    )


@register_method("dv-bafilter")
def _make_dv_bafilter(duration_us: int = 2_000) -> Method:
    return DvMethod("bafilter", duration_us=duration_us)


@register_method("dv-knoise")
def _make_dv_knoise(time_delta_us: int = 1_000) -> Method:
    return DvMethod("knoise", time_delta_us=time_delta_us)


# ---------------------------------------------------------------------------------------
# Streaming files


@dataclasses.dataclass(frozen=True)
class DeflareStats:
    """What :func:`deflare_file` did, and how fast.

    The timings are not part of the equality or the repr (they differ run to run).
    """

    events_in: int
    events_out: int
    late_dropped: int
    """Outputs that lagged their input by more than ``max_lag_us`` (EFR only)."""
    seconds: float = dataclasses.field(default=0.0, compare=False, repr=False)
    """Wall time of reading, de-flaring and writing (not of the method's setup,
    such as loading a model)."""
    span_us: int = dataclasses.field(default=0, compare=False, repr=False)
    """Time from the input's first event to its last."""
    latency_ms: tuple[float, float, float] = dataclasses.field(
        default=(0.0, 0.0, 0.0), compare=False, repr=False
    )
    """Median, 95th percentile and maximum, over the streaming windows, of the
    time from the moment a window is complete (its last event read) to the
    moment the method returns its output: the method's latency in a live stream."""

    @property
    def real_time_factor(self) -> float:
        """Run time over recording time (below 1: faster than the sensor)."""
        return self.seconds / (self.span_us * 1e-6) if self.span_us > 0 else math.nan


class _Reorder:
    """Holds an unordered streamer's outputs until no later output can precede them.

    Outputs arrive in emission order; released batches are stable-sorted by
    time, so their concatenation is the stable sort of all outputs (the
    one-pass result) as long as nothing is dropped. An output older than
    what was already released (it lagged more than ``max_lag_us``) is dropped
    and counted.
    """

    def __init__(self, streamer: Streamer, max_lag_us: int | None) -> None:
        self.streamer = streamer
        self.max_lag_us = max_lag_us
        self.held = _EMPTY  # sorted
        self.new: list[np.ndarray] = []
        self.n_new = 0
        self.released: int | None = None
        self.dropped = 0

    def _merge(self) -> None:
        if not self.new:
            return
        new = concat_events(self.new)
        new = new[np.argsort(new["t"], kind="stable")]
        both = concat_events([self.held, new])
        self.held = both[np.argsort(both["t"], kind="stable")]  # two sorted runs: linear
        self.new, self.n_new = [], 0

    def push(self, outputs: np.ndarray, until_us: int) -> np.ndarray:
        if outputs.size and self.released is not None:
            late = outputs["t"] < self.released
            if late.any():
                self.dropped += int(late.sum())
                outputs = outputs[~late]
        if outputs.size:
            self.new.append(outputs)
            self.n_new += outputs.size
        # Release in batches at least as large as what is held: linear work overall.
        if self.n_new < max(_REORDER_BATCH, self.held.size):
            return _EMPTY
        mark = self.streamer.safe_time_us(until_us)
        if self.max_lag_us is not None:
            mark = max(mark, until_us - self.max_lag_us)
        self._merge()
        k = int(np.searchsorted(self.held["t"], mark, side="left"))
        out, self.held = self.held[:k], self.held[k:]
        self.released = mark if self.released is None else max(self.released, mark)
        return out

    def finish(self, outputs: np.ndarray) -> np.ndarray:
        if outputs.size and self.released is not None:
            late = outputs["t"] < self.released
            self.dropped += int(late.sum())
            outputs = outputs[~late]
        self.new.append(outputs)
        self._merge()
        out, self.held = self.held, _EMPTY
        return out


class StreamRun:
    """One method streamed over aligned windows: sorted outputs, counts and call timings.

    Shared by :func:`deflare_file` (which writes the outputs) and the benchmark
    (which scores them window by window), so both run a method the same way.
    """

    def __init__(
        self,
        method: Method,
        sensor_size: SensorSize,
        *,
        rng: np.random.Generator | int | None,
        prepared: Any,
        max_lag_us: int | None,
    ) -> None:
        self.streamer = method.streamer(sensor_size, rng=rng, prepared=prepared)
        # load the stream check's compiled kernel now (start-up), not in the first window
        check_events(np.zeros(1, dtype=EVENT_DTYPE))
        self.reorder = None if self.streamer.ordered else _Reorder(self.streamer, max_lag_us)
        self.n_in = 0
        self.first_t: int | None = None
        self.last_t: int | None = None
        self.call_seconds: list[float] = []
        """Seconds of each ``process`` call and of the final ``flush``."""

    @property
    def dropped(self) -> int:
        """Outputs dropped for lagging more than ``max_lag_us`` (EFR only)."""
        return self.reorder.dropped if self.reorder is not None else 0

    def outputs(
        self, windows: Iterable[tuple[int, np.ndarray]], window_us: int
    ) -> Iterator[np.ndarray]:
        """Feed ``(start_us, events)`` windows in order; yield sorted output chunks."""
        streamer, reorder = self.streamer, self.reorder
        for start, events in windows:
            self.n_in += events.size
            if events.size:
                self.first_t = int(events["t"][0]) if self.first_t is None else self.first_t
                self.last_t = int(events["t"][-1])
            t_call = time.perf_counter()
            out = streamer.process(events, start + window_us)
            self.call_seconds.append(time.perf_counter() - t_call)
            yield out if reorder is None else reorder.push(out, start + window_us)
        t_call = time.perf_counter()
        tail = streamer.flush()
        self.call_seconds.append(time.perf_counter() - t_call)
        yield tail if reorder is None else reorder.finish(tail)


def deflare_file(
    in_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    method: str | Method,
    window_us: int = 20_000,
    sensor_size: SensorSize | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    rng: np.random.Generator | int | None = None,
    max_lag_us: int | None = 10_000_000,
    evt_version: str = "evt2",
    progress: bool | None = None,
    group: str | None = None,
) -> DeflareStats:
    """Stream a file through a method window by window and write the result atomically.

    Parameters
    ----------
    in_path, out_path : path-like
        Any readable / writable event format, by suffix (see
        :func:`edeflare.io.list_formats`). The output is written to a
        temporary file and moved into place only when complete.
    method : str or Method
        A registered name (see :func:`list_methods`) or a method object.
    window_us : int
        Length of the aligned windows read at a time (memory: one window).
    sensor_size : (width, height), optional
        For files that record none.
    params : mapping, optional
        The method's parameters, when ``method`` is a name.
    rng : numpy.random.Generator or int, optional
        For methods that draw (``voxel``); a seed makes the output reproducible.
    max_lag_us : int or None
        EFR stamps outputs in the past (a pixel's queues advance only when it
        gets a new event), so outputs are held until no earlier one can come.
        Outputs lagging their input by more than this are released anyway and
        later ones older than that are dropped (counted in the result, with a
        warning), which bounds memory. ``None`` holds everything: exact for
        any length, memory grows with the output. Files shorter than
        ``max_lag_us`` are always exact.
    evt_version : {"evt2", "evt3"}
        Encoding of ``.raw`` outputs (see :func:`edeflare.io.write_event_chunks`).
    progress : bool, optional
        Show a progress bar; ``None`` shows it on a terminal only.

    Returns
    -------
    DeflareStats
        Events read, events written, late outputs dropped.

    Notes
    -----
    EFR computes its per-pixel bias over the whole input, as the original
    program does: unless a ``bias`` map is given, the file is read twice (a
    first pass for the bias map, then the filtering pass).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io import write_events, read_events
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> ev = make_events([0, 100, 40_000], [1, 2, 3], [1, 1, 1], [1, 0, 1])
    >>> write_events(folder / "in.h5", ev, (8, 8))
    >>> deflare_file(folder / "in.h5", folder / "out.npz", "raw", progress=False)
    DeflareStats(events_in=3, events_out=3, late_dropped=0)
    """
    from .io import open_events, write_event_chunks

    if isinstance(window_us, bool) or not isinstance(window_us, (int, np.integer)):
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if window_us <= 0:
        raise ParameterError(f"window_us must be a positive int, got {window_us!r}")
    if max_lag_us is not None and (isinstance(max_lag_us, bool) or max_lag_us < 0):
        raise ParameterError(f"max_lag_us must be a non-negative int or None, got {max_lag_us!r}")
    if isinstance(method, Method):
        if params:
            raise ParameterError("pass parameters either to create_method or here, not both")
        m = method
    else:
        m = create_method(method, **dict(params or {}))
    src = open_events(in_path, sensor_size, group=group)
    size = src.sensor_size
    disable = None if progress is None else not progress
    prepared = None
    if m.needs_prepass:
        with tqdm(
            total=src.n_events,
            unit="ev",
            unit_scale=True,
            disable=disable,
            leave=False,
            desc="first pass",
        ) as bar:

            def counted() -> Iterator[np.ndarray]:
                for chunk in src.chunks():
                    bar.update(chunk.size)
                    yield chunk

            prepared = m.prepare(counted(), size)
    run = StreamRun(m, size, rng=rng, prepared=prepared, max_lag_us=max_lag_us)
    t_begin = time.perf_counter()

    def windows(bar: tqdm) -> Iterator[tuple[int, np.ndarray]]:
        for start, events in src.windows(window_us):
            bar.update(events.size)
            yield start, events

    desc = m.name or type(m).__name__
    with tqdm(
        total=src.n_events, unit="ev", unit_scale=True, disable=disable, leave=False, desc=desc
    ) as bar:
        n_out = write_event_chunks(
            out_path, run.outputs(windows(bar), window_us), size, evt_version=evt_version
        )
    dropped = run.dropped
    if dropped:
        warnings.warn(
            f"{out_path}: {dropped} output events lagged their input by more than "
            f"max_lag_us={max_lag_us} and were dropped; pass max_lag_us=None for an exact result",
            stacklevel=2,
        )
    calls_ms = np.asarray(run.call_seconds) * 1e3
    return DeflareStats(
        run.n_in,
        n_out,
        dropped,
        seconds=time.perf_counter() - t_begin,
        span_us=0 if run.first_t is None or run.last_t is None else run.last_t - run.first_t,
        latency_ms=(
            float(np.median(calls_ms)),
            float(np.percentile(calls_ms, 95)),
            float(calls_ms.max()),
        ),
    )


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`deflare`: ``edeflare.deflare(events, size, "efr")``.

    The package face offers the function ``edeflare.deflare`` and the module
    ``edeflare.deflare`` (``edeflare.deflare.register_method``) under one name
    without one shadowing the other.
    """

    def __call__(self, *args: Any, **kwargs: Any) -> np.ndarray:
        return deflare(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
