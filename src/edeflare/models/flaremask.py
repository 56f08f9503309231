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
3. the logits are upsampled bilinearly to the sensor's pixels and the keep
   probability is :math:`m = \min(1, 2\,\sigma(\ell))`, exactly 1 at
   initialisation (the identity, like every preset) and below 1 where the
   network learns flare.

As a voxel-to-voxel model (training, evaluation, any decoder), the output is
the input gated by :math:`m`: :math:`\max(v, 0)\,m_{on} - \max(-v, 0)\,m_{off}`.
For de-flaring, :func:`event_keep_mask` makes the decision per event at full
resolution instead (keep where :math:`m > 1/2` at the event's own pixel, bin
and polarity) from low-resolution features computed straight from the events:
no full-resolution grid is ever built, which is what makes the model fast
(``benchmarks/bench_models.py``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F

from .unet2d import UNet2dLayers

__all__ = ["FlareMaskNet", "event_features", "event_keep_mask", "keep_loss"]


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
    ) -> None:
        super().__init__(2 * int(bins) + 1, 2 * int(bins), features, groups)
        self.bins = int(bins)
        self.scale = int(scale)

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
        :func:`event_keep_mask` samples them.
        """
        h, w = x.shape[3:]
        low = self.logits(self.features(x))
        full = F.interpolate(low, scale_factor=self.scale, mode="bilinear", align_corners=False)
        return full[:, :, :h, :w]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        keep = torch.clamp(2 * torch.sigmoid(self.pixel_logits(x)), max=1.0)
        z = x[:, 0]
        out = z.clamp(min=0) * keep[:, : self.bins] - (-z).clamp(min=0) * keep[:, self.bins :]
        return out[:, None].to(x.dtype)


def event_features(
    events: np.ndarray,
    sensor_size: tuple[int, int],
    window_start_us: int,
    window_us: int,
    bins: int,
    scale: int,
) -> np.ndarray:
    """The features of :meth:`FlareMaskNet.features`, straight from events (float32).

    Equal to ``net.features(encode(...))`` where no cell holds ON and OFF events
    of one pixel and bin that cancel (the voxel grid is signed; the event counts
    are not), which is what real windows mostly look like.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 5, 15], [0, 1, 5], [0, 0, 0], [1, 1, 0])
    >>> f = event_features(ev, (8, 4), 0, 20, bins=2, scale=4)
    >>> f.shape, round(float(f[0, 0, 0]), 4), float(f[4, 0, 0])  # log(1 + 2), 2 of 16 pixels
    ((5, 1, 2), 1.0986, 0.125)
    """
    width, height = sensor_size
    h, w = -(-height // scale), -(-width // scale)
    b = ((events["t"] - int(window_start_us)) * bins) // int(window_us)
    cx = events["x"].astype(np.int64) // scale
    cy = events["y"].astype(np.int64) // scale
    channel = b + bins * (1 - events["p"].astype(np.int64))
    idx = (channel * h + cy) * w + cx
    counts = np.bincount(idx, minlength=2 * bins * h * w).reshape(2 * bins, h, w)
    pixels = np.unique(events["y"].astype(np.int64) * width + events["x"])
    cells = (pixels // width // scale) * w + (pixels % width) // scale
    active = np.bincount(cells, minlength=h * w).reshape(1, h, w) / float(scale * scale)
    return np.concatenate([np.log1p(counts), active]).astype(np.float32)


def event_keep_mask(
    logits: np.ndarray,
    events: np.ndarray,
    window_start_us: int,
    window_us: int,
    scale: int,
    threshold: float = 0.5,
) -> np.ndarray:
    """Per-event keep decisions from low-resolution logits ``(2 bins, h, w)``.

    The logit of the event's own polarity and bin is interpolated bilinearly at
    the event's pixel centre (as :meth:`FlareMaskNet.forward` upsamples it) and
    the event is kept where its keep probability :math:`\\sigma(\\ell + \\ln 3)`
    (:func:`keep_loss`'s) exceeds ``threshold``; at 1/2 that is
    :math:`\\min(1, 2\\sigma(\\ell)) > 1/2`, i.e. :math:`\\ell > -\\ln 3`. A lower
    threshold keeps more (of the scene, and of the flare).

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([0, 15], [1, 1], [1, 1], [1, 1])
    >>> lg = np.zeros((4, 1, 1), np.float32); lg[1] = -5.0   # drop ON events of bin 1
    >>> event_keep_mask(lg, ev, 0, 20, scale=4).tolist()
    [True, False]
    """
    n_ch, h, w = logits.shape
    bins = n_ch // 2
    b = ((events["t"] - int(window_start_us)) * bins) // int(window_us)
    channel = b + bins * (1 - events["p"].astype(np.int64))
    # align_corners=False: pixel centre x + 0.5 sits at (x + 0.5) / scale - 0.5 in cells.
    fx = np.clip((events["x"] + 0.5) / scale - 0.5, 0, w - 1)
    fy = np.clip((events["y"] + 0.5) / scale - 0.5, 0, h - 1)
    x0 = np.floor(fx).astype(np.int64)
    y0 = np.floor(fy).astype(np.int64)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    ax, ay = fx - x0, fy - y0
    flat = logits.reshape(n_ch, -1)
    base = channel
    v = (
        flat[base, y0 * w + x0] * (1 - ax) * (1 - ay)
        + flat[base, y0 * w + x1] * ax * (1 - ay)
        + flat[base, y1 * w + x0] * (1 - ax) * ay
        + flat[base, y1 * w + x1] * ax * ay
    )
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold must be in (0, 1), got {threshold}")
    return v > np.log(threshold / (1.0 - threshold)) - np.log(3.0)


def keep_loss(
    net: FlareMaskNet, x: torch.Tensor, y: torch.Tensor, keep_weight: float = 0.5
) -> torch.Tensor:
    r"""Class-balanced cross-entropy of the per-event keep decisions (training ``loss="keep"``).

    ``x`` is the input's voxel grid and ``y`` its keep-only target (the subset of
    the input's events to keep), both ``(N, 1, bins, H, W)``. In a cell of
    ``n`` input events of one polarity, ``k = min(n, y^\pm)`` are to be kept
    and ``n - k`` dropped; the network's keep probability there is
    :math:`p = \sigma(\ell + \ln 3)`, which exceeds 1/2 exactly where
    :func:`event_keep_mask` keeps. The events to keep weigh ``keep_weight``
    of the loss and those to drop the rest (half each by default), however
    rare the flare is in the batch: the mean-squared error of the voxel grids
    is dominated by the dense light cores and barely sees a scattered flare
    event. A ``keep_weight`` above 1/2 makes the mask drop only where it is
    surer (it keeps more of the scene and of the flare).

    Examples
    --------
    >>> net = FlareMaskNet(bins=2, scale=4, features=(8, 16), groups=4)
    >>> x = torch.zeros(1, 1, 2, 8, 8); x[0, 0, 0, 1, 1] = 3; x[0, 0, 1, 6, 6] = -1
    >>> y = x.clone(); y[0, 0, 1, 6, 6] = 0          # drop the OFF event, keep the 3 ON
    >>> # untrained: p = 3/4 everywhere, -(ln(3/4) + ln(1/4)) / 2
    >>> round(keep_loss(net, x, y).item(), 4)
    0.8370
    >>> round(keep_loss(net, x, y, keep_weight=0.75).item(), 4)  # -(3 ln(3/4) + ln(1/4)) / 4
    0.5623
    """
    z, g = x[:, 0].float(), y[:, 0].float()
    n = torch.cat([z.clamp(min=0), (-z).clamp(min=0)], 1)
    k = torch.minimum(torch.cat([g.clamp(min=0), (-g).clamp(min=0)], 1), n)
    logit = net.pixel_logits(x) + float(np.log(3.0))
    keep_term = (k * F.logsigmoid(logit)).sum() / k.sum().clamp(min=1)
    drop_term = ((n - k) * F.logsigmoid(-logit)).sum() / (n - k).sum().clamp(min=1)
    return -(keep_weight * keep_term + (1.0 - keep_weight) * drop_term)
