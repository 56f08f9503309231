"""The training loss of a flare mask: cross-entropy of keep decisions against the targets."""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from .flaremask import FlareMaskNet

__all__ = ["keep_loss"]


def keep_loss(
    net: FlareMaskNet,
    x: torch.Tensor,
    y: torch.Tensor,
    keep_weight: float = 0.5,
    cells: str = "bin",
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

    With ``cells="window"`` the counts are matched per pixel and polarity over
    the whole window instead of per bin: ``k = n min(N, Y) / N`` in each bin,
    with ``N`` and ``Y`` the window's totals. A scene edge that flare shifts by a
    bin is then kept, not dropped from one bin and missed in the next.

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
    if cells not in ("bin", "window"):
        raise ValueError(f"cells must be 'bin' or 'window', got {cells!r}")
    z, g = x[:, 0].float(), y[:, 0].float()
    n = torch.cat([z.clamp(min=0), (-z).clamp(min=0)], 1)
    target = torch.cat([g.clamp(min=0), (-g).clamp(min=0)], 1)
    if cells == "bin":
        k = torch.minimum(target, n)
    else:  # (N, 2 bins, H, W) -> per polarity, the window's totals
        shape = (n.shape[0], 2, n.shape[1] // 2, *n.shape[2:])
        total = n.reshape(shape).sum(2, keepdim=True)
        share = torch.minimum(target.reshape(shape).sum(2, keepdim=True), total)
        k = (n.reshape(shape) * share / total.clamp(min=1e-9)).reshape(n.shape)
    logit = net.pixel_logits(x) + float(np.log(3.0))
    keep_term = (k * F.logsigmoid(logit)).sum() / k.sum().clamp(min=1)
    drop_term = ((n - k) * F.logsigmoid(-logit)).sum() / (n - k).sum().clamp(min=1)
    return -(keep_weight * keep_term + (1.0 - keep_weight) * drop_term)
