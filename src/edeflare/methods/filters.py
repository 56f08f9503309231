"""The classical event filters as methods: EFR, PFD-A / PFD-B and dv-processing's filters."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from ..baselines.efr import EFRFilter, EFRParams, efr_bias, efr_delays
from ..baselines.pfd import PFDFilter, PFDParams
from ..errors import ParameterError
from ..events import SensorSize
from .base import Method, MethodFactory, Streamer, param_values, register_method

__all__ = ["DvMethod", "EFRMethod", "PFDMethod"]


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


@register_method("efr", params=EFRParams)
def _make_efr(**params: Any) -> Method:
    return EFRMethod(**param_values(EFRParams(**params)))


def _pfd_factory(score: str) -> MethodFactory:
    def make(**params: Any) -> Method:
        return PFDMethod(score, **param_values(PFDParams(**params)))

    make.__name__ = f"_make_pfd_{score.lower()}"
    return make


register_method("pfd-a", _pfd_factory("A"), params=PFDParams)
register_method("pfd-b", _pfd_factory("B"), params=PFDParams)


class _DvStreamer(Streamer):
    def __init__(self, filt: Any) -> None:
        self.filter = filt

    def process(self, events: np.ndarray, until_us: int) -> np.ndarray:
        return self.filter.filter(events)


class DvMethod(Method):
    """A dv-processing noise filter (see :mod:`edeflare.baselines.dv`; needs the ``dv`` extra)."""

    def __init__(self, filter_name: str, **params: Any) -> None:
        from ..baselines.dv import _check_params

        super().__init__(**_check_params(filter_name, params))  # validate now
        self.filter_name = filter_name

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        from ..baselines.dv import DvFilter

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
