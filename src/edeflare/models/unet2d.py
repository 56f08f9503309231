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

__all__ = ["ResidualUNet2d", "UNet2dLayers"]


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


class UNet2dLayers(nn.Module):
    """The layers of a 2-D U-Net and its pass: ``(N, in, H, W) -> (N, out, H, W)``.

    Shared by :class:`ResidualUNet2d` and
    :class:`~edeflare.models.flaremask.FlareMaskNet`. The last 1x1 convolution
    is zero-initialised, inputs are padded to :attr:`multiple` and cropped back.

    Examples
    --------
    >>> net = UNet2dLayers(3, 2, (8, 16), groups=4)
    >>> net.unet(torch.randn(1, 3, 5, 7)).abs().max().item()
    0.0
    """

    def __init__(
        self, in_channels: int, out_channels: int, widths: Sequence[int], groups: int
    ) -> None:
        super().__init__()
        widths = tuple(int(f) for f in widths)
        self.widths = widths
        self.first = _Block2d(in_channels, widths[0], groups)
        self.downs = nn.ModuleList(_Block2d(a, b, groups) for a, b in itertools.pairwise(widths))
        self.ups = nn.ModuleList(
            nn.ConvTranspose2d(b, a, 3, stride=2, padding=1, bias=False)
            for a, b in zip(widths[-2::-1], widths[:0:-1], strict=True)
        )
        self.up_blocks = nn.ModuleList(_Block2d(a, a, groups) for a in widths[-2::-1])
        self.final = nn.Conv2d(widths[0], out_channels, 1)
        nn.init.zeros_(self.final.weight)
        nn.init.zeros_(self.final.bias)

    @property
    def multiple(self) -> int:
        """Input sizes are padded to multiples of this (``2 ** (levels - 1)``)."""
        return 2 ** (len(self.widths) - 1)

    def unet(self, z: torch.Tensor) -> torch.Tensor:
        """The U-Net's output for ``(N, in, H, W)`` (padded, then cropped to ``H, W``)."""
        h, w = z.shape[2:]
        m = self.multiple
        if (-h) % m or (-w) % m:
            z = F.pad(z, [0, (-w) % m, 0, (-h) % m])
        skips = [self.first(z)]
        for down in self.downs:
            skips.append(down(F.max_pool2d(skips[-1], 2)))
        out = skips.pop()
        for up, block in zip(self.ups, self.up_blocks, strict=True):
            skip = skips.pop()
            out = block(up(out, output_size=skip.shape[2:]) + skip)
        return self.final(out)[:, :, :h, :w]


class ResidualUNet2d(UNet2dLayers):
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
        super().__init__(int(bins), int(bins), features, groups)
        self.bins = int(bins)
        self.features = self.widths

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 5 or x.shape[1] != 1 or x.shape[2] != self.bins:
            raise ValueError(f"expected input (N, 1, {self.bins}, H, W), got {tuple(x.shape)}")
        return x + self.unet(x[:, 0])[:, None]
