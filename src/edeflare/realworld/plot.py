"""The alignment picture: both signatures before and after alignment, and the correlation."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .align import Alignment, estimate_offset  # noqa: F401  (estimate_offset: doctest)
from .signature import Signature

_OBS_COLOR = (230, 120, 20)
_REF_COLOR = (20, 110, 200)


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=size)


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not hi > lo:
        return [lo]
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step) * step
    return [first + i * step for i in range(int((hi - first) / step) + 1)]


def _panel(
    draw: ImageDraw.ImageDraw,
    box: tuple[int, int, int, int],
    series: Sequence[tuple[np.ndarray, np.ndarray, tuple[int, int, int], str]],
    xlim: tuple[float, float],
    ylim: tuple[float, float],
    title: str,
    xlabel: str,
    vline: float | None = None,
) -> None:
    x0, y0, x1, y1 = box
    font, small = _font(14), _font(12)
    draw.text((x0, y0 - 20), title, fill=(0, 0, 0), font=font)
    draw.rectangle(box, outline=(0, 0, 0))
    (xa, xb), (ya, yb) = xlim, ylim

    def px(x: np.ndarray) -> np.ndarray:
        return x0 + (np.asarray(x, dtype=np.float64) - xa) / (xb - xa or 1) * (x1 - x0)

    def py(y: np.ndarray) -> np.ndarray:
        return y1 - (np.asarray(y, dtype=np.float64) - ya) / (yb - ya or 1) * (y1 - y0)

    for tx in _ticks(xa, xb):
        u = float(px(tx))
        draw.line([(u, y1), (u, y1 + 4)], fill=(0, 0, 0))
        draw.text((u, y1 + 6), f"{tx:g}", fill=(0, 0, 0), font=small, anchor="mt")
    for ty in _ticks(ya, yb, 4):
        v = float(py(ty))
        draw.line([(x0 - 4, v), (x0, v)], fill=(0, 0, 0))
        draw.line([(x0, v), (x1, v)], fill=(230, 230, 230))
        draw.text((x0 - 6, v), f"{ty:g}", fill=(0, 0, 0), font=small, anchor="rm")
    draw.text(((x0 + x1) / 2, y1 + 22), xlabel, fill=(0, 0, 0), font=small, anchor="mt")
    if vline is not None and xa <= vline <= xb:
        u = float(px(vline))
        draw.line([(u, y0), (u, y1)], fill=(120, 120, 120), width=1)
    legend_x = float(x1)
    for _, _, color, label in reversed(series):  # legend in the title row, right-aligned
        if label:
            draw.text((legend_x, y0 - 20), label, fill=color, font=font, anchor="ra")
            legend_x -= font.getlength(label) + 16
    for k, (xs, ys, color, _) in enumerate(series):
        keep = np.isfinite(ys) & (xs >= xa) & (xs <= xb)
        pts = list(
            zip(
                px(xs[keep]).tolist(),
                np.clip(py(ys[keep]), y0, y1).tolist(),
                strict=True,
            )
        )
        if len(pts) > 1:
            draw.line(pts, fill=color, width=2 if k == 0 else 1)


def plot_alignment(
    obs: Signature,
    ref: Signature,
    alignment: Alignment,
    path: str | os.PathLike[str] | None = None,
    *,
    span_us: int | None = None,
    expected_offset_us: float | None = None,
    pseudocount: float = 4.0,
) -> np.ndarray:
    """Picture both signatures before and after alignment, and the correlation curve.

    Top: the ON fraction of both passes over ``span_us`` (default 40 coarse
    bins) with the reference placed by ``expected_offset_us`` (default: the
    recordings' starts aligned); middle: the same with the reference shifted
    by the found offset; bottom: correlation against offset. The span is
    where the observation's polarity activity is strongest.

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 3)``; also written to ``path`` (PNG) when given.

    Examples
    --------
    >>> sig = Signature(0, 100, np.array([5, 0, 0, 5] * 50), np.array([0, 5, 0, 0] * 50))
    >>> a = estimate_offset(sig, sig, max_offset_us=2_000)
    >>> plot_alignment(sig, sig, a).shape
    (760, 1000, 3)
    """
    fine = obs.bin_us
    span = int(span_us) if span_us is not None else 40 * alignment.bin_us
    span = max(span, 4 * fine)
    prior = ref.t_start_us - obs.t_start_us if expected_offset_us is None else expected_offset_us
    offset = alignment.offset_us
    # Where to look: the span of the observation with the most polarity activity.
    activity = np.abs(obs.on.astype(np.float64) - obs.off)
    n_span = max(1, min(obs.n_bins, span // fine))
    csum = np.concatenate([[0.0], np.cumsum(activity)])
    moving = csum[n_span:] - csum[:-n_span]
    start_bin = int(np.argmax(moving)) if moving.size else 0
    t0 = obs.t_start_us + start_bin * fine
    fo, fr = obs.on_fraction(pseudocount), ref.on_fraction(pseudocount)
    xo = (obs.t_start_us + (np.arange(obs.n_bins) + 0.5) * fine - t0) / 1000
    xr_ref = ref.t_start_us + (np.arange(ref.n_bins) + 0.5) * fine - t0
    width, height = 1000, 760
    canvas = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    xlim = (0.0, span / 1000)
    labels = ("observation (filter)", "reference")
    for k, (shift, title) in enumerate(
        (
            (prior, f"before: reference shifted by {prior / 1000:.3f} ms"),
            (offset, f"after alignment: reference shifted by {offset / 1000:.3f} ms"),
        )
    ):
        box = (70, 40 + k * 240, width - 30, 40 + k * 240 + 170)
        _panel(
            draw,
            box,
            [
                (xo, fo, _OBS_COLOR, labels[0]),
                ((xr_ref - shift) / 1000, fr, _REF_COLOR, labels[1]),
            ],
            xlim,
            (0.0, 1.0),
            title,
            f"time (ms) from t = {t0} us of the observation; y: ON fraction",
        )
    lags = alignment.lags_us / 1000
    scores = alignment.scores
    finite = scores[np.isfinite(scores)]
    ylo = min(0.0, float(finite.min())) if finite.size else -1.0
    second = alignment.second_peak
    title = (
        f"correlation vs offset: peak {alignment.correlation:.3f} at {offset / 1000:.3f} ms, "
        f"second peak {second:.3f}, confidence {alignment.confidence:.3f}"
        if math.isfinite(second)
        else f"correlation vs offset: peak {alignment.correlation:.3f} at {offset / 1000:.3f} ms, "
        f"confidence {alignment.confidence:.3f}"
    )
    xl = (
        (float(lags[0]), float(lags[-1]))
        if lags.size > 1
        else (offset / 1000 - 1, offset / 1000 + 1)
    )
    _panel(
        draw,
        (70, 40 + 2 * 240, width - 30, 40 + 2 * 240 + 170),
        [(lags, scores, (40, 40, 40), "")],
        xl,
        (ylo, 1.0),
        title,
        "offset t_reference - t_observation (ms)",
        vline=offset / 1000,
    )
    image = np.asarray(canvas)
    if path is not None:
        from ..viz import save_image

        save_image(path, image)
    return image
