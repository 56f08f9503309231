"""FireNet-sized recurrent event-to-image network (our own, after Scheerlinck et al. 2020).

The architecture of "Fast Image Reconstruction with an Event Camera" (WACV
2020), written here from the paper's description: a 3x3 head, two
convolutional GRUs each followed by a residual block, and a 1x1 prediction,
16 features throughout, about 38 k parameters. It maps one window's voxel
grid and the recurrent state to an image in ``[0, 1]`` (log intensity, see
:func:`edeflare.recon.clips.intensity_to_image`).

One addition of ours makes it learnable in minutes on a CPU: a per-pixel
leaky integrator of the signed event counts (the log-intensity change that
events encode, with a learned contrast and decay) is part of the state,
fed to the head beside the normalised voxels (:func:`normalise_voxels`),
and added to the prediction before the sigmoid. The GRUs then learn what
integration alone cannot: the scene's level, filling flat regions, and
suppressing noise.
"""

from __future__ import annotations

import torch
from torch import nn

__all__ = ["ConvGRU", "FireNet", "normalise_voxels"]


class ConvGRU(nn.Module):
    """A convolutional GRU cell: ``h' = (1 - z) h + z tanh(W [x, r h])``."""

    def __init__(self, channels: int, kernel: int = 3) -> None:
        super().__init__()
        pad = kernel // 2
        self.gates = nn.Conv2d(2 * channels, 2 * channels, kernel, padding=pad)
        self.candidate = nn.Conv2d(2 * channels, channels, kernel, padding=pad)

    def forward(self, x: torch.Tensor, h: torch.Tensor | None) -> torch.Tensor:
        if h is None:
            h = torch.zeros_like(x)
        z, r = torch.sigmoid(self.gates(torch.cat([x, h], dim=1))).chunk(2, dim=1)
        c = torch.tanh(self.candidate(torch.cat([x, r * h], dim=1)))
        return (1 - z) * h + z * c


class _Residual(nn.Module):
    def __init__(self, channels: int) -> None:
        super().__init__()
        self.a = nn.Conv2d(channels, channels, 3, padding=1)
        self.b = nn.Conv2d(channels, channels, 3, padding=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(x + self.b(torch.relu(self.a(x))))


class FireNet(nn.Module):
    """Events to images, one window at a time, with a recurrent state.

    Parameters
    ----------
    bins : int
        Temporal bins of the input voxel grid.
    features : int
        Channels of every layer.

    Examples
    --------
    >>> net = FireNet()
    >>> sum(p.numel() for p in net.parameters())
    37949
    >>> image, state = net(torch.zeros(1, 5, 24, 32), None)
    >>> tuple(image.shape), len(state)
    ((1, 1, 24, 32), 3)
    """

    def __init__(self, bins: int = 5, features: int = 16) -> None:
        super().__init__()
        self.bins = int(bins)
        self.head = nn.Conv2d(self.bins + 1, features, 3, padding=1)
        self.gru1 = ConvGRU(features)
        self.res1 = _Residual(features)
        self.gru2 = ConvGRU(features)
        self.res2 = _Residual(features)
        self.pred = nn.Conv2d(features, 1, 1)
        # The integrator: contrast per event (image units) and decay per window (logit).
        self.contrast = nn.Parameter(torch.tensor(0.03))
        self.keep_logit = nn.Parameter(torch.tensor(3.0))  # sigmoid(3) = 0.95 per window
        self.mix = nn.Conv2d(1, 1, 5, padding=2)
        with torch.no_grad():
            self.mix.weight.zero_()
            self.mix.weight[0, 0, 2, 2] = 4.0  # logit slope of the sigmoid at 0.5
            self.mix.bias.zero_()

    def forward(
        self,
        voxels: torch.Tensor,
        state: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None,
    ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """``(N, bins, H, W)`` signed event counts, state -> ``(N, 1, H, W)`` image, state."""
        h1, h2, level = (None, None, None) if state is None else state
        change = self.contrast * voxels.sum(dim=1, keepdim=True)
        level = change if level is None else torch.sigmoid(self.keep_logit) * level + change
        x = torch.relu(self.head(torch.cat([normalise_voxels(voxels), level], dim=1)))
        h1 = self.gru1(x, h1)
        x = self.res1(h1)
        h2 = self.gru2(x, h2)
        x = self.res2(h2)
        return torch.sigmoid(self.pred(x) + self.mix(level)), (h1, h2, level)


def normalise_voxels(voxels: torch.Tensor) -> torch.Tensor:
    """Scale each sample's voxel grid by the root mean square of its non-zero cells.

    Event counts per window vary by orders of magnitude between scenes and
    sensors; the network sees unit-scale inputs whatever the rate (a window
    without events stays zero).

    Examples
    --------
    >>> v = torch.zeros(1, 2, 2, 2); v[0, 0, 0, 0] = 4.0; v[0, 1, 1, 1] = -4.0
    >>> normalise_voxels(v)[0, 0, 0, 0].item()
    1.0
    """
    flat = voxels.flatten(1)
    nonzero = flat != 0
    n = nonzero.sum(dim=1).clamp(min=1)
    mean_sq = (flat**2).sum(dim=1) / n
    scale = torch.sqrt(mean_sq).clamp(min=1e-6)
    return voxels / scale.view(-1, *([1] * (voxels.dim() - 1)))
