"""The ``model`` method: a trained E-DeflareNet (:mod:`edeflare.models`) behind the registry."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .._registry import cli_option
from ..errors import ParameterError
from .base import Method, param_values, register_method

__all__ = ["ModelMethod", "ModelParams"]


@dataclasses.dataclass(frozen=True)
class _ModelOptions:
    """The ``model`` method's own parameters (the rules' knobs join them in ModelParams)."""

    cli_title: ClassVar[str] = "model (a bundled or trained network; default night)"

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


def _rule_fields() -> list[tuple[str, Any, Any]]:
    """The rules' knobs as ``model`` parameters: None takes the model card's value."""
    from ..rules import knob_fields

    return [
        (name, f"{f.type} | None", dataclasses.field(default=None, metadata=f.metadata))
        for name, (_, f) in knob_fields().items()
    ]


ModelParams = dataclasses.make_dataclass(
    "ModelParams", _rule_fields(), bases=(_ModelOptions,), frozen=True
)
ModelParams.__module__ = __name__
ModelParams.__doc__ = """The ``model`` method's parameters (see :class:`ModelMethod`): its own and
the rules' knobs (:mod:`edeflare.rules`), each None for the model card's value."""


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
    it where the mean of its two keep logits passes the threshold
    (:mod:`edeflare.models.two_view`); ``0`` keeps one windowing. The rules'
    knobs (:mod:`edeflare.rules`) default to the model card's values.
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
        **rules: float | int | None,
    ) -> None:
        from ..models.infer import DECODERS, RUNTIMES, resolve_weights
        from ..models.two_view import check_phase_shift
        from ..models.weights import read_card
        from ..rules import RuleSet

        if decoder not in DECODERS:
            raise ParameterError(f"decoder must be one of {DECODERS}, got {decoder!r}")
        if runtime not in RUNTIMES:
            raise ParameterError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
        if keep_threshold is not None and not 0.0 < keep_threshold < 1.0:
            raise ParameterError(f"keep_threshold must be in (0, 1), got {keep_threshold!r}")
        RuleSet(rules)  # checks every knob now, naming it
        if (
            isinstance(batch_windows, bool)
            or not isinstance(batch_windows, int)
            or batch_windows < 1
        ):
            raise ParameterError(f"batch_windows must be a positive int, got {batch_windows!r}")
        path = resolve_weights(weights)
        self.card = read_card(path)  # fails now on a missing or foreign file
        phase_shift_us = check_phase_shift(phase_shift_us, self.card, path)
        super().__init__(
            weights=str(path),
            decoder=decoder,
            device=device,
            batch_windows=batch_windows,
            seed=seed,
            runtime=runtime,
            keep_threshold=keep_threshold,
            phase_shift_us=phase_shift_us,
            **rules,
        )
        # One loaded (and, with ONNX Runtime, exported and warmed) network per seed,
        # shared by every stream of this method: a benchmark opens one per sequence.
        self._deflarers: dict[int, Any] = {}
        self._knobs = tuple(rules)

    def streamer(self, sensor_size, *, rng=None, prepared=None):  # type: ignore[no-untyped-def]
        from ..models.infer import ModelDeflarer

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
                **{k: p[k] for k in self._knobs},
            )
        deflarer = self._deflarers[seed]
        return deflarer.streamer(sensor_size, phase_shift_us=p["phase_shift_us"])


@register_method("model", params=ModelParams)
def _make_model(**params: Any) -> Method:
    return ModelMethod(**param_values(ModelParams(**params)))
