r"""A flare mask estimated at a working resolution below the sensor's.

Real lens flare in events is mostly *sparse*: single events scattered along
radial streaks and ghost rings, far (tens to hundreds of pixels) from the
light that causes them, while the light itself is a dense compact burst. What
tells one from the other is context at a large scale, not detail at the
pixel, so :class:`FlareMaskNet` looks at the window through cells of
``scale x scale`` pixels:

1. **features** per cell and time bin: :math:`\log(1 + n)` of the ON and OFF
   counts, and the fraction of the cell's pixels that fired in the window
   (dense cores fill their cells, scattered flare does not);
2. a residual 2-D U-Net (:class:`~edeflare.models.unet2d.ResidualUNet2d`'s
   blocks) maps them to one logit :math:`\ell` per cell, bin and polarity;
3. the logits are upsampled bilinearly to the sensor's pixels;
4. optionally (``pixel_hidden > 0``, the ``mask.pixel`` preset) a per-pixel
   refinement adds :math:`\delta = v^\top \mathrm{relu}(a\,\ell + W f + b) + c`
   to each logit, where :math:`f` are the pixel's own features in the window
   (:data:`PIXEL_FEATURES`: :math:`\log(1 + n)` of its events of the logit's
   polarity and of the other, and of the events of its 3x3 and 5x5
   neighbourhoods). The cell sees context; the pixel tells a dense light's edge
   from a lone scattered event or a hot pixel in the same cell. :math:`v` and
   :math:`c` start at zero;
5. the keep probability is :math:`m = \min(1, 2\,\sigma(\ell))`, exactly 1 at
   initialisation (the identity, like every preset) and below 1 where the
   network learns flare.

As a voxel-to-voxel model (training, evaluation, any decoder), the output is
the input gated by :math:`m`: :math:`\max(v, 0)\,m_{on} - \max(-v, 0)\,m_{off}`.
For de-flaring, :func:`~edeflare.models.mask_kernels.event_keep_mask` makes the
decision per event at full
resolution instead (keep where :math:`m > 1/2` at the event's own pixel, bin
and polarity) from low-resolution features computed straight from the events:
no full-resolution voxel grid is ever built, which is what makes the model fast
(``benchmarks/bench_models.py``); the refinement adds one full-resolution count of
the window's events per pixel
(:func:`~edeflare.models.mask_kernels.event_pixel_features`). The per-event kernels
live in :mod:`edeflare.models.mask_kernels`, the training loss in
:mod:`edeflare.models.mask_loss`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from .unet2d import UNet2dLayers

__all__ = ["PIXEL_FEATURES", "FlareMaskNet"]

PIXEL_FEATURES = ("own polarity", "other polarity", "3x3 neighbours", "5x5 ring")
r"""The per-pixel features of the refinement, each :math:`\log(1 + n)` of a count of
the window's events: at the pixel in the logit's polarity, at the pixel in the other
one, in the 8 pixels around it, and in the 16 around those."""


class FlareMaskNet(UNet2dLayers):
    """Per-cell flare mask at ``1/scale`` of the sensor's resolution.

    Parameters
    ----------
    bins : int
        Time bins of the voxel grid.
    scale : int
        Side of a cell in sensor pixels.
    features : sequence of int
        Channels of the U-Net's levels.
    groups : int
        Groups of the group norms.
    pixel_hidden : int
        Width of the per-pixel refinement (0: none).

    Examples
    --------
    >>> net = FlareMaskNet(bins=8, scale=4, features=(8, 16), groups=4)
    >>> x = torch.randn(2, 1, 8, 13, 21).round()
    >>> bool(torch.equal(net(x), x))          # the identity at initialisation
    True
    >>> net.logits(net.features(x)).shape      # (N, 2 bins, ceil(H / 4), ceil(W / 4))
    torch.Size([2, 16, 4, 6])
    """

    def __init__(
        self,
        bins: int = 8,
        scale: int = 4,
        features: Sequence[int] = (16, 32, 64, 128),
        groups: int = 8,
        pixel_hidden: int = 0,
    ) -> None:
        super().__init__(2 * int(bins) + 1, 2 * int(bins), features, groups)
        self.bins = int(bins)
        self.scale = int(scale)
        self.pixel_hidden = int(pixel_hidden)
        if self.pixel_hidden > 0:
            self.pixel_in = nn.Conv2d(len(PIXEL_FEATURES), self.pixel_hidden, 1)
            self.pixel_gain = nn.Parameter(torch.full((self.pixel_hidden,), 0.1))
            self.pixel_out = nn.Conv2d(self.pixel_hidden, 1, 1)
            nn.init.zeros_(self.pixel_out.weight)
            nn.init.zeros_(self.pixel_out.bias)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """Low-resolution features ``(N, 2 bins + 1, ceil(H / s), ceil(W / s))`` of voxel grids."""
        if x.ndim != 5 or x.shape[1] != 1 or x.shape[2] != self.bins:
            raise ValueError(f"expected input (N, 1, {self.bins}, H, W), got {tuple(x.shape)}")
        z = x[:, 0].float()
        s = self.scale
        h, w = z.shape[2:]
        pad = [0, (-w) % s, 0, (-h) % s]
        counts = torch.cat([z.clamp(min=0), (-z).clamp(min=0)], 1)
        counts = F.avg_pool2d(F.pad(counts, pad), s) * (s * s)
        active = F.avg_pool2d(F.pad((z != 0).any(1, keepdim=True).float(), pad), s)
        return torch.cat([torch.log1p(counts), active], 1)

    def logits(self, feats: torch.Tensor) -> torch.Tensor:
        """Keep logits ``(N, 2 bins, h, w)`` (ON bins, then OFF bins) of low-resolution features."""
        return self.unet(feats)

    def pixel_logits(self, x: torch.Tensor) -> torch.Tensor:
        """Keep logits at every pixel ``(N, 2 bins, H, W)`` of voxel grids ``(N, 1, bins, H, W)``.

        The low-resolution logits upsampled bilinearly onto the padded grid of
        whole cells, then cropped: pixel centres fall where
        :func:`event_keep_mask` samples them; then the per-pixel refinement,
        if the net has one.
        """
        h, w = x.shape[3:]
        low = self.logits(self.features(x))
        full = F.interpolate(low, scale_factor=self.scale, mode="bilinear", align_corners=False)
        full = full[:, :, :h, :w]
        if self.pixel_hidden == 0:
            return full
        z = x[:, 0].float()
        on, off = z.clamp(min=0).sum(1, keepdim=True), (-z).clamp(min=0).sum(1, keepdim=True)
        total = on + off
        box3 = F.avg_pool2d(total, 3, stride=1, padding=1, count_include_pad=True) * 9
        box5 = F.avg_pool2d(total, 5, stride=1, padding=2, count_include_pad=True) * 25
        ring = [box3 - total, box5 - box3]
        b = self.bins
        out = []
        for own, other, part in ((on, off, full[:, :b]), (off, on, full[:, b:])):
            f = torch.log1p(torch.cat([own, other, *ring], 1).clamp(min=0))
            hidden = self.pixel_in(f)[:, None] + self.pixel_gain[:, None, None] * part[:, :, None]
            delta = torch.einsum("nbkhw,k->nbhw", F.relu(hidden), self.pixel_out.weight[0, :, 0, 0])
            out.append(part + delta + self.pixel_out.bias[0])
        return torch.cat(out, 1)

    def pixel_params(self) -> dict[str, np.ndarray] | None:
        """The refinement's weights as float64 arrays (None without one), for
        :func:`event_keep_mask`: ``w_in (hidden, 4)``, ``b_in``, ``gain``, ``w_out``, ``b_out``."""
        if self.pixel_hidden == 0:
            return None
        with torch.no_grad():
            return {
                "w_in": self.pixel_in.weight[:, :, 0, 0].double().cpu().numpy(),
                "b_in": self.pixel_in.bias.double().cpu().numpy(),
                "gain": self.pixel_gain.double().cpu().numpy(),
                "w_out": self.pixel_out.weight[0, :, 0, 0].double().cpu().numpy(),
                "b_out": self.pixel_out.bias.double().cpu().numpy(),
            }

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        keep = torch.clamp(2 * torch.sigmoid(self.pixel_logits(x)), max=1.0)
        z = x[:, 0]
        out = z.clamp(min=0) * keep[:, : self.bins] - (-z).clamp(min=0) * keep[:, self.bins :]
        return out[:, None].to(x.dtype)
