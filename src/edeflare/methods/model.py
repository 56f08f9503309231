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
        from ..models.ghosts import check_ghost_shift, check_logit_shift, check_support
        from ..models.halos import check_halo_shift
        from ..models.infer import DECODERS, RUNTIMES, resolve_weights
        from ..models.streaks import check_streak_shift
        from ..models.two_view import check_phase_shift
        from ..models.weights import read_card

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
        return deflarer.streamer(sensor_size, phase_shift_us=p["phase_shift_us"])


@register_method("model", params=ModelParams)
def _make_model(**params: Any) -> Method:
    return ModelMethod(**param_values(ModelParams(**params)))
