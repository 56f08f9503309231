"""A light 2-D residual U-Net over voxel grids, for CPU use.

The ``T`` time bins become channels: ``(N, 1, T, H, W) -> (N, T, H, W)``,
so each 3x3 convolution mixes all bins at once. Pooling is over ``(H, W)``
only. Same contract as :class:`~edeflare.models.unet3d.ResidualUNet3d`:
``out = x + f(x)`` with a zero-initialised last layer (identity at
initialisation), padding to a multiple of ``2 ** (levels - 1)`` and cropping back.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

__all__ = ["ResidualUNet2d"]


class _Block2d(nn.Module):
    def __init__(self, in_channels: int, out_channels: int, groups: int) -> None:
        super().__init__()
        self.project = (
            nn.Conv2d(in_channels, out_channels, 1)
            if in_channels != out_channels
            else nn.Identity()
        )
        self.norm1 = nn.GroupNorm(groups, out_channels)
        self.conv1 = nn.Conv2d(out_channels, out_channels, 3, padding=1, bias=False)
        self.norm2 = nn.GroupNorm(groups, out_channels)
        self.conv2 = nn.Conv2d(out_channels, out_channels, 3, padding=1, bias=False)
        self.act = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        residual = self.project(x)
        out = self.act(self.conv1(self.norm1(residual)))
        return self.act(self.conv2(self.norm2(out)) + residual)


class ResidualUNet2d(nn.Module):
    """Residual 2-D U-Net with time bins as channels.

    Examples
    --------
    >>> net = ResidualUNet2d(bins=8, features=(8, 16), groups=4)
    >>> x = torch.randn(2, 1, 8, 10, 14)
    >>> bool(torch.equal(net(x), x))
    True
    """

    def __init__(
        self, bins: int = 8, features: Sequence[int] = (16, 32, 64), groups: int = 8
    ) -> None:
        super().__init__()
        features = tuple(int(f) for f in features)
        self.bins = int(bins)
        self.features = features
        self.first = _Block2d(self.bins, features[0], groups)
        self.downs = nn.ModuleList(_Block2d(a, b, groups) for a, b in itertools.pairwise(features))
        self.ups = nn.ModuleList(
            nn.ConvTranspose2d(b, a, 3, stride=2, padding=1, bias=False)
            for a, b in zip(features[-2::-1], features[:0:-1], strict=True)
        )
        self.up_blocks = nn.ModuleList(_Block2d(a, a, groups) for a in features[-2::-1])
        self.final = nn.Conv2d(features[0], self.bins, 1)
        nn.init.zeros_(self.final.weight)
        nn.init.zeros_(self.final.bias)

    @property
    def multiple(self) -> int:
        """Input sizes are padded to multiples of this (``2 ** (levels - 1)``)."""
        return 2 ** (len(self.features) - 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 5 or x.shape[1] != 1 or x.shape[2] != self.bins:
            raise ValueError(f"expected input (N, 1, {self.bins}, H, W), got {tuple(x.shape)}")
        h, w = x.shape[3:]
        m = self.multiple
        z = x[:, 0]
        if (-h) % m or (-w) % m:
            z = F.pad(z, [0, (-w) % m, 0, (-h) % m])
        skips = [self.first(z)]
        for down in self.downs:
            skips.append(down(F.max_pool2d(skips[-1], 2)))
        out = skips.pop()
        for up, block in zip(self.ups, self.up_blocks, strict=True):
            skip = skips.pop()
            out = block(up(out, output_size=skip.shape[2:]) + skip)
        res = self.final(out)[:, :, :h, :w]
        return x + res[:, None]
