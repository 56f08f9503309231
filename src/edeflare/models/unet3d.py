"""E-DeflareNet: a residual 3D U-Net that maps flare-corrupted voxel grids to clean ones.

``out = x + f(x)`` where ``f`` is a U-Net of :class:`~edeflare.models.blocks.ResBlock3d`
levels (paper: 4 levels of 32/64/128/256 features, 2x max pooling over all
three axes so 8 bins reach 1 at the bottom, summation skips, transposed
convolutions) and a final 1x1x1 convolution whose weight and bias start at
zero: the model is exactly the identity at initialisation and learns the
(negative) flare residual. Input and output are ``(N, 1, T, H, W)``; sizes that
are not multiples of ``2**(levels-1)`` are zero-padded and cropped back.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

from .blocks import Down, ResBlock3d, Up

__all__ = ["ResidualUNet3d"]


class ResidualUNet3d(nn.Module):
    """Residual 3D U-Net with an identity shortcut around the whole network.

    Parameters
    ----------
    features : sequence of int
        Feature maps per level, e.g. ``(32, 64, 128, 256)`` (paper).
    groups : int
        Group-norm groups.

    Examples
    --------
    >>> net = ResidualUNet3d(features=(8, 16), groups=4)
    >>> x = torch.randn(1, 1, 8, 12, 10)
    >>> bool(torch.equal(net(x), x))   # identity at initialisation
    True
    """

    def __init__(self, features: Sequence[int] = (32, 64, 128, 256), groups: int = 8) -> None:
        super().__init__()
        features = tuple(int(f) for f in features)
        if not features:
            raise ValueError("features must list at least one level")
        self.features = features
        self.first = ResBlock3d(1, features[0], groups)
        self.downs = nn.ModuleList(Down(a, b, groups) for a, b in itertools.pairwise(features))
        self.ups = nn.ModuleList(
            Up(b, a, groups) for a, b in zip(features[-2::-1], features[:0:-1], strict=True)
        )
        self.final = nn.Conv3d(features[0], 1, kernel_size=1)
        nn.init.zeros_(self.final.weight)
        nn.init.zeros_(self.final.bias)

    @property
    def multiple(self) -> int:
        """Input sizes are padded to multiples of this (``2 ** (levels - 1)``)."""
        return 2 ** (len(self.features) - 1)

    def residual(self, x: torch.Tensor) -> torch.Tensor:
        """``f(x)`` on an input whose sizes are multiples of :attr:`multiple`."""
        skips = [self.first(x)]
        for down in self.downs:
            skips.append(down(skips[-1]))
        out = skips.pop()
        for up in self.ups:
            out = up(out, skips.pop())
        return self.final(out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 5 or x.shape[1] != 1:
            raise ValueError(f"expected input (N, 1, T, H, W), got {tuple(x.shape)}")
        t, h, w = x.shape[2:]
        m = self.multiple
        pad = [0, (-w) % m, 0, (-h) % m, 0, (-t) % m]
        padded = F.pad(x, pad) if any(pad) else x
        res = self.residual(padded)[:, :, :t, :h, :w]
        return x + res
