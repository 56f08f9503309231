"""De-flaring event windows with a trained model: encode, restore, decode.

Each window ``[start, start + window)`` is encoded into a voxel grid, a batch
of grids goes through the network (on CUDA when present), and each restored
grid is decoded back to events with one of two decoders:

- ``"paper"``: round each cell, emit ``|n|`` events at uniform random times in
  the cell's bin (Appendix C; :func:`edeflare.voxel.decode`);
- ``"keep"``: keep the input's own events (with their real timestamps) where
  the restored grid keeps them and synthesise only what the grid adds
  (:func:`edeflare.voxel.decode_keep`).

Decoding draws come from a generator seeded by ``(seed, window start)``, so
the output does not depend on batching or on where a stream is resumed.

Mask models (:class:`~edeflare.models.flaremask.FlareMaskNet`, the ``mask.*``
presets) skip the full-resolution grid: their low-resolution features are
counted straight from the events and each input event is kept or dropped by
the mask at its own pixel, bin and polarity
(:func:`~edeflare.models.mask_kernels.event_keep_mask`); they add no events, so
both decoders give the same result.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np
import torch

from ..errors import EdeflareError
from ..events import (
    SensorSize,
    check_events,
    check_sensor_size,
    concat_events,
    make_events,
    select_events,
)
from ..lights.cells import covered_us
from ..methods.base import Streamer
from ..methods.windows import WindowStreamer
from ..rules import RULES, RuleSet, WindowContext
from ..rules.terms import RuleTerms, knob_sets, unit_shifts
from ..voxel import decode, decode_keep, encode
from . import create_model
from .event_features import window_features
from .event_head import (
    EventHead,
    EventHeadEnsemble,
    event_cells,
    gather_context,
    head_logits,
    head_logits_at_cells,
)
from .export import GRAPH_MASK, MaskOutputs, OnnxNetwork, onnx_bytes
from .flaremask import FlareMaskNet
from .mask_kernels import (
    event_features,
    event_keep_logits,
    event_records,
    keep_logit_threshold,
)
from .two_view import TwoViewStreamer, check_phase_shift, view_windows
from .weights import ModelCard, WeightsError, load_model

__all__ = [
    "DECODERS",
    "DEFAULT_MODEL",
    "RUNTIMES",
    "ModelDeflarer",
    "bundled_weights",
    "resolve_weights",
    "unlit_model_file",
]

DECODERS = ("keep", "paper")
RUNTIMES = ("auto", "torch", "onnx")

DEFAULT_MODEL = "night"
"""The bundled model used when none is named (``"default"`` is another name for it).

``night`` (a ``mask.pixel`` trained on the simulator calibrated on real night
recordings, ``assets/night.md``) removes the sparse flare real sensors record and
keeps the light, on a CPU at about the speed of the sensor. ``eflare`` (``assets/eflare.md``, the
default until 2026-11-25) is the voxel-to-voxel ``unet2d.lite`` trained on the
uncalibrated simulator: better on that simulator's own test sets, far worse on
real recordings and 20 times slower. ``paper`` (``assets/paper.md``) is the paper's
``unet3d.paper``, trained once on a GPU: it is the one that improves reconstructions on the
optics test set ``eflare-r-sim``, and it fails on real recordings too.
"""

_ASSETS = Path(__file__).resolve().parent.parent / "assets"


def bundled_weights(name: str = DEFAULT_MODEL) -> Path:
    """Path of a model shipped inside the package (``assets/<name>.safetensors``).

    Examples
    --------
    >>> bundled_weights().name, bundled_weights("default").name, bundled_weights("eflare").name
    ('night.safetensors', 'night.safetensors', 'eflare.safetensors')
    """
    if name == "default":
        name = DEFAULT_MODEL
    path = _ASSETS / f"{name}.safetensors"
    if not path.is_file():
        shipped = sorted(p.stem for p in _ASSETS.glob("*.safetensors")) if _ASSETS.is_dir() else []
        raise EdeflareError(
            f"no bundled model {name!r} (shipped: {shipped or 'none yet'}); pass weights of "
            "your own (--model PATH) or a baseline (--method efr, pfd-a, pfd-b, voxel)"
        )
    return path


def resolve_weights(weights: str | os.PathLike[str] | None) -> str | os.PathLike[str]:
    """The weights file meant by ``weights``: the default bundled model for None, a
    bundled model for a name without a suffix that is not a file, else the path itself.

    Examples
    --------
    >>> resolve_weights("night").name
    'night.safetensors'
    >>> resolve_weights("run/model.safetensors")
    'run/model.safetensors'
    """
    if weights is None:
        return bundled_weights()
    if not Path(weights).suffix and not Path(weights).exists():
        return bundled_weights(str(weights))
    return weights


def unlit_model_file(name: str, weights: str | os.PathLike[str]) -> str | os.PathLike[str]:
    """The weights file of a card's ``unlit_model`` ``name``: a bundled model's name, or a
    file named relative to the folder of the model ``weights`` whose card names it.

    Examples
    --------
    >>> unlit_model_file("learned", "runs/pair.safetensors").name
    'learned.safetensors'
    >>> unlit_model_file("lit.safetensors", "runs/pair.safetensors")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.models.weights.WeightsError: runs/pair.safetensors: its card's unlit_model 'lit...
    """
    if not Path(name).suffix:
        return bundled_weights(name)
    path = Path(weights).parent / name
    if not path.is_file():
        raise WeightsError(f"{weights}: its card's unlit_model {name!r} is not a file ({path})")
    return path


def _check_unlit(model: ModelDeflarer, unlit: ModelDeflarer) -> None:
    """Both experts must judge the same windows: mask models of one window length, the
    unlit one without an expert of its own."""
    where = f"{model.weights}: unlit_model {model.card.unlit_model!r}"
    if not isinstance(model.model, FlareMaskNet) or not isinstance(unlit.model, FlareMaskNet):
        raise WeightsError(f"{where}: both experts must be mask models (mask.* presets)")
    if unlit.card.unlit_model:
        raise WeightsError(f"{where} names an unlit_model of its own; one level only")
    if unlit.rules.active:
        on = sorted(k for k, v in unlit.card.rules.items() if v)
        raise WeightsError(
            f"{where} sets rule knobs {on}; the rules of a pair are its first card's"
        )
    if unlit.window_us != model.window_us:
        raise WeightsError(
            f"{where} has {unlit.window_us} us windows, this model {model.window_us} us"
        )


@contextlib.contextmanager
def _torch_threads(n: int) -> Iterator[None]:
    """Run torch with ``n`` intra-op threads inside the block (0: leave them as they are).

    A mask network is small (a few ms per window on one core), and each window's
    per-event numpy work runs between its calls: with a second torch thread
    spinning for work, the two fight over the cores (measured: the default model
    twice slower end to end on 2 cores, p95 latency 100 ms instead of 18 ms).
    """
    before = torch.get_num_threads()
    if n <= 0 or n == before:
        yield
        return
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@contextlib.contextmanager
def _full_precision(device: torch.device) -> Iterator[None]:
    """On CUDA, run float32 convolutions without TF32 and with deterministic kernels.

    By default cuDNN may run float32 convolutions in TF32 (a 10-bit mantissa) and
    pick its algorithms per shape and batch size. On an H200 the default model's logits
    then differed from the CPU's by up to 6e-3, 2-16 events of a recording changed side
    of the threshold, and a file streamed (other batch sizes) kept one event fewer than
    the same events in memory. Inside this block they agreed with the CPU on 7 of 8
    recordings and in all but 1 of 219,596 events on the 8th (the study ``gpu-default``,
    ``docs/studies.md``). The mask networks are small and their time goes elsewhere.
    The previous flags are restored on exit; elsewhere this does nothing.
    """
    if device.type != "cuda":
        yield
        return
    with torch.backends.cudnn.flags(
        enabled=torch.backends.cudnn.enabled, benchmark=False, deterministic=True, allow_tf32=False
    ):
        yield


def _onnx_installed() -> bool:
    """True where ONNX export and ONNX Runtime can both be imported."""
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in ("onnx", "onnxruntime"))


def _device(device: str) -> torch.device:
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(device)


def _warm_up_windows(
    sensor_size: tuple[int, int], window_us: int, n: int
) -> list[tuple[int, np.ndarray]]:
    """``n`` windows for :meth:`ModelDeflarer.warm_up`: the first a 12x12 block firing 20
    events per pixel (a light, where the sensor is that large) among 64 scattered events,
    the others scattered events alone, the last 65,536 of them (the kernels' counts are
    ``uint16`` below that many events, ``int32`` from it: both variants compile). Their
    fields are strided views, as a real window's are (numba compiles separately for the
    contiguous fields of one event)."""
    width, height = sensor_size
    rng = np.random.default_rng(0)

    def scatter(k: int) -> np.ndarray:
        return make_events(
            np.sort(rng.integers(0, window_us, k)), rng.integers(0, width, k),
            rng.integers(0, height, k), rng.integers(0, 2, k),
        )  # fmt: skip

    side = min(12, width, height)
    yy, xx = np.mgrid[:side, :side]
    k = 20 * side * side
    block = make_events(
        np.arange(k) * window_us // k, np.tile(xx.ravel(), 20), np.tile(yy.ravel(), 20),
        np.ones(k, np.int64),
    )  # fmt: skip
    out = []
    for i in range(n):
        if i == 0:
            ev = concat_events([scatter(64), block])
        else:
            ev = scatter(1 << 16 if i == n - 1 else 64)
        ev = ev[np.argsort(ev["t"], kind="stable")]
        ev["t"] += i * window_us
        out.append((i * window_us, ev))
    return out


class ModelDeflarer:
    """Apply a trained E-DeflareNet to event windows.

    Parameters
    ----------
    weights : path-like
        A ``.safetensors`` file written by :func:`edeflare.models.weights.save_model`,
        or an ``.onnx`` file written by :func:`edeflare.models.export.export_onnx`.
    decoder : {"keep", "paper"}
    device : str
        ``"auto"`` (CUDA if available), ``"cpu"``, ``"cuda:1"``...
    batch_windows : int
        Windows per forward pass.
    seed : int
        Seeds the decoding draws (with each window's start).
    runtime : {"auto", "torch", "onnx"}
        What runs the network: ``"auto"`` is ONNX Runtime for ``.onnx`` files
        and for mask models on CPU where ``onnx`` and ``onnxruntime`` are
        installed (``benchmarks/bench_realtime.py``: 1.1-1.8x faster end to
        end), torch otherwise; ``"onnx"`` on a ``.safetensors`` file exports
        the network (in memory, once per sensor size) and runs it with ONNX
        Runtime. Encoding and decoding are the same code for both.
    keep_threshold : float, optional
        Mask models: an event is kept where its keep probability exceeds this
        (default: the model card's, 1/2 unless the card says otherwise). Lower
        keeps more of the scene and of the flare.
    **rules
        Mask models: the rules' knobs (:mod:`edeflare.rules`: ``halo_shift``,
        ``ghost_shift``, ``streak_shift``, ``far_shift``, ``light_free_shift``,
        ``light_free_support``, ``light_free_crowding``, ``scatter_shift``), each
        shifting the keep logits of the events where its evidence holds. A knob not
        given (or None) takes the model card's value; the card's rules are off
        unless it says otherwise.

    Attributes
    ----------
    rules : RuleSet
        The rules' knob values in use (the card's, with the overrides).
    pixel_params : dict or None
        The per-pixel refinement's weights of a ``mask.pixel`` model
        (:meth:`~edeflare.models.flaremask.FlareMaskNet.pixel_params`; from the
        ONNX metadata for an ``.onnx`` file), applied per event after the network.
    head_params : dict or None
        The learned keep head of the card's ``head``
        (:meth:`~edeflare.models.event_head.EventHead.numpy_params`; from the ONNX
        metadata for an ``.onnx`` file): each event's keep logit from the network's
        logit and the window's evidence (:mod:`~edeflare.models.event_features`).

    On CPU a mask network runs on one thread (see ``_torch_threads``): it is small,
    and the per-event work between its calls uses the other cores.
    """

    def __init__(
        self,
        weights: str | os.PathLike[str],
        *,
        decoder: str = "keep",
        device: str = "auto",
        batch_windows: int = 4,
        seed: int = 0,
        runtime: str = "auto",
        keep_threshold: float | None = None,
        **rules: float | int | None,
    ) -> None:
        if decoder not in DECODERS:
            raise EdeflareError(f"decoder must be one of {DECODERS}, got {decoder!r}")
        if batch_windows < 1:
            raise EdeflareError(f"batch_windows must be at least 1, got {batch_windows}")
        if runtime not in RUNTIMES:
            raise EdeflareError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
        is_onnx = Path(weights).suffix.lower() == ".onnx"
        self.weights = weights
        if runtime == "torch" and is_onnx:
            raise EdeflareError(f"{weights}: an ONNX file runs with runtime 'onnx', not 'torch'")
        self.device = _device(device)
        self._onnx: dict[tuple[int, int], OnnxNetwork] = {}
        self._warm: set[tuple[int, int]] = set()
        if is_onnx:
            exported = OnnxNetwork(weights, device=str(self.device))
            if exported.graph == GRAPH_MASK and self.device.type == "cpu":  # see _torch_threads
                exported = OnnxNetwork(weights, device="cpu", threads=1)
            self._onnx[exported.sensor_size] = exported
            card = exported.card
            model = create_model(card.preset)  # the architecture only: its scale and bins
            self.pixel_params = exported.pixel_params
            if isinstance(model, FlareMaskNet) and model.pixel_hidden and not self.pixel_params:
                raise EdeflareError(
                    f"{weights}: a {card.preset} export without its pixel refinement; "
                    "export it again with this version"
                )
            self.head_params = exported.head_params
            if card.head and self.head_params is None:
                raise EdeflareError(
                    f"{weights}: an export without its keep head; export it again with this version"
                )
        else:
            model, card = load_model(weights, self.device)
            self.pixel_params = model.pixel_params() if isinstance(model, FlareMaskNet) else None
            head = getattr(model, "head", None)
            heads = (EventHead, EventHeadEnsemble)
            self.head_params = head.numpy_params() if isinstance(head, heads) else None
        if card.head and not isinstance(model, FlareMaskNet):
            raise EdeflareError(f"{weights}: a keep head needs a mask model, not a {card.preset}")
        self.model: torch.nn.Module = model
        self.card: ModelCard = card
        # the mask graph's outputs (logits, and a keep head's context maps after them)
        self._mask_outputs = MaskOutputs(model) if isinstance(model, FlareMaskNet) else None
        fast_onnx = runtime == "auto" and isinstance(model, FlareMaskNet) and _onnx_installed()
        self.runtime = (
            "onnx"
            if is_onnx or runtime == "onnx" or (fast_onnx and self.device.type == "cpu")
            else "torch"
        )
        self._exported_only = is_onnx
        threshold = card.keep_threshold if keep_threshold is None else keep_threshold
        self.keep_threshold = float(threshold)
        if not 0.0 < self.keep_threshold < 1.0:
            raise EdeflareError(f"keep_threshold must be in (0, 1), got {self.keep_threshold}")
        self.rules = RuleSet({**card.rules, **{k: v for k, v in rules.items() if v is not None}})
        for rule in RULES.values():
            params = self.rules.params[rule.name]
            if rule.active(params) and not isinstance(model, FlareMaskNet):
                knob = next(k for k, v in vars(params).items() if v)
                raise EdeflareError(
                    f"{weights}: {knob} needs a mask model, not a {card.preset} (voxel-to-voxel)"
                )
        self.decoder = decoder
        self.batch_windows = int(batch_windows)
        self.seed = int(seed)
        self.unlit: ModelDeflarer | None = None
        """The card's ``unlit_model``: the expert for windows without a found light."""
        self._unlit_shift = 0.0
        if card.unlit_model:
            self.unlit = ModelDeflarer(
                unlit_model_file(card.unlit_model, weights),
                decoder=decoder,
                device=str(self.device),
                batch_windows=batch_windows,
                seed=seed,
                runtime="onnx" if self.runtime == "onnx" else "torch",
            )
            _check_unlit(self, self.unlit)
            # its logits moved so that this card's keep threshold is its own card's
            self._unlit_shift = keep_logit_threshold(card.keep_threshold) - keep_logit_threshold(
                self.unlit.card.keep_threshold
            )

    @property
    def window_us(self) -> int:
        """Window length the model was trained on (µs)."""
        return self.card.window_us

    def _onnx_network(self, sensor_size: SensorSize) -> OnnxNetwork:
        size = (int(sensor_size[0]), int(sensor_size[1]))
        if size not in self._onnx:
            if self._exported_only:  # an .onnx file: made for one sensor size
                next(iter(self._onnx.values())).require_sensor_size(size)
            one = isinstance(self.model, FlareMaskNet) and self.device.type == "cpu"
            self._onnx[size] = OnnxNetwork(
                onnx_bytes(self.model.cpu(), self.card, size),
                device=str(self.device),
                threads=1 if one else None,  # see _torch_threads
            )
        return self._onnx[size]

    def _network(self, x: np.ndarray, sensor_size: SensorSize, mask: bool) -> np.ndarray:
        """The network's output for a float32 batch: logits (mask) or restored grids."""
        if self.runtime == "onnx":
            return self._onnx_network(sensor_size)(x)
        threads = 1 if mask and self.device.type == "cpu" else 0
        with torch.inference_mode(), _torch_threads(threads), _full_precision(self.device):
            t = torch.from_numpy(x).to(self.device)
            y = self._mask_outputs(t) if mask else self.model(t)
            return y.float().cpu().numpy()

    def network_output(
        self, events: np.ndarray, sensor_size: SensorSize, start_us: int
    ) -> np.ndarray:
        """The network's output for one window: mask logits ``(2 bins, h, w)`` of a mask
        model, the restored grid ``(bins, H, W)`` of a voxel model."""
        check_events(events, sensor_size)
        if isinstance(self.model, FlareMaskNet):
            net = self.model
            x = event_features(events, sensor_size, start_us, self.window_us, net.bins, net.scale)
            return self._network(x[None], sensor_size, True)[0]
        grid = encode(events, sensor_size, start_us, self.window_us, self.card.bins)
        return self._restore([grid], sensor_size)[0]

    def _restore(self, grids: list[np.ndarray], sensor_size: SensorSize) -> list[np.ndarray]:
        y = self._network(np.stack(grids)[:, None].astype(np.float32), sensor_size, False)
        return list(y[:, 0])

    def _decode(self, grid: np.ndarray, events: np.ndarray, start: int) -> np.ndarray:
        rng = np.random.default_rng((self.seed, int(start)))
        if self.decoder == "keep":
            return decode_keep(grid, events, start, self.window_us, rng)
        return decode(grid, start, self.window_us, rng)

    def windows(
        self,
        windows: Iterable[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        *,
        span_us: tuple[int | None, int | None] | None = None,
    ) -> Iterator[tuple[int, np.ndarray]]:
        """De-flare ``(window_start_us, events)`` pairs, in order, batching the network calls.

        ``span_us = (first, end)`` is the recording's time span (either side
        may be None: open): the network sees empty bins before the first event
        of a recording or after its end and may fill them, but the sensor
        recorded nothing there, so no event is synthesised outside the span
        (the cells of bins outside it are left as the input has them, and added
        events outside it are dropped).

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from edeflare.models import create_model
        >>> from edeflare.models.weights import ModelCard, save_model
        >>> from edeflare.events import make_events
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "m.safetensors"
        >>> save_model(p, create_model("unet2d.lite"), ModelCard(preset="unet2d.lite"))
        >>> ev = make_events([10, 30_000], [1, 2], [1, 2], [1, 0])
        >>> out = ModelDeflarer(p).windows([(0, ev[:1]), (20_000, ev[1:])], (4, 4))
        >>> [(s, e["t"].tolist()) for s, e in out]   # an untrained model is the identity
        [(0, [10]), (20000, [30000])]
        """
        lo, hi = span_us if span_us is not None else (None, None)
        batch: list[tuple[int, np.ndarray]] = []
        for start, events in windows:
            check_events(events, sensor_size)
            if events.size and (
                events["t"][0] < start or events["t"][-1] >= start + self.window_us
            ):
                raise EdeflareError(
                    f"the window starting at {start} us holds events from {events['t'][0]} to "
                    f"{events['t'][-1]} us, outside [{start}, {start + self.window_us}) (the "
                    f"model's window is {self.window_us} us)"
                )
            batch.append((int(start), events))
            if len(batch) == self.batch_windows:
                yield from self._run(batch, sensor_size, lo, hi)
                batch = []
        if batch:
            yield from self._run(batch, sensor_size, lo, hi)

    def window_logits(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        *,
        cells: list[np.ndarray] | None = None,
    ) -> list[np.ndarray]:
        """A mask model's per-event keep logits for ``(window_start_us, events)`` windows.

        One network call for the batch; windows may start anywhere (aligned or
        not). An event is kept where its logit exceeds
        :func:`~edeflare.models.mask_kernels.keep_logit_threshold` of
        :attr:`keep_threshold`. ``cells``, a list, receives each window's cells as a
        keep head's context reads them: the network's inputs and its keep logits
        ``(4 bins + 1, h, w)``.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> from edeflare.models import create_model
        >>> from edeflare.models.weights import ModelCard, save_model
        >>> from edeflare.events import make_events
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "m.safetensors"
        >>> save_model(p, create_model("mask.lite"), ModelCard(preset="mask.lite"))
        >>> ev = make_events([10, 30], [1, 2], [1, 2], [1, 0])
        >>> d = ModelDeflarer(p)
        >>> [v.tolist() for v in d.window_logits([(0, ev[:1]), (5, ev[1:])], (8, 8))]
        [[0.0], [0.0]]
        >>> keep_logit_threshold(d.keep_threshold) < 0.0  # untrained: keeps everything
        True
        """
        return self._keep_logits(batch, sensor_size, cells)[0]

    def _keep_logits(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        cells: list[np.ndarray] | None = None,
        *,
        rules: bool = True,
        support: bool = False,
    ) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
        """:meth:`window_logits`' logits (the rules' shifts added only where ``rules``),
        and each window's 5x5 support where the rules, a head or ``support`` ask for it.
        With an ``unlit`` expert, the windows where the light test finds no light are its
        (its logits shifted onto this card's keep threshold), the others this model's, and
        this card's rules act on both."""
        w = self.window_us
        # one context per window (the lights found once): the gate, the head and the rules
        contexts = [WindowContext(ev, sensor_size, covered_us(ev, s, w)) for s, ev in batch]
        if self.unlit is None:
            return self._own_keep_logits(
                batch, sensor_size, contexts, cells, rules=rules, support=support
            )
        apply = rules and self.rules.active
        need = support or (apply and self.rules.needs_support)
        logits: list[np.ndarray] = [np.empty(0, np.float32)] * len(batch)
        supports: list[np.ndarray | None] = [None] * len(batch)
        window_cells: list[np.ndarray] = [np.empty(0, np.float32)] * len(batch)
        for expert, found in ((self, True), (self.unlit, False)):
            idx = [k for k, ctx in enumerate(contexts) if ctx.has_lights == found]
            if not idx:
                continue
            got: list[np.ndarray] | None = [] if cells is not None else None
            out, sups = expert._own_keep_logits(
                [batch[k] for k in idx], sensor_size, [contexts[k] for k in idx], got,
                rules=False, support=need,
            )  # fmt: skip
            shift = np.float32(0.0 if expert is self else self._unlit_shift)
            for j, k in enumerate(idx):
                logits[k] = out[j] + shift if shift else out[j]
                supports[k] = sups[j]
                if got is not None:
                    window_cells[k] = got[j]
        if cells is not None:
            cells.extend(window_cells)
        if apply:  # this card's rules (and their overrides) over both experts' windows
            for v, ctx in zip(logits, contexts, strict=True):
                self.rules.apply(v, ctx)
        return logits, supports

    def _own_keep_logits(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        contexts: list[WindowContext],
        cells: list[np.ndarray] | None = None,
        *,
        rules: bool = True,
        support: bool = False,
    ) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
        """:meth:`_keep_logits` of this model's own network, head and rules; ``contexts``
        are the windows' (their support is set here, once the network has counted it)."""
        head = self.head_params
        apply = rules and self.rules.active
        need = support or (apply and self.rules.needs_support) or head is not None
        out, supports, maps = self._network_logits(batch, sensor_size, need, cells)
        if not apply and head is None:
            return out, supports
        for k, (v, sup, ctx) in enumerate(zip(out, supports, contexts, strict=True)):
            ctx.support = sup
            if head is not None:
                v = out[k] = self._head_logits(ctx, v, None if maps is None else maps[k])
            if apply:
                self.rules.apply(v, ctx)
        return out, supports

    def _head_logits(
        self, ctx: WindowContext, logits: np.ndarray, maps: np.ndarray | None
    ) -> np.ndarray:
        """A window's keep head logits: :func:`head_logits` of :meth:`_head_columns`, the
        context's share of the first layer computed per cell, not per event."""
        names = self.head_params["features"]
        features = window_features(ctx, logits, names, window_us=self.window_us)
        if maps is None:
            return head_logits(self.head_params, features)
        cells = event_cells(ctx.events, self.model.scale, maps.shape[-1])
        return head_logits_at_cells(self.head_params, features, maps, cells)

    def _head_columns(
        self, ctx: WindowContext, logits: np.ndarray, maps: np.ndarray | None
    ) -> np.ndarray:
        """A window's keep head inputs: its features, then its context maps' columns."""
        names = self.head_params["features"]
        features = window_features(ctx, logits, names, window_us=self.window_us)
        if maps is None:
            return features
        return np.hstack([features, gather_context(maps, ctx.events, self.model.scale)])

    def head_inputs(
        self, batch: list[tuple[int, np.ndarray]], sensor_size: SensorSize
    ) -> list[np.ndarray]:
        """What the keep head reads of each event of ``(window_start_us, events)``
        windows: ``(n, columns)`` float32 per window, its features
        (:func:`~edeflare.models.event_features.window_features`) then, with a context,
        each member's context columns; ``head_logits(self.head_params, x)`` of them is
        :meth:`window_logits` without rules. For fitting a head to other data.

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> d = ModelDeflarer(bundled_weights("learned-absolute"), runtime="torch")
        >>> ev = make_events([10, 30, 50], [1, 2, 3], [1, 2, 3], [1, 0, 1])
        >>> (x,) = d.head_inputs([(0, ev)], (64, 64))
        >>> x.shape                      # 21 features and three members' 8 context maps
        (3, 45)
        """
        if self.head_params is None:
            raise EdeflareError(f"{self.weights}: no keep head to read inputs for")
        if self.unlit is not None:
            raise EdeflareError(
                f"{self.weights}: two experts (unlit_model {self.card.unlit_model!r}); "
                "read each one's head inputs apart"
            )
        out, supports, maps = self._network_logits(batch, sensor_size, True)
        w = self.window_us
        return [
            self._head_columns(
                WindowContext(ev, sensor_size, covered_us(ev, start, w), sup),
                v, None if maps is None else maps[k],
            )
            for k, ((start, ev), v, sup) in enumerate(zip(batch, out, supports, strict=True))
        ]  # fmt: skip

    def rule_terms(
        self,
        events: np.ndarray,
        sensor_size: SensorSize,
        delays_us: Sequence[int] | None = None,
    ) -> RuleTerms:
        """A stream's keep logits split into the model's with every rule off (its
        network's, or its keep head's) and each rule knob's term
        (:mod:`edeflare.rules.terms`), in windowings delayed by ``delays_us`` (default: the
        model's two views, 0 and its phase shift).

        ``terms.logits(knobs, views=(0, 1)) > keep_logit_threshold(t)`` is what this
        model keeps with those knobs and keep threshold ``t`` (its own up to float
        rounding): a search over the knobs runs the network once.

        Examples
        --------
        >>> from edeflare.events import make_events
        >>> d = ModelDeflarer(bundled_weights("night"))
        >>> ev = make_events([10, 30, 50], [1, 2, 3], [1, 2, 3], [1, 0, 1])
        >>> terms = d.rule_terms(ev, (16, 16))
        >>> terms.delays_us, terms.base.shape, terms.units[("halo_shift",)]["halo_shift"].shape
        ((0, 5000), (2, 3), (2, 3))
        """
        size = check_sensor_size(sensor_size)
        check_events(events, size)
        w = self.window_us
        if delays_us is None:
            delays_us = (0, check_phase_shift(None, self.card, self.weights))
        delays = tuple(int(d) for d in delays_us)
        base = np.zeros((len(delays), events.size), np.float32)
        units = {on: {name: np.zeros_like(base) for name in on} for on in knob_sets()}
        t = np.ascontiguousarray(events["t"]).astype(np.int64)
        for v, delay in enumerate(delays):
            for start, i, k in view_windows(t, w, delay):  # TwoViewStreamer's windows
                part = events[i:k]
                (logit,), (support,) = self._keep_logits(
                    [(start, part)], size, rules=False, support=True
                )
                base[v, i:k] = logit
                ctx = WindowContext(part, size, covered_us(part, start, w), support)
                for on, per_knob in unit_shifts(self.rules, ctx).items():
                    for name, unit in per_knob.items():
                        units[on][name][v, i:k] = unit
        return RuleTerms(delays, base, units)

    def _network_logits(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        support: bool,
        cells: list[np.ndarray] | None = None,
    ) -> tuple[list[np.ndarray], list[np.ndarray | None], np.ndarray | None]:
        """The network's per-event keep logits of the windows (no rule, no head), each
        event's 5x5 support where asked (free with the refinement's counts), and a head's
        context maps (None without one). ``cells`` receives each window's cells."""
        net = self.model
        if not isinstance(net, FlareMaskNet):
            raise EdeflareError("per-event keep logits need a mask model (a mask.* preset)")
        w, scale = self.window_us, net.scale
        # each window's events sorted once for both kernels
        records = [event_records(ev, s, w, net.bins, sensor_size) for s, ev in batch]
        feats = np.stack(
            [
                event_features(ev, sensor_size, s, w, net.bins, scale, records=r)
                for (s, ev), r in zip(batch, records, strict=True)
            ]
        )
        logits = self._network(feats, sensor_size, True)
        head = self.head_params
        # a head's context maps follow the logits in the network's output
        maps = logits[:, 2 * net.bins :] if head is not None and head["context"] else None
        logits = logits[:, : 2 * net.bins]
        if cells is not None:
            cells.extend(np.concatenate([feats, logits], 1))
        supports = [np.empty(ev.size, np.int64) if support else None for _, ev in batch]
        out = [
            event_keep_logits(
                lg, events, start, w, scale, pixel_params=self.pixel_params,
                sensor_size=sensor_size, support=sup, records=r,
            )
            for (start, events), lg, sup, r in zip(batch, logits, supports, records, strict=True)
        ]  # fmt: skip
        return out, supports, maps

    def _run_mask(
        self, batch: list[tuple[int, np.ndarray]], sensor_size: SensorSize
    ) -> Iterator[tuple[int, np.ndarray]]:
        cut = keep_logit_threshold(self.keep_threshold)
        for (start, events), v in zip(batch, self.window_logits(batch, sensor_size), strict=True):
            yield start, select_events(events, v > cut)

    def _run(
        self,
        batch: list[tuple[int, np.ndarray]],
        sensor_size: SensorSize,
        lo: int | None,
        hi: int | None,
    ) -> Iterator[tuple[int, np.ndarray]]:
        if isinstance(self.model, FlareMaskNet):
            yield from self._run_mask(batch, sensor_size)
            return
        bins, w = self.card.bins, self.window_us
        grids = [encode(ev, sensor_size, s, w, bins) for s, ev in batch]
        for (start, events), grid, restored in zip(
            batch, grids, self._restore(grids, sensor_size), strict=True
        ):
            # bin b covers [start + ceil(b w / bins), start + ceil((b + 1) w / bins))
            edges = start + -(-np.arange(bins + 1) * w // bins)
            outside = np.zeros(bins, dtype=bool)
            if lo is not None:
                outside |= edges[1:] <= lo
            if hi is not None:
                outside |= edges[:-1] >= hi
            if outside.any():
                restored[outside] = grid[outside]
            out = self._decode(restored, events, start)
            if (lo is not None and start < lo) or (hi is not None and start + w > hi):
                t = out["t"]
                inside = (t >= (start if lo is None else lo)) & (
                    t < (start + w if hi is None else hi)
                )
                out = out[inside]
            yield start, out

    def warm_up(self, sensor_size: SensorSize) -> None:
        """Run small windows through the whole path, so the first real one does not pay
        for loading compiled kernels and preparing the network's layers for this shape
        (about 0.5 s on CPU): start-up, not latency. Once per sensor size.

        The windows are :func:`_warm_up_windows`: one with a light and one without, so
        the rules of both kinds of window load theirs too.
        """
        size = (int(sensor_size[0]), int(sensor_size[1]))
        if size in self._warm:
            return
        n = max(2, self.batch_windows)
        for _ in self.windows(_warm_up_windows(size, self.window_us, n), sensor_size):
            pass
        self._warm.add(size)

    def streamer(self, sensor_size: SensorSize, *, phase_shift_us: int | None = None) -> Streamer:
        """This model's state over one stream (see :class:`edeflare.methods.Streamer`).

        A mask model judges each event in two windowings (aligned, and delayed
        by ``phase_shift_us``; default a quarter of its window) and keeps it
        where the mean of its two keep logits passes
        (:class:`~edeflare.models.two_view.TwoViewStreamer`); ``0`` keeps one
        windowing. Voxel-to-voxel models use one windowing.
        """
        shift = check_phase_shift(phase_shift_us, self.card, self.weights)
        size = check_sensor_size(sensor_size)
        self.warm_up(size)
        if shift:
            streamer = TwoViewStreamer(
                self.window_us,
                shift,
                lambda batch: self.window_logits(batch, size),
                keep_logit_threshold(self.keep_threshold),
                self.batch_windows,
            )
            warm = _warm_up_windows(size, self.window_us, 2)
            streamer.warm_up(lambda: self.window_logits(warm, size))
            return streamer

        def transform(
            batch: list[tuple[int, np.ndarray]], span: tuple[int, int | None]
        ) -> list[np.ndarray]:
            return [ev for _, ev in self.windows(batch, size, span_us=span)]

        return WindowStreamer(self.window_us, transform)

    def __call__(
        self, events: np.ndarray, sensor_size: SensorSize, *, phase_shift_us: int | None = None
    ) -> np.ndarray:
        """De-flare a whole stream in memory: the same result as
        ``edeflare.deflare(events, sensor_size, "model", weights=...)``."""
        check_events(events, sensor_size)
        streamer = self.streamer(sensor_size, phase_shift_us=phase_shift_us)
        until = int(events["t"][-1]) + 1 if events.size else 0
        return concat_events([streamer.process(events, until), streamer.flush()])
