"""Building blocks of the residual 3D U-Net (layout ``(N, C, T, H, W)``).

The blocks follow pytorch-3dunet's ``ResNetBlock`` / ``Encoder`` /
``Decoder`` as used by E-DeflareNet (paper, Appendix C): group norm before
each convolution, summation skip connections, transposed convolutions for
upsampling.
"""

from __future__ import annotations

import torch
from torch import nn

__all__ = ["Down", "ResBlock3d", "Up"]


class ResBlock3d(nn.Module):
    """Residual block: projection, (GN, 3x3x3 conv, ReLU), (GN, 3x3x3 conv), add, ReLU.

    The projection is a biased 1x1x1 convolution when the channel count
    changes, the identity otherwise; the 3x3x3 convolutions have no bias
    (the group norm before them makes it redundant).

    Parameters
    ----------
    in_channels, out_channels : int
    groups : int
        Groups of the group norms (paper: 8); must divide ``out_channels``.

    Examples
    --------
    >>> block = ResBlock3d(1, 8, groups=4)
    >>> block(torch.zeros(1, 1, 2, 4, 4)).shape
    torch.Size([1, 8, 2, 4, 4])
    """

    def __init__(self, in_channels: int, out_channels: int, groups: int = 8) -> None:
        super().__init__()
        if out_channels % groups:
            raise ValueError(f"groups ({groups}) must divide out_channels ({out_channels})")
        self.project = (
            nn.Conv3d(in_channels, out_channels, kernel_size=1)
            if in_channels != out_channels
            else nn.Identity()
        )
        self.norm1 = nn.GroupNorm(groups, out_channels)
        self.conv1 = nn.Conv3d(out_channels, out_channels, kernel_size=3, padding=1, bias=False)
        self.norm2 = nn.GroupNorm(groups, out_channels)
        self.conv2 = nn.Conv3d(out_channels, out_channels, kernel_size=3, padding=1, bias=False)
        self.act = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        residual = self.project(x)
        out = self.act(self.conv1(self.norm1(residual)))
        out = self.conv2(self.norm2(out))
        return self.act(out + residual)


class Down(nn.Module):
    """2x max pooling over ``(T, H, W)``, then a residual block."""

    def __init__(self, in_channels: int, out_channels: int, groups: int = 8) -> None:
        super().__init__()
        self.pool = nn.MaxPool3d(kernel_size=2)
        self.block = ResBlock3d(in_channels, out_channels, groups)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.block(self.pool(x))


class Up(nn.Module):
    """Stride-2 3x3x3 transposed convolution, add the skip features, then a residual block."""

    def __init__(self, in_channels: int, out_channels: int, groups: int = 8) -> None:
        super().__init__()
        self.up = nn.ConvTranspose3d(
            in_channels, out_channels, kernel_size=3, stride=2, padding=1, bias=False
        )
        self.block = ResBlock3d(out_channels, out_channels, groups)

    def forward(self, x: torch.Tensor, skip: torch.Tensor) -> torch.Tensor:
        x = self.up(x, output_size=skip.shape[2:])
        return self.block(x + skip)
