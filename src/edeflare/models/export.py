"""ONNX export of a trained model, and running the exported graph with ONNX Runtime.

What is exported is the network only, the part that runs on tensors; encoding
events into the network's input and deciding events from its output stay in
:class:`~edeflare.models.infer.ModelDeflarer`, identical for both runtimes.

- Mask models (``mask.*``): the graph ``features -> logits`` of
  :meth:`~edeflare.models.flaremask.FlareMaskNet.logits`: input ``features``
  ``(N, 2 bins + 1, ceil(H / scale), ceil(W / scale))`` float32, output
  ``logits`` ``(N, 2 bins, ...)``.
- Voxel models (``unet2d.*``, ``unet3d.*``): the whole forward pass, input
  ``voxels`` ``(N, 1, bins, H, W)`` float32, output ``restored`` of the same shape.

A graph is exported for one sensor size (the U-Nets pad to a multiple of their
depth, which the tracer fixes) with a free batch size. The file's metadata
holds the model card (``edeflare_card``, as in the safetensors file), the graph
kind (``edeflare_graph``) and the sensor size (``edeflare_sensor_size``), so an
exported file is self-describing: ``edeflare deflare --model model.onnx`` runs
it. The ``onnx`` extra (``pip install 'edeflare[onnx]'``) provides ``onnx``
(export) and ``onnxruntime`` (running).

Examples
--------
>>> import tempfile, pathlib
>>> from edeflare.models import create_model
>>> from edeflare.models.weights import ModelCard, save_model
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> save_model(folder / "m.safetensors", create_model("mask.fast"), ModelCard(preset="mask.fast"))
>>> card = export_onnx(folder / "m.safetensors", folder / "m.onnx", (64, 48))
>>> net = OnnxNetwork(folder / "m.onnx")
>>> net.graph, net.sensor_size, net.input_shape(2)
('mask_logits', (64, 48), (2, 17, 6, 8))
"""

from __future__ import annotations

import collections
import dataclasses
import hashlib
import io
import json
import os
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from ..errors import DependencyError, EdeflareError
from ..events import SensorSize, check_sensor_size
from ..io._atomic import atomic_path
from .event_features import check_feature_names
from .flaremask import FlareMaskNet
from .weights import ModelCard, WeightsError, load_model

__all__ = [
    "DEFAULT_OPSET",
    "GRAPH_MASK",
    "GRAPH_VOXEL",
    "OnnxNetwork",
    "Parity",
    "export_onnx",
    "onnx_bytes",
    "onnx_parity",
    "read_onnx_card",
]

GRAPH_MASK = "mask_logits"
GRAPH_VOXEL = "voxel"
DEFAULT_OPSET = 17

_CARD_KEY = "edeflare_card"
_GRAPH_KEY = "edeflare_graph"
_PIXEL_KEY = "edeflare_pixel_refinement"  # mask.pixel: the per-event refinement's weights
_HEAD_KEY = "edeflare_keep_head"  # a learned keep head's weights (models.event_head)
_SIZE_KEY = "edeflare_sensor_size"


def _need(module: str) -> Any:
    try:
        return __import__(module)
    except ImportError:
        raise DependencyError(
            f"ONNX needs the {module!r} package: pip install 'edeflare[onnx]'"
        ) from None


class MaskOutputs(nn.Module):
    """A mask network's graph: its keep logits ``(N, 2 bins, h, w)`` of cell features and,
    where its keep head has a context, the context's maps after them (``(N, 2 bins + k,
    h, w)``; the context reads the features and the logits)."""

    def __init__(self, net: FlareMaskNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        logits = self.net.logits(features)
        head = getattr(self.net, "head", None)
        if head is None or not head.context:
            return logits
        return torch.cat([logits, head.context_maps(torch.cat([features, logits], 1))], 1)


def _example_input(model: nn.Module, card: ModelCard, size: SensorSize) -> tuple[str, torch.Tensor]:
    width, height = size
    if isinstance(model, FlareMaskNet):
        s = model.scale
        h, w = -(-height // s), -(-width // s)
        return GRAPH_MASK, torch.zeros(1, 2 * model.bins + 1, h, w)
    return GRAPH_VOXEL, torch.zeros(1, 1, card.bins, height, width)


_EXPORTED: collections.OrderedDict[tuple[str, tuple[int, int], int], bytes] = (
    collections.OrderedDict()
)
"""The graphs :func:`onnx_bytes` made in this process, by the model's digest, the sensor
size and the opset, the latest last: exporting takes 0.3-0.5 s, more than the network
takes for a second of a night recording, and ``edeflare score --phases 4``, the
benchmarks and every new :class:`~edeflare.models.infer.ModelDeflarer` of the same
weights ask for the same graph again."""

_EXPORTED_MAX = 8


def _digest(model: nn.Module, card: ModelCard) -> str:
    """What the exported graph depends on: every tensor of the model, and its card."""
    h = hashlib.sha256(json.dumps(card.to_dict(), sort_keys=True).encode())
    for name, tensor in model.state_dict().items():
        h.update(name.encode())
        h.update(str(tuple(tensor.shape)).encode() + str(tensor.dtype).encode())
        h.update(tensor.detach().cpu().reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()


def onnx_bytes(
    model: nn.Module, card: ModelCard, sensor_size: SensorSize, *, opset: int = DEFAULT_OPSET
) -> bytes:
    """The ONNX file of ``model`` for ``sensor_size``, with its metadata, as bytes.

    Made once per process for the same model (its tensors and card), size and opset,
    then taken from a cache of the last :data:`_EXPORTED_MAX`.
    """
    size = check_sensor_size(sensor_size)
    key = (_digest(model, card), (int(size[0]), int(size[1])), int(opset))
    if key in _EXPORTED:
        _EXPORTED.move_to_end(key)
        return _EXPORTED[key]
    out = _export(model, card, size, opset)
    _EXPORTED[key] = out
    while len(_EXPORTED) > _EXPORTED_MAX:
        _EXPORTED.popitem(last=False)
    return out


def _export(model: nn.Module, card: ModelCard, size: SensorSize, opset: int) -> bytes:
    onnx = _need("onnx")
    graph, example = _example_input(model, card, size)
    module = MaskOutputs(model) if graph == GRAPH_MASK else model
    names = ("features", "logits") if graph == GRAPH_MASK else ("voxels", "restored")
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        # The TorchScript exporter is the one that needs no extra package
        # (onnxscript); it warns that it is legacy and that the U-Net's padding
        # becomes a constant, which is why a graph is made for one sensor size.
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        torch.onnx.export(
            module.eval(),
            (example,),
            buffer,
            input_names=[names[0]],
            output_names=[names[1]],
            dynamic_axes={names[0]: {0: "batch"}, names[1]: {0: "batch"}},
            opset_version=int(opset),
            dynamo=False,
        )
    proto = onnx.load_from_string(buffer.getvalue())
    meta = [
        (_CARD_KEY, json.dumps(card.to_dict())),
        (_GRAPH_KEY, graph),
        (_SIZE_KEY, json.dumps(list(size))),
    ]
    params = model.pixel_params() if isinstance(model, FlareMaskNet) else None
    if params is not None:  # applied per event after the graph (mask_kernels.event_keep_mask)
        meta.append((_PIXEL_KEY, json.dumps({k: v.tolist() for k, v in params.items()})))
    head = getattr(model, "head", None)
    if head is not None:  # applied per event after the graph, as in ModelDeflarer
        meta.append((_HEAD_KEY, json.dumps(_head_lists(head.numpy_params()))))
    for key, value in meta:
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    proto.producer_name = "edeflare"
    return proto.SerializeToString()


def export_onnx(
    weights: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    sensor_size: SensorSize,
    *,
    opset: int = DEFAULT_OPSET,
) -> ModelCard:
    """Write the network of a weights file as ONNX for one sensor size, atomically.

    Parameters
    ----------
    weights : path-like
        A ``.safetensors`` file of :func:`~edeflare.models.weights.save_model`.
    out_path : path-like
        The ``.onnx`` file to write.
    sensor_size : (width, height)
        The sensor the graph is made for.
    opset : int
        ONNX operator set.

    Returns
    -------
    ModelCard
        The model's card (also stored in the file's metadata).
    """
    model, card = load_model(weights, "cpu")
    data = onnx_bytes(model, card, sensor_size, opset=opset)
    with atomic_path(Path(out_path)) as tmp:
        Path(tmp).write_bytes(data)
    return card


def _metadata(session: Any, source: str) -> tuple[ModelCard, str, SensorSize]:
    meta = session.get_modelmeta().custom_metadata_map
    missing = [k for k in (_CARD_KEY, _GRAPH_KEY, _SIZE_KEY) if k not in meta]
    if missing:
        raise WeightsError(
            f"{source}: not an edeflare ONNX export (metadata lacks {missing}); "
            "write one with `edeflare export`"
        )
    try:
        card = ModelCard.from_dict(json.loads(meta[_CARD_KEY]))
        width, height = json.loads(meta[_SIZE_KEY])
    except (json.JSONDecodeError, TypeError, ValueError) as exc:
        raise WeightsError(f"{source}: unreadable edeflare metadata ({exc})") from None
    graph = meta[_GRAPH_KEY]
    if graph not in (GRAPH_MASK, GRAPH_VOXEL):
        raise WeightsError(f"{source}: unknown graph kind {graph!r}")
    return card, graph, (int(width), int(height))


class OnnxNetwork:
    """An exported network run by ONNX Runtime: numpy in, numpy out.

    Parameters
    ----------
    model : path-like or bytes
        An ``.onnx`` file written by :func:`export_onnx`, or its bytes.
    device : str
        ``"cpu"``, or ``"cuda"`` / ``"auto"`` to use ONNX Runtime's CUDA
        provider when it is installed.
    threads : int, optional
        Intra-op threads (ONNX Runtime's default: one per core).
    """

    def __init__(
        self,
        model: str | os.PathLike[str] | bytes,
        *,
        device: str = "cpu",
        threads: int | None = None,
    ) -> None:
        ort = _need("onnxruntime")
        source = "<in memory>" if isinstance(model, bytes) else str(model)
        if not isinstance(model, bytes) and not Path(model).is_file():
            raise WeightsError(f"{source}: no such ONNX file")
        options = ort.SessionOptions()
        options.log_severity_level = 3
        if threads is not None:
            options.intra_op_num_threads = int(threads)
        providers = ["CPUExecutionProvider"]
        if device != "cpu" and "CUDAExecutionProvider" in ort.get_available_providers():
            providers.insert(0, "CUDAExecutionProvider")
        try:
            payload = model if isinstance(model, bytes) else str(model)
            self.session = ort.InferenceSession(payload, options, providers=providers)
        except Exception as exc:  # onnxruntime raises its own Fail/InvalidGraph classes
            raise WeightsError(f"{source}: not a loadable ONNX model ({exc})") from None
        self.card, self.graph, self.sensor_size = _metadata(self.session, source)
        self.pixel_params = _pixel_params(self.session, source)
        self.head_params = _head_params(self.session, source)
        self.input_name = self.session.get_inputs()[0].name
        self._shape = tuple(self.session.get_inputs()[0].shape[1:])
        self.source = source

    def input_shape(self, batch: int) -> tuple[int, ...]:
        """The input shape for ``batch`` windows."""
        return (int(batch), *(int(d) for d in self._shape))

    def require_sensor_size(self, sensor_size: SensorSize) -> None:
        """Raise unless the graph was exported for ``sensor_size``."""
        if tuple(sensor_size) != self.sensor_size:
            w, h = self.sensor_size
            raise EdeflareError(
                f"{self.source}: exported for a {w}x{h} sensor, the recording is "
                f"{sensor_size[0]}x{sensor_size[1]}; export it again with "
                f"--sensor-size {sensor_size[0]}x{sensor_size[1]}"
            )

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Run the graph on a float32 batch."""
        x = np.ascontiguousarray(x, dtype=np.float32)
        if x.shape[1:] != self._shape:
            raise EdeflareError(
                f"{self.source}: input of shape {x.shape[1:]} per window, the graph takes "
                f"{self._shape}"
            )
        return self.session.run(None, {self.input_name: x})[0]


def _pixel_params(session: Any, source: str) -> dict[str, np.ndarray] | None:
    """The per-pixel refinement's weights stored beside the graph (None: it has none)."""
    text = session.get_modelmeta().custom_metadata_map.get(_PIXEL_KEY)
    if text is None:
        return None
    try:
        return {k: np.asarray(v, dtype=np.float64) for k, v in json.loads(text).items()}
    except (ValueError, TypeError, AttributeError) as exc:
        raise WeightsError(f"{source}: unreadable pixel refinement metadata ({exc})") from None


def _head_lists(p: Mapping[str, Any]) -> dict[str, Any]:
    """A head's :meth:`~edeflare.models.event_head.EventHead.numpy_params` as JSON lists
    (an ensemble's with its ``members``')."""
    out: dict[str, Any] = {"features": list(p["features"]), "context": int(p["context"])}
    if "members" in p:
        out["members"] = [_head_lists(m) for m in p["members"]]
    else:
        out["weights"] = [w.tolist() for w in p["weights"]]
        out["biases"] = [b.tolist() for b in p["biases"]]
    return out


def _head_params(session: Any, source: str) -> dict[str, Any] | None:
    """The learned keep head's weights stored beside the graph (None: it has none)."""
    text = session.get_modelmeta().custom_metadata_map.get(_HEAD_KEY)
    if text is None:
        return None
    try:
        return _head_arrays(json.loads(text), f"{source}: keep head")
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        raise WeightsError(f"{source}: unreadable keep head metadata ({exc})") from None


def _head_arrays(raw: Mapping[str, Any], where: str) -> dict[str, Any]:
    """:func:`_head_lists`' inverse, checked (``ValueError`` and kin where malformed)."""
    context = raw.get("context", 0)
    if isinstance(context, bool) or not isinstance(context, int) or context < 0:
        raise ValueError(f"context channels {context!r}")
    features = check_feature_names(raw["features"], where)
    if "members" in raw:
        members = [_head_arrays(m, where) for m in raw["members"]]
        if len(members) < 2 or sum(m["context"] for m in members) != context:
            raise ValueError(f"{len(members)} members for {context} context channels")
        return {"features": features, "context": context, "members": members}
    return {
        "features": features,
        "context": context,
        "weights": [np.asarray(w, dtype=np.float32) for w in raw["weights"]],
        "biases": [np.asarray(b, dtype=np.float32) for b in raw["biases"]],
    }


def read_onnx_card(path: str | os.PathLike[str]) -> ModelCard:
    """The model card stored in an exported ``.onnx`` file."""
    return OnnxNetwork(path).card


@dataclasses.dataclass(frozen=True)
class Parity:
    """How closely an exported graph follows torch on the same windows.

    ``decisions`` are what the output is made of: per event keep / drop for a
    mask model; per voxel cell the rounded event count for a voxel model (a
    cell rounded differently changes the events decoded from it).
    """

    windows: int
    max_abs_diff: float
    max_abs_value: float
    decisions: int
    decisions_differing: int
    unit: str

    def __str__(self) -> str:
        return (
            f"{self.windows} windows: max |onnx - torch| = {self.max_abs_diff:.3g} "
            f"(outputs up to {self.max_abs_value:.3g}); {self.decisions_differing:,} of "
            f"{self.decisions:,} {self.unit} decisions differ"
        )


def onnx_parity(
    weights: str | os.PathLike[str],
    exported: str | os.PathLike[str],
    windows: Iterable[tuple[int, np.ndarray]],
    sensor_size: SensorSize,
) -> Parity:
    """Compare an exported graph with the torch model of its weights on event windows.

    The network's outputs (mask logits or restored grids) are compared
    element by element, and the decisions made from them: which events a
    mask model keeps, or each cell's rounded count for a voxel model.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.models import create_model
    >>> from edeflare.models.weights import ModelCard, save_model
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> net = create_model("mask.fast")
    >>> save_model(folder / "m.safetensors", net, ModelCard(preset="mask.fast"))
    >>> _ = export_onnx(folder / "m.safetensors", folder / "m.onnx", (32, 16))
    >>> ev = make_events([0, 5, 9], [1, 2, 30], [1, 2, 15], [1, 0, 1])
    >>> p = onnx_parity(folder / "m.safetensors", folder / "m.onnx", [(0, ev)], (32, 16))
    >>> p.max_abs_diff, p.decisions, p.decisions_differing, p.unit
    (0.0, 3, 0, 'event')
    """
    from .infer import ModelDeflarer
    from .mask_kernels import event_keep_mask, keep_logit_threshold

    torch_run = ModelDeflarer(weights, runtime="torch", batch_windows=1)
    onnx_run = ModelDeflarer(exported, batch_windows=1)
    mask = isinstance(torch_run.model, FlareMaskNet)
    scale = torch_run.model.scale if mask else 1
    n_windows = n_decisions = differing = 0
    worst = largest = 0.0
    for start, events in windows:
        y0 = torch_run.network_output(events, sensor_size, start)
        y1 = onnx_run.network_output(events, sensor_size, start)
        worst = max(worst, float(np.max(np.abs(y0 - y1))))
        largest = max(largest, float(np.max(np.abs(y0))))
        if mask and torch_run.head_params is not None:  # the head's decisions, after the net
            k0, k1 = (
                run.window_logits([(start, events)], sensor_size)[0]
                > keep_logit_threshold(run.keep_threshold)
                for run in (torch_run, onnx_run)
            )
            differing += int(np.count_nonzero(k0 != k1))
            n_decisions += int(events.size)
        elif mask:
            k0, k1 = (
                event_keep_mask(
                    y,
                    events,
                    start,
                    torch_run.window_us,
                    scale,
                    run.keep_threshold,
                    pixel_params=run.pixel_params,
                    sensor_size=sensor_size,
                )
                for y, run in ((y0, torch_run), (y1, onnx_run))
            )
            differing += int(np.count_nonzero(k0 != k1))
            n_decisions += int(events.size)
        else:
            differing += int(np.count_nonzero(np.rint(y0) != np.rint(y1)))
            n_decisions += int(y0.size)
        n_windows += 1
    return Parity(n_windows, worst, largest, n_decisions, differing, "event" if mask else "cell")
