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

__all__ = [
    "HEAD_BLOCK",
    "EventHead",
    "EventHeadEnsemble",
    "build_head",
    "event_cells",
    "gather_context",
    "head_logits",
    "head_logits_at_cells",
    "head_spec",
]


def head_spec(spec: Mapping[str, Any], where: str = "model card") -> dict[str, Any]:
    """A card's ``head`` entry checked: ``{"features": [...], "hidden": [...]}``, and
    ``"context": {"channels": k, "inputs": c, "widths": [...]}`` for a head with a learned
    whole-frame context (:class:`EventHead`; with ``"relative_counts": m``, its first ``m``
    inputs, log event counts, are read relative to the window's mean), and
    ``"members": n`` (2 or more) for an ensemble of ``n`` such heads
    (:class:`EventHeadEnsemble`).

    Examples
    --------
    >>> head_spec({"features": ["net_logit"], "hidden": [8]})
    {'features': ['net_logit'], 'hidden': [8]}
    >>> head_spec({"features": ["net_logit"], "hidden": [8], "members": 3})["members"]
    3
    >>> head_spec({"features": ["net_logit"], "hiden": [8]}, "head")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    edeflare.errors.ParameterError: head: unknown keys ['hiden'] (a head holds features, ...)
    """
    unknown = sorted(set(spec) - {"features", "hidden", "context", "members"})
    if unknown:
        raise ParameterError(
            f"{where}: unknown keys {unknown} (a head holds features, hidden, context, members)"
        )
    features = list(check_feature_names(spec.get("features", ()), where))
    if not features:
        raise ParameterError(f"{where}: needs at least one feature")
    hidden = _widths(spec.get("hidden", ()), f"{where}: hidden widths")
    out: dict[str, Any] = {"features": features, "hidden": hidden}
    context = spec.get("context")
    if context:
        if not isinstance(context, Mapping):
            raise ParameterError(f"{where}: context must be a mapping, got {context!r}")
        unknown = sorted(set(context) - {"channels", "inputs", "widths", "relative_counts"})
        if unknown or not {"channels", "inputs", "widths"} <= set(context):
            raise ParameterError(
                f"{where}: context holds channels, inputs, widths (and relative_counts), "
                f"got {sorted(context)}"
            )
        sizes = [context["channels"], context["inputs"]]
        channels, inputs = _widths(sizes, f"{where}: context sizes")
        widths = _widths(context["widths"], f"{where}: context widths")
        if not widths:
            raise ParameterError(f"{where}: context widths must not be empty")
        out["context"] = {"channels": channels, "inputs": inputs, "widths": widths}
        relative = context.get("relative_counts", 0)
        if relative:
            (relative,) = _widths([relative], f"{where}: context relative_counts")
            if relative > inputs:
                raise ParameterError(
                    f"{where}: context relative_counts {relative} exceeds its {inputs} inputs"
                )
            out["context"]["relative_counts"] = relative
    members = spec.get("members", 1)
    if isinstance(members, bool) or not isinstance(members, int) or members < 1:
        raise ParameterError(f"{where}: members must be a positive integer, got {members!r}")
    if members > 1:
        out["members"] = members
    return out


def build_head(spec: Mapping[str, Any]) -> EventHead | EventHeadEnsemble:
    """A fresh head of a card's ``head`` entry: an :class:`EventHead`, or an
    :class:`EventHeadEnsemble` where it has ``members``.

    Examples
    --------
    >>> type(build_head({"features": ["net_logit"], "hidden": [4], "members": 2})).__name__
    'EventHeadEnsemble'
    """
    spec = head_spec(spec)
    members = spec.pop("members", 1)
    if members == 1:
        return EventHead(**spec)
    return EventHeadEnsemble([EventHead(**spec) for _ in range(members)])


def _widths(values: Any, what: str) -> list[int]:
    if not isinstance(values, Sequence) or any(
        isinstance(h, bool) or not isinstance(h, int) or h < 1 for h in values
    ):
        raise ParameterError(f"{what} must be positive integers, got {values!r}")
    return [int(h) for h in values]


class EventHead(nn.Module):
    """Keep logit of an event from its features: standardise, then a ReLU perceptron.

    With a ``context``, a small 2-D U-Net (:class:`~edeflare.models.unet2d.UNet2dLayers`)
    maps the window's cells (the mask network's inputs and its keep logits, ``inputs``
    channels) to ``channels`` maps of the whole frame; each event reads them at its cell
    (:meth:`context_maps`, then :func:`gather_context`), as extra columns after its
    features. The context is learned with the head, from the same pairs.

    Parameters
    ----------
    features : sequence of str
        The :data:`~edeflare.models.event_features.FEATURES` it reads, in order.
    hidden : sequence of int
        Widths of the hidden layers (none: a logistic regression).
    context : mapping, optional
        ``{"channels": k, "inputs": c, "widths": [...]}``: the context network's output
        maps, input channels and level widths (none: no context). With
        ``"relative_counts": m``, the first ``m`` input channels (the cells' log(1 + n)
        event counts) are read as log(1 + n / the window's mean n over them): the same
        (in expectation) when a window's events are thinned at random
        (:meth:`context_input`).

    Examples
    --------
    >>> head = EventHead(("net_logit", "support", "halo"), hidden=(16, 8))
    >>> head(torch.zeros(5, 3)).shape
    torch.Size([5])
    >>> sum(p.numel() for p in head.parameters())
    209
    >>> ctx = EventHead(("net_logit",), (8,), {"channels": 2, "inputs": 5, "widths": [4, 8]})
    >>> ctx.context_maps(torch.zeros(1, 5, 6, 7)).shape, ctx.columns
    (torch.Size([1, 2, 6, 7]), 3)
    """

    def __init__(
        self,
        features: Sequence[str],
        hidden: Sequence[int] = (32, 16),
        context: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__()
        spec = head_spec(
            {"features": list(features), "hidden": list(hidden), "context": context or {}}
        )
        self.feature_names: tuple[str, ...] = tuple(spec["features"])
        self.hidden: tuple[int, ...] = tuple(spec["hidden"])
        self.context: dict[str, Any] | None = spec.get("context")
        k = self.context["channels"] if self.context else 0
        self.columns = len(self.feature_names) + k
        """Input columns: the features, then the context's channels."""
        # the context's columns keep mean 0 and scale 1 (learned maps need no scaling)
        self.register_buffer("mean", torch.zeros(self.columns))
        self.register_buffer("scale", torch.ones(self.columns))
        if self.context:
            from .unet2d import UNet2dLayers

            c, widths = self.context["inputs"], self.context["widths"]
            self.context_net = UNet2dLayers(c, k, widths, _groups(widths))
            # not zero like a residual's last layer: the perceptron must see the maps vary
            # from the start for either to learn
            nn.init.normal_(self.context_net.final.weight, std=0.1)
            self.register_buffer("context_mean", torch.zeros(c))
            self.register_buffer("context_scale", torch.ones(c))
        widths = [self.columns, *self.hidden, 1]
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in itertools.pairwise(widths))

    def spec(self) -> dict[str, Any]:
        """The card's ``head`` entry of this head."""
        out: dict[str, Any] = {"features": list(self.feature_names), "hidden": list(self.hidden)}
        if self.context:
            out["context"] = dict(self.context)
        return out

    def standardise_on(self, x: torch.Tensor, cells: torch.Tensor | None = None) -> None:
        """Set the standardisation to the mean and standard deviation of features ``x``
        (per column) and, with a context, of ``cells`` (per channel, over every cell of
        the windows ``(N, inputs, h, w)``, given as the context reads them:
        :meth:`context_input`)."""
        n = len(self.feature_names)
        with torch.no_grad():
            self.mean[:n] = x[:, :n].mean(0)
            self.scale[:n] = x[:, :n].std(0).clamp(min=1e-3)
            if self.context and cells is not None:
                flat = cells.transpose(0, 1).reshape(cells.shape[1], -1).double()
                self.context_mean.copy_(flat.mean(1))
                self.context_scale.copy_(flat.std(1).clamp(min=1e-3))

    def context_maps(self, cells: torch.Tensor) -> torch.Tensor:
        """The context's maps ``(N, channels, h, w)`` of windows' cells ``(N, inputs, h, w)``."""
        if not self.context:
            raise ValueError("this head has no context")
        cells = self.context_input(cells)
        z = (cells - self.context_mean[:, None, None]) / self.context_scale[:, None, None]
        return self.context_net.unet(z)

    def context_input(self, cells: torch.Tensor) -> torch.Tensor:
        """Windows' cells ``(N, inputs, h, w)`` as the context reads them: as given, or with
        ``relative_counts`` of them (log(1 + n) counts) as log(1 + n / m), ``m`` the window's
        mean ``n`` over those channels and cells (a window without events: 0).

        Examples
        --------
        >>> head = EventHead(["net_logit"], (4,), {"channels": 1, "inputs": 2,
        ...                  "widths": [4], "relative_counts": 1})
        >>> cells = torch.log1p(torch.tensor([[[[1.0, 3.0]], [[5.0, 5.0]]]]))  # n = 1, 3
        >>> head.context_input(cells)[0, 0, 0].expm1().tolist()  # n / 2; the second left
        [0.5, 1.5]
        """
        m = self.context.get("relative_counts", 0) if self.context else 0
        if not m:
            return cells
        n = (torch.exp(cells[:, :m]) - 1.0).clamp(min=0.0)  # expm1: not in ONNX opset 17
        mean = n.mean(dim=(1, 2, 3), keepdim=True)
        return torch.cat([torch.log1p(n / mean.clamp(min=1e-6)), cells[:, m:]], 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = (x - self.mean) / self.scale
        for k, layer in enumerate(self.layers):
            z = layer(z)
            if k < len(self.layers) - 1:
                z = torch.relu(z)
        return z[..., 0]

    def numpy_params(self) -> dict[str, Any]:
        """The weights as float32 arrays for :func:`head_logits` (the standardisation
        folded into the first layer), the feature names and the context's channels
        (``context``, 0 without one: the columns after the features)."""
        with torch.no_grad():
            weights = [layer.weight.double().cpu().numpy() for layer in self.layers]
            biases = [layer.bias.double().cpu().numpy() for layer in self.layers]
            mean, scale = self.mean.double().cpu().numpy(), self.scale.double().cpu().numpy()
        w0 = weights[0] / scale
        biases[0] = biases[0] - w0 @ mean
        weights[0] = w0
        return {
            "features": self.feature_names,
            "context": self.context["channels"] if self.context else 0,
            "weights": [np.ascontiguousarray(w.T, np.float32) for w in weights],
            "biases": [b.astype(np.float32) for b in biases],
        }


class EventHeadEnsemble(nn.Module):
    """Several :class:`EventHead` of one layout, trained apart (other seeds): an event's
    keep logit is the mean of theirs.

    Heads trained from other seeds disagree on real recordings far more than on the
    simulated pairs they were chosen on; their mean is steadier than any one of them.
    Its input columns are the features, then each member's context channels in turn
    (:meth:`context_maps` gives the members' maps one after another).

    Parameters
    ----------
    members : sequence of EventHead
        Two or more heads of one layout (features, hidden widths, context).

    Examples
    --------
    >>> heads = [EventHead(("net_logit",), (4,)) for _ in range(3)]
    >>> ens = EventHeadEnsemble(heads)
    >>> x = torch.randn(5, 1)
    >>> bool(torch.allclose(ens(x), torch.stack([h(x) for h in heads]).mean(0)))
    True
    >>> ens.spec()["members"], ens.columns
    (3, 1)
    """

    def __init__(self, members: Sequence[EventHead]) -> None:
        super().__init__()
        if len(members) < 2:
            raise ParameterError(f"an ensemble needs at least two heads, got {len(members)}")
        layout = members[0].spec()
        for m in members[1:]:
            if m.spec() != layout:
                raise ParameterError(
                    f"an ensemble's heads must share one layout, got {layout} and {m.spec()}"
                )
        self.members = nn.ModuleList(members)

    # the layout is the members' (one for all): read from the first
    @property
    def feature_names(self) -> tuple[str, ...]:
        return self.members[0].feature_names

    @property
    def hidden(self) -> tuple[int, ...]:
        return self.members[0].hidden

    @property
    def context(self) -> dict[str, Any] | None:
        return self.members[0].context

    @property
    def columns(self) -> int:
        """Input columns: the features, then each member's context channels."""
        return len(self.feature_names) + sum(m.columns - len(m.feature_names) for m in self.members)

    def spec(self) -> dict[str, Any]:
        """The card's ``head`` entry: a member's, with ``members``."""
        return {**self.members[0].spec(), "members": len(self.members)}

    def context_maps(self, cells: torch.Tensor) -> torch.Tensor:
        """The members' maps one after another ``(N, members * channels, h, w)``."""
        return torch.cat([m.context_maps(cells) for m in self.members], 1)

    def _member_columns(self, x: torch.Tensor, i: int) -> torch.Tensor:
        n = len(self.feature_names)
        if not self.context:
            return x
        k = self.context["channels"]
        return torch.cat([x[:, :n], x[:, n + i * k : n + (i + 1) * k]], 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        logits = [m(self._member_columns(x, i)) for i, m in enumerate(self.members)]
        return torch.stack(logits).mean(0)

    def numpy_params(self) -> dict[str, Any]:
        """:func:`head_logits`' weights: each member's (``members``), the feature names
        and every context column (``context``: members x channels)."""
        params = [m.numpy_params() for m in self.members]
        return {
            "features": self.feature_names,
            "context": sum(p["context"] for p in params),
            "members": params,
        }


def _groups(widths: Sequence[int]) -> int:
    """Group norms' groups of a context network of level ``widths``: 4 where all divide."""
    return 4 if all(w % 4 == 0 for w in widths) else 1


def gather_context(maps: np.ndarray, events: np.ndarray, scale: int) -> np.ndarray:
    """Each event's column of context ``maps`` ``(k, h, w)`` at its cell of ``scale``
    pixels: ``(n, k)`` float32.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> maps = np.arange(2 * 2 * 3, dtype=np.float32).reshape(2, 2, 3)
    >>> gather_context(maps, make_events([0, 1], [0, 9], [0, 5], [1, 0]), 4).tolist()
    [[0.0, 6.0], [5.0, 11.0]]
    """
    k, h, w = maps.shape
    cell = event_cells(events, scale, w)
    return np.ascontiguousarray(maps.reshape(k, h * w)[:, cell].T, dtype=np.float32)


def event_cells(events: np.ndarray, scale: int, cells_wide: int) -> np.ndarray:
    """Each event's flat cell on a grid ``cells_wide`` cells wide of ``scale``-pixel cells.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> event_cells(make_events([0, 1], [0, 9], [0, 5], [1, 0]), 4, 3).tolist()
    [0, 5]
    """
    y, x = events["y"].astype(np.intp) // scale, events["x"].astype(np.intp) // scale
    return y * cells_wide + x


HEAD_BLOCK = 4_096
"""Events per block of :func:`head_logits`: a block's hidden activations (every member's,
side by side) stay near the cache. With the members' first layers side by side and the
context's share computed per cell, `learned`'s head takes 0.8-1.0x the time of one
product per member over every column in blocks of 65,536 (20,000-200,000 events), and
`edeflare deflare --model learned` 0.88-0.94x (640x480, 1-3 M events/s)."""


def head_logits(params: Mapping[str, Any], features: np.ndarray) -> np.ndarray:
    """The keep logits of ``(n, F)`` features (float32), from :meth:`EventHead.numpy_params`
    (an ensemble's, :meth:`EventHeadEnsemble.numpy_params`: the mean of its members').

    Rows are independent: blocks of :data:`HEAD_BLOCK` events give what one block would.
    The columns after the features are the context's (every member's channels in turn):
    :func:`head_logits_at_cells` reads them from the context's maps instead.
    """
    z = np.asarray(features, np.float32)
    layers = _StackedHead(params)
    n = len(params["features"])
    return layers.logits(z[:, :n], z[:, n:] if layers.context else None)


def head_logits_at_cells(
    params: Mapping[str, Any], features: np.ndarray, maps: np.ndarray, cells: np.ndarray
) -> np.ndarray:
    """:func:`head_logits` of a window's events with their context columns read from the
    context's ``maps`` ``(k, h, w)`` at each event's flat cell ``cells``
    (:func:`event_cells`), without building those columns: each cell's share of the first
    layer is computed once per cell (a 640x480 window has 4,800 cells and up to millions of
    events) and added to its events' rows.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> head = EventHead(("net_logit",), (4,), {"channels": 2, "inputs": 3, "widths": [4]})
    >>> params = head.numpy_params()
    >>> ev = make_events([0, 1], [0, 9], [0, 5], [1, 0])
    >>> maps = np.arange(2 * 2 * 3, dtype=np.float32).reshape(2, 2, 3)
    >>> x = np.array([[0.5], [-1.0]], np.float32)
    >>> columns = np.hstack([x, gather_context(maps, ev, 4)])
    >>> at = head_logits_at_cells(params, x, maps, event_cells(ev, 4, 3))
    >>> bool(np.allclose(at, head_logits(params, columns), atol=1e-6))
    True
    """
    layers = _StackedHead(params)
    if not layers.context:
        raise ValueError("this head has no context to read maps for")
    k = maps.shape[0]
    if k != layers.context:
        raise ValueError(f"{k} context maps for a head that reads {layers.context}")
    per_cell = maps.reshape(k, -1).T.astype(np.float32) @ layers.first_context
    return layers.logits(np.asarray(features, np.float32), rows=per_cell, cells=cells)


class _StackedHead:
    """A head's (or an ensemble's) layers for :func:`head_logits`: every member's first
    layer side by side (one product over the features for all of them; the context's
    columns block-diagonal), the deeper layers per member."""

    def __init__(self, params: Mapping[str, Any]) -> None:
        members = params["members"] if "members" in params else [params]
        n = len(params["features"])
        self.context = int(params["context"])
        firsts = [m["weights"][0] for m in members]
        self.first_features = np.ascontiguousarray(np.hstack([w[:n] for w in firsts]))
        self.first_context = np.zeros((self.context, self.first_features.shape[1]), np.float32)
        row = col = 0
        for w in firsts:
            k = w.shape[0] - n
            self.first_context[row : row + k, col : col + w.shape[1]] = w[n:]
            row, col = row + k, col + w.shape[1]
        self.first_bias = np.concatenate([m["biases"][0] for m in members]).astype(np.float32)
        self.spans = list(itertools.pairwise(np.cumsum([0] + [w.shape[1] for w in firsts])))
        self.deeper = [list(zip(m["weights"][1:], m["biases"][1:], strict=True)) for m in members]

    def logits(
        self,
        features: np.ndarray,
        context: np.ndarray | None = None,
        *,
        rows: np.ndarray | None = None,
        cells: np.ndarray | None = None,
    ) -> np.ndarray:
        """Mean keep logit of the members for ``features`` and either per-event
        ``context`` columns or per-cell first-layer ``rows`` read at ``cells``."""
        out = np.empty(features.shape[0], np.float32)
        for lo in range(0, features.shape[0], HEAD_BLOCK):
            hi = lo + HEAD_BLOCK
            a = features[lo:hi] @ self.first_features
            if context is not None:
                a += context[lo:hi] @ self.first_context
            if rows is not None and cells is not None:
                a += rows[cells[lo:hi]]
            a += self.first_bias
            if self.deeper[0]:  # hidden layers: the first one's ReLU (else: the logit)
                np.maximum(a, 0.0, out=a)
            total = np.zeros(a.shape[0], np.float32)
            for (i, j), layers in zip(self.spans, self.deeper, strict=True):
                z = a[:, i:j]
                for k, (w, b) in enumerate(layers):
                    z = (np.maximum(z, 0.0) if k else z) @ w
                    z += b
                total += z[:, 0]
            out[lo:hi] = total / len(self.deeper)
        return out
