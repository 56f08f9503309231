"""Downstream check: does de-flaring help image reconstruction?

The paper reconstructs video from events (E2VID) before and after
de-flaring. Here each stream (the input, every method's output, the ground
truth's events) is reconstructed by the bundled recurrent network
(:class:`edeflare.recon.infer.Reconstructor`) window by window, and each
image at a window's end is scored against the simulator's flare-free image
of that instant (:func:`edeflare.io.sequence.read_frames`, mapped like the
network's training targets: log intensity by
:func:`edeflare.recon.clips.intensity_to_image`). Events never tell the
absolute brightness, so both images are first shifted to mean 0.5
(:func:`edeflare.recon.clips.centre_image`), then:

- **PSNR** ``10 log10(1 / MSE)`` of the images in ``[0, 1]``;
- **SSIM** (:func:`skimage.metrics.structural_similarity`, ``data_range=1``);
- the **flare-region error**: the RMS difference of the two centred images over the
  flare annulus around the light (:class:`~edeflare.eval.flare_score.FlareGeometry`
  located on the clean image of the same instant by
  :func:`~edeflare.eval.flare_score.flare_geometry`: from the source radius out to
  0.4 of the short side), where flare in the events shows up as false glow or
  streaks in the image. The no-reference flare score
  (:func:`~edeflare.eval.flare_score.flare_score`) is no use on these images: a
  light that does not change makes no events, so a reconstruction hardly shows the
  source, and its energy (the score's denominator) is noise.

The first :data:`~edeflare.recon.clips.BURN_IN` windows of each sequence are
not scored: the network has seen too few events to know the scene. Means are
over the scored windows of all sequences.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import EdeflareError
from ..events import concat_events
from ..recon.clips import centre_image, intensity_to_image
from .flare_score import flare_geometry

__all__ = [
    "CleanFrame",
    "DownstreamScores",
    "RealReconstruction",
    "image_scores",
    "reconstruct_recording",
]


def image_scores(image: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """``(PSNR dB, SSIM)`` of an image in ``[0, 1]`` against a reference in ``[0, 1]``.

    Examples
    --------
    >>> ref = np.linspace(0, 1, 64 * 64).reshape(64, 64)
    >>> psnr, ssim = image_scores(ref + 0.1, ref)
    >>> round(psnr, 6), ssim > 0.9
    (20.0, True)
    """
    from skimage.metrics import structural_similarity

    image = np.asarray(image, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    mse = float(np.mean((image - reference) ** 2))
    psnr = math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)
    side = min(reference.shape)
    win = min(7, side if side % 2 else side - 1)
    ssim = float(structural_similarity(image, reference, data_range=1.0, win_size=win))
    return psnr, ssim


@dataclass(frozen=True)
class CleanFrame:
    """A clean frame prepared for scoring: mapped and centred like a reconstruction, and
    the flare annulus around its light. Made once per frame, used by every stream.

    Examples
    --------
    >>> clean = np.full((40, 60), 0.05); clean[19:22, 29:32] = 1.0
    >>> ref = CleanFrame.of(clean)
    >>> round(float(ref.image.mean()), 6), int(ref.annulus.sum()) > 0
    (0.5, True)
    """

    image: np.ndarray
    annulus: np.ndarray

    @classmethod
    def of(cls, intensity: np.ndarray) -> CleanFrame:
        """From a clean intensity image (:func:`~edeflare.recon.clips.intensity_to_image`,
        centred; the annulus of :func:`~edeflare.eval.flare_score.flare_geometry`)."""
        image = centre_image(intensity_to_image(intensity))
        _, annulus, _ = flare_geometry(image).masks(image.shape)
        return cls(image, annulus)


@dataclass
class DownstreamScores:
    """PSNR, SSIM and flare-region error per scored window of one stream kind (a
    method, the input, the GT).

    Examples
    --------
    >>> clean = np.full((40, 60), 0.05); clean[19:22, 29:32] = 1.0   # a lamp in the dark
    >>> image = intensity_to_image(clean)
    >>> flared = image.copy(); flared[20, 5:55] = image.max()          # and a streak
    >>> s = DownstreamScores(); s.add(image, clean); s.add(flared, clean)
    >>> s.flare[0], s.flare[1] > 0.0, s.means()["windows"]   # the streak's error, in the annulus
    (0.0, True, 2)
    """

    psnr: list[float] = field(default_factory=list)
    ssim: list[float] = field(default_factory=list)
    flare: list[float] = field(default_factory=list)

    def add(self, image: np.ndarray, intensity: np.ndarray | CleanFrame) -> None:
        """Score one reconstructed image against the clean intensity image of its instant
        (or that image already prepared, :class:`CleanFrame`)."""
        clean = intensity if isinstance(intensity, CleanFrame) else CleanFrame.of(intensity)
        mine = centre_image(image)
        psnr, ssim = image_scores(mine, clean.image)
        self.psnr.append(psnr)
        self.ssim.append(ssim)
        diff = (np.asarray(mine, np.float64) - clean.image)[clean.annulus]
        self.flare.append(float(np.sqrt(np.mean(diff**2))) if diff.size else math.nan)

    def means(self) -> dict[str, float]:
        """``{"psnr", "ssim", "flare", "windows"}`` (``flare``: the flare-region RMS
        error), means over the scored windows (NaN without any)."""
        n = len(self.psnr)
        flare = [f for f in self.flare if math.isfinite(f)]
        return {
            "psnr": float(np.mean(self.psnr)) if n else math.nan,
            "ssim": float(np.mean(self.ssim)) if n else math.nan,
            "flare": float(np.mean(flare)) if flare else math.nan,
            "windows": n,
        }


@dataclass
class RealReconstruction:
    """Reconstructions of one real recording before and after de-flaring (no reference).

    Attributes
    ----------
    name : str
        The recording's file name.
    columns : list of str
        ``"input events"``, then one column per stream: ``"input"`` and each method.
    image : numpy.ndarray
        ``(H, W, 3)`` uint8 figure: the last complete window's input events, then
        each stream's reconstruction at that window's end.
    events : dict of str to int
        Events of each stream over the reconstructed span.
    span_us : tuple of int
        ``(start, end)`` of the reconstructed span.
    """

    name: str
    columns: list[str]
    image: np.ndarray
    events: dict[str, int]
    span_us: tuple[int, int]


def reconstruct_recording(
    path: str | os.PathLike[str],
    methods: Mapping[str, Any],
    *,
    max_span_us: int = 2_000_000,
    window_us: int = 20_000,
) -> RealReconstruction:
    """Reconstruct a real recording and every method's output of it (qualitative).

    The first ``max_span_us`` of the recording (whole if shorter; a long file is
    not read past it) go through each method in memory (``methods``: column
    label to a method name or :class:`~edeflare.methods.Method`), and every
    stream through the bundled reconstructor over aligned ``window_us``
    windows from the first event. Real recordings have no flare-free image: the
    figure is to look at, as the paper's real-data reconstructions are.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from edeflare.events import make_events
    >>> from edeflare.io import write_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "rec.h5"
    >>> ev = make_events([0, 25_000, 45_000], [1, 2, 3], [1, 1, 2], [1, 0, 1])
    >>> write_events(path, ev, (8, 6))
    >>> r = reconstruct_recording(path, {"raw": "raw"})
    >>> r.columns, r.events, r.span_us
    (['input events', 'input', 'raw'], {'input': 3, 'raw': 3}, (0, 40000))
    """
    from ..events import window_start_for
    from ..io import open_events
    from ..methods import Method, create_method
    from ..recon.infer import reconstruct_events
    from ..viz import event_frame, grid

    source = open_events(path)
    size = source.sensor_size
    first = source.first_time_us()
    if first is None:
        raise EdeflareError(f"{path}: no events to reconstruct")
    start = window_start_for(first, window_us)
    chunks = [ev for _, ev in source.windows(window_us, end_us=start + max_span_us)]
    events = concat_events(chunks)
    streams = {"input": events}
    for label, method in methods.items():
        m = method if isinstance(method, Method) else create_method(method)
        streams[label] = m(events, size, rng=0)
    # the last window the span covers completely (at least one)
    end = start + window_us * max(1, (int(events["t"][-1]) + 1 - start) // window_us)
    last = events[(events["t"] >= end - window_us) & (events["t"] < end)]
    cells = [event_frame(last, size)]
    for stream in streams.values():
        _, images = reconstruct_events(stream, size, start_us=start, end_us=end)
        gray = np.clip(np.round(images[-1] * 255.0), 0, 255).astype(np.uint8)
        cells.append(np.repeat(gray[:, :, None], 3, axis=2))
    columns = ["input events", *streams]
    labels = [f"input events (last {window_us / 1000:g} ms)", *streams]
    return RealReconstruction(
        Path(path).name,
        columns,
        grid(cells, labels=labels, ncols=len(cells)),
        {k: int(v.size) for k, v in streams.items()},
        (start, end),
    )
