"""Shared pieces of the context-head study: one window's inputs and the model.

A window gives (a) the night network's cell inputs and its cell logits, stacked as the
context network's input (33 channels at 8x8-pixel cells), (b) every event's 21 head
features (its net logit among them) and (c) every event's cell.
"""

from __future__ import annotations

import itertools

import numpy as np
import torch
from torch import nn

from edeflare.lights.cells import covered_us
from edeflare.models.event_features import DEFAULT_FEATURES, FEATURES, window_features
from edeflare.models.infer import ModelDeflarer, bundled_weights
from edeflare.models.mask_kernels import event_features, event_keep_logits, event_records
from edeflare.models.unet2d import UNet2dLayers
from edeflare.models.weights import read_card
from edeflare.rules import WindowContext

LN3 = float(np.log(3.0))
LIGHT_FREE = list(FEATURES).index("light_free")
CELL = 8


def night_deflarer() -> ModelDeflarer:
    w = bundled_weights("night")
    card = read_card(w)
    d = ModelDeflarer(w, runtime="torch", batch_windows=1, **{k: 0 for k in card.rules})
    d.head_params = None
    return d


def window_inputs(d: ModelDeflarer, ev: np.ndarray, start: int, size, lights=False) -> tuple:
    """(context input (33, h, w) float32, features (n, 21) float32, cell (n,) int64);
    ``lights``: a 34th channel, 1 on the window's light cells."""
    net, w = d.model, d.window_us
    rec = event_records(ev, start, w, net.bins, size)
    cellf = event_features(ev, size, start, w, net.bins, net.scale, records=rec)
    low = d._network(cellf[None], size, True)[0]
    support = np.empty(ev.size, np.int64)
    v = event_keep_logits(
        low,
        ev,
        start,
        w,
        net.scale,
        pixel_params=d.pixel_params,
        sensor_size=size,
        support=support,
        records=rec,
    )
    ctx = WindowContext(ev, size, covered_us(ev, start, w), support)
    f = window_features(ctx, v, DEFAULT_FEATURES, window_us=w)
    cw = -(-int(size[0]) // CELL)
    cell = (ev["y"].astype(np.int64) // CELL) * cw + ev["x"].astype(np.int64) // CELL
    parts = [cellf, low]
    if lights:
        parts.append(ctx.lights[None].astype(np.float32))
    return np.concatenate(parts).astype(np.float32), f, cell


class ContextHead(nn.Module):
    """A per-event MLP over the head features and ``k`` context channels that a cell
    U-Net computes from the whole window (k = 0: the plain head)."""

    def __init__(
        self, nfeat: int, k: int = 8, hidden=(64, 32), widths=(16, 32, 64, 64), in_ch: int = 33
    ):
        super().__init__()
        self.k = k
        self.register_buffer("mean", torch.zeros(nfeat))
        self.register_buffer("scale", torch.ones(nfeat))
        self.register_buffer("cmean", torch.zeros(in_ch, 1, 1))
        self.register_buffer("cscale", torch.ones(in_ch, 1, 1))
        if k:
            self.ctx = UNet2dLayers(in_ch, k, widths, groups=4)
            nn.init.normal_(self.ctx.final.weight, std=0.1)  # let the head see it from the start
        sizes = [nfeat + k, *hidden, 1]
        self.mlp = nn.ModuleList(nn.Linear(a, b) for a, b in itertools.pairwise(sizes))

    def context(self, c: torch.Tensor) -> torch.Tensor:
        """(B, k, h, w) of (B, 33, h, w)."""
        return self.ctx.unet((c - self.cmean) / self.cscale)

    def forward(self, feats: torch.Tensor, ctx_rows: torch.Tensor | None) -> torch.Tensor:
        z = (feats - self.mean) / self.scale
        if self.k:
            z = torch.cat([z, self.gate(feats, ctx_rows)], 1)
        for i, layer in enumerate(self.mlp):
            z = layer(z)
            if i < len(self.mlp) - 1:
                z = torch.relu(z)
        return z[:, 0]

    gate_light_free = False
    """Zero the context of events in windows without a light (its light_free feature)."""

    def gate(self, feats: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        if not self.gate_light_free:
            return rows
        return rows * (1.0 - feats[:, LIGHT_FREE : LIGHT_FREE + 1])

    def rows(self, c: torch.Tensor, win: torch.Tensor, cell: torch.Tensor) -> torch.Tensor:
        """Context rows of events: window ``win`` of the batch, flat ``cell``."""
        emb = self.context(c)  # (B, k, h, w)
        b, k = emb.shape[:2]
        flat = emb.reshape(b, k, -1).permute(0, 2, 1).reshape(-1, k)
        return flat[win * emb.shape[2] * emb.shape[3] + cell]
