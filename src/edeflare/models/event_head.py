r"""A learned per-event keep head: the evidence of :mod:`~edeflare.models.event_features`
weighed by a small network trained on simulated pairs, in place of hand-set rule shifts.

:class:`EventHead` is a multilayer perceptron on the standardised features
(:math:`(f - \mu) / \sigma`, with :math:`\mu, \sigma` measured on its training
events and stored with it) that outputs one keep logit per event, on the mask
network's scale: an event is kept where the head's logit exceeds
:func:`~edeflare.models.mask_kernels.keep_logit_threshold` of the card's
``keep_threshold``. Its weights live in the model's safetensors file under
``head.`` and its layout in the card's ``head`` entry (feature names, hidden
widths). :meth:`EventHead.numpy_params` and :func:`head_logits` run it without
torch, so de-flaring and the ONNX runtime share one implementation.

Examples
--------
>>> head = EventHead(("net_logit", "support"), hidden=(4,))
>>> x = np.array([[1.0, 0.0], [-2.0, 3.0]], np.float32)
>>> head_logits(head.numpy_params(), x).shape
(2,)
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from ..errors import ParameterError
from .event_features import check_feature_names

__all__ = ["HEAD_BLOCK", "EventHead", "head_logits", "head_spec"]


def head_spec(spec: Mapping[str, Any], where: str = "model card") -> dict[str, Any]:
    """A card's ``head`` entry checked: ``{"features": [...], "hidden": [...]}``.

    Examples
    --------
    >>> head_spec({"features": ["net_logit"], "hidden": [8]})
    {'features': ['net_logit'], 'hidden': [8]}
    >>> head_spec({"features": ["net_logit"], "hiden": [8]}, "head")
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: head: unknown keys ['hiden'] (a head holds features, hidden)
    """
    unknown = sorted(set(spec) - {"features", "hidden"})
    if unknown:
        raise ParameterError(f"{where}: unknown keys {unknown} (a head holds features, hidden)")
    features = list(check_feature_names(spec.get("features", ()), where))
    if not features:
        raise ParameterError(f"{where}: needs at least one feature")
    hidden = spec.get("hidden", ())
    if not isinstance(hidden, Sequence) or any(
        isinstance(h, bool) or not isinstance(h, int) or h < 1 for h in hidden
    ):
        raise ParameterError(f"{where}: hidden widths must be positive integers, got {hidden!r}")
    return {"features": features, "hidden": [int(h) for h in hidden]}


class EventHead(nn.Module):
    """Keep logit of an event from its features: standardise, then a ReLU perceptron.

    Parameters
    ----------
    features : sequence of str
        The :data:`~edeflare.models.event_features.FEATURES` it reads, in order.
    hidden : sequence of int
        Widths of the hidden layers (none: a logistic regression).

    Examples
    --------
    >>> head = EventHead(("net_logit", "support", "halo"), hidden=(16, 8))
    >>> head(torch.zeros(5, 3)).shape
    torch.Size([5])
    >>> sum(p.numel() for p in head.parameters())
    209
    """

    def __init__(self, features: Sequence[str], hidden: Sequence[int] = (32, 16)) -> None:
        super().__init__()
        spec = head_spec({"features": list(features), "hidden": list(hidden)})
        self.feature_names: tuple[str, ...] = tuple(spec["features"])
        self.hidden: tuple[int, ...] = tuple(spec["hidden"])
        n = len(self.feature_names)
        self.register_buffer("mean", torch.zeros(n))
        self.register_buffer("scale", torch.ones(n))
        widths = [n, *self.hidden, 1]
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in itertools.pairwise(widths))

    def spec(self) -> dict[str, Any]:
        """The card's ``head`` entry of this head."""
        return {"features": list(self.feature_names), "hidden": list(self.hidden)}

    def standardise_on(self, x: torch.Tensor) -> None:
        """Set the standardisation to the mean and standard deviation of ``x`` (per column)."""
        with torch.no_grad():
            self.mean.copy_(x.mean(0))
            self.scale.copy_(x.std(0).clamp(min=1e-3))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = (x - self.mean) / self.scale
        for k, layer in enumerate(self.layers):
            z = layer(z)
            if k < len(self.layers) - 1:
                z = torch.relu(z)
        return z[..., 0]

    def numpy_params(self) -> dict[str, Any]:
        """The weights as float32 arrays for :func:`head_logits` (the standardisation
        folded into the first layer)."""
        with torch.no_grad():
            weights = [layer.weight.double().cpu().numpy() for layer in self.layers]
            biases = [layer.bias.double().cpu().numpy() for layer in self.layers]
            mean, scale = self.mean.double().cpu().numpy(), self.scale.double().cpu().numpy()
        w0 = weights[0] / scale
        biases[0] = biases[0] - w0 @ mean
        weights[0] = w0
        return {
            "features": self.feature_names,
            "weights": [np.ascontiguousarray(w.T, np.float32) for w in weights],
            "biases": [b.astype(np.float32) for b in biases],
        }


HEAD_BLOCK = 65_536
"""Events per block of :func:`head_logits`: a block's hidden activations stay in the
cache (a dense 1280x720 window holds millions of events: twice as fast as one block)."""


def head_logits(params: Mapping[str, Any], features: np.ndarray) -> np.ndarray:
    """The keep logits of ``(n, F)`` features (float32), from :meth:`EventHead.numpy_params`.

    Rows are independent: blocks of :data:`HEAD_BLOCK` events give what one block would.
    """
    z = np.asarray(features, np.float32)
    out = np.empty(z.shape[0], np.float32)
    last = len(params["weights"]) - 1
    layers = list(zip(params["weights"], params["biases"], strict=True))
    for lo in range(0, z.shape[0], HEAD_BLOCK):
        a = z[lo : lo + HEAD_BLOCK]
        for k, (w, b) in enumerate(layers):
            a = a @ w
            a += b
            if k < last:
                np.maximum(a, 0.0, out=a)
        out[lo : lo + HEAD_BLOCK] = a[:, 0]
    return out
