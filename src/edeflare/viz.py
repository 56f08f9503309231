"""Pictures of events: frames (ON red, OFF blue), labelled grids, voxel montages, GIF/MP4.

All images are ``uint8`` arrays of shape ``(H, W, 3)``; nothing here changes
its inputs. Files are written atomically.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .errors import EdeflareError
from .events import SensorSize, check_events, check_sensor_size, count_map
from .io._atomic import atomic_path

__all__ = [
    "OFF_COLOR",
    "ON_COLOR",
    "event_frame",
    "grid",
    "save_animation",
    "save_image",
    "voxel_montage",
]

ON_COLOR = (220, 30, 30)
"""Red, for ON events (brightness up), as in the paper's figures."""
OFF_COLOR = (30, 70, 220)
"""Blue, for OFF events."""

_BACKGROUNDS = {"white": (255, 255, 255), "black": (0, 0, 0)}


def event_frame(
    events: np.ndarray,
    sensor_size: SensorSize,
    *,
    background: str = "white",
) -> np.ndarray:
    """Render events as an RGB frame: a pixel is red if ON events dominate, blue if OFF do.

    Pixels with as many ON as OFF events are drawn in the mix of both
    colours; pixels without events keep the background.

    Parameters
    ----------
    events : numpy.ndarray
        Events (usually one window).
    sensor_size : (width, height)
    background : {"white", "black"}

    Returns
    -------
    numpy.ndarray
        ``uint8`` ``(H, W, 3)``.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> img = event_frame(make_events([0, 1], [0, 1], [0, 0], [1, 0]), (2, 1))
    >>> img[0, 0].tolist(), img[0, 1].tolist()
    ([220, 30, 30], [30, 70, 220])
    """
    check_events(events, sensor_size)
    width, height = check_sensor_size(sensor_size)
    if background not in _BACKGROUNDS:
        raise EdeflareError(f"background must be one of {sorted(_BACKGROUNDS)}, got {background!r}")
    net = count_map(events, (width, height), signed=True)
    hit = count_map(events, (width, height)) > 0
    img = np.empty((height, width, 3), dtype=np.uint8)
    img[:] = _BACKGROUNDS[background]
    img[net > 0] = ON_COLOR
    img[net < 0] = OFF_COLOR
    img[hit & (net == 0)] = tuple((a + b) // 2 for a, b in zip(ON_COLOR, OFF_COLOR, strict=True))
    return img


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=size)


def grid(
    images: Sequence[np.ndarray],
    *,
    labels: Sequence[str] | None = None,
    ncols: int | None = None,
    row_labels: Sequence[str] | None = None,
    captions: Sequence[str] | None = None,
    pad: int = 4,
    font_size: int = 14,
    background: tuple[int, int, int] = (255, 255, 255),
) -> np.ndarray:
    """Tile images into a labelled grid (e.g. columns input / method / ground truth).

    Parameters
    ----------
    images : sequence of ``(H, W, 3)`` uint8 arrays
        Row-major; sizes may differ (each cell is as large as the largest image).
    labels : sequence of str, optional
        Column titles (one per column) drawn above the first row.
    ncols : int, optional
        Columns; defaults to ``len(labels)`` or ``len(images)``.
    row_labels : sequence of str, optional
        Titles drawn at the left of each row.
    captions : sequence of str, optional
        One caption per image, drawn above it.

    Examples
    --------
    >>> a = np.zeros((10, 20, 3), np.uint8)
    >>> grid([a, a, a, a], labels=["in", "out"]).shape[1] > 40
    True
    """
    if not images:
        raise EdeflareError("grid needs at least one image")
    ncols = ncols or (len(labels) if labels else len(images))
    nrows = -(-len(images) // ncols)
    cell_h = max(im.shape[0] for im in images)
    cell_w = max(im.shape[1] for im in images)
    font = _font(font_size)
    top = font_size + 2 * pad if labels else 0
    cap = font_size + pad if captions else 0
    cell_h += cap
    left = 0
    if row_labels:
        left = max(int(font.getlength(str(s))) for s in row_labels) + 2 * pad
    height = top + nrows * (cell_h + pad) + pad
    width = left + ncols * (cell_w + pad) + pad
    canvas = Image.new("RGB", (width, height), background)
    draw = ImageDraw.Draw(canvas)
    for i, im in enumerate(images):
        r, c = divmod(i, ncols)
        x0 = left + pad + c * (cell_w + pad)
        y0 = top + pad + r * (cell_h + pad)
        canvas.paste(
            Image.fromarray(np.ascontiguousarray(im[..., :3]).astype(np.uint8)), (x0, y0 + cap)
        )
        if captions:
            draw.text(
                (x0 + cell_w / 2, y0), str(captions[i]), fill=(0, 0, 0), font=font, anchor="mt"
            )
    for c, text in enumerate(labels or []):
        x0 = left + pad + c * (cell_w + pad)
        draw.text((x0 + cell_w / 2, pad), str(text), fill=(0, 0, 0), font=font, anchor="mt")
    for r, text in enumerate(row_labels or []):
        y0 = top + pad + r * (cell_h + pad)
        draw.text((pad, y0 + cell_h / 2), str(text), fill=(0, 0, 0), font=font, anchor="lm")
    return np.asarray(canvas)


def voxel_montage(
    voxel: np.ndarray,
    *,
    vmax: float | None = None,
    ncols: int | None = None,
) -> np.ndarray:
    """Show the bins of a voxel grid ``(B, H, W)`` side by side, labelled ``bin k``.

    Positive cells (net ON) shade to red, negative (net OFF) to blue, zero is
    white; ``vmax`` is full colour (default: the 99th percentile of the
    non-zero magnitudes, at least 1, so a few hot pixels do not wash out the rest).

    Examples
    --------
    >>> v = np.zeros((2, 3, 4), np.float32); v[0, 1, 2] = 2; v[1, 0, 0] = -1
    >>> voxel_montage(v).dtype
    dtype('uint8')
    """
    voxel = np.asarray(voxel, dtype=np.float64)
    if voxel.ndim != 3:
        raise EdeflareError(f"voxel must have shape (bins, H, W), got {voxel.shape}")
    if not np.isfinite(voxel).all():
        raise EdeflareError("voxel contains NaN or infinity")
    if vmax:
        scale = float(vmax)
    else:
        nonzero = np.abs(voxel[voxel != 0])
        scale = max(1.0, float(np.percentile(nonzero, 99))) if nonzero.size else 1.0
    a = np.clip(voxel / scale, -1.0, 1.0)[..., None]
    white = np.array([255.0, 255.0, 255.0])
    on = np.array(ON_COLOR, dtype=np.float64)
    off = np.array(OFF_COLOR, dtype=np.float64)
    rgb = np.where(a > 0, white + a * (on - white), white + (-a) * (off - white))
    tiles = [np.round(t).astype(np.uint8) for t in rgb]
    captions = [f"bin {k}" for k in range(len(tiles))]
    return grid(tiles, captions=captions, ncols=ncols or len(tiles), background=(200, 200, 200))


def save_image(path: str | os.PathLike[str], image: np.ndarray) -> None:
    """Write an image (PNG/JPEG/... by suffix) atomically.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "f.png"
    >>> save_image(p, np.zeros((4, 4, 3), np.uint8)); p.exists()
    True
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        Image.fromarray(np.asarray(image, dtype=np.uint8)).save(tmp, format=_pil_format(path))


def _pil_format(path: Path) -> str:
    ext = path.suffix.lower().lstrip(".")
    return {"jpg": "JPEG", "jpeg": "JPEG", "tif": "TIFF", "tiff": "TIFF"}.get(ext, ext.upper())


def _pad_to(image: np.ndarray, multiple: int) -> np.ndarray:
    h, w = image.shape[:2]
    ph, pw = (-h) % multiple, (-w) % multiple
    if ph == 0 and pw == 0:
        return image
    return np.pad(image, ((0, ph), (0, pw), (0, 0)), constant_values=255)


def save_animation(
    path: str | os.PathLike[str], frames: Iterable[np.ndarray], fps: float = 10.0
) -> None:
    """Write frames as an animated ``.gif`` (looping) or an H.264 ``.mp4``, atomically.

    MP4 frames are padded with white to multiples of 16 pixels (the codec's
    macro block); the encoder is the ``ffmpeg`` binary shipped with
    ``imageio-ffmpeg``. ``frames`` may be a generator: an MP4 is encoded as
    they come (one frame in memory), a GIF collects them first.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "a.gif"
    >>> save_animation(p, [np.zeros((4, 4, 3), np.uint8)] * 2); p.exists()
    True
    """
    import imageio.v2 as imageio

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise EdeflareError(f"{path}: animations are .gif or .mp4, got {suffix!r}")
    frames = iter(frames)
    first = next(frames, None)
    if first is None:
        raise EdeflareError(f"{path}: no frames to write")
    with atomic_path(path) as tmp:
        if suffix == ".gif":
            pil = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in (first, *frames)]
            pil[0].save(
                tmp,
                format="GIF",
                save_all=True,
                append_images=pil[1:],
                duration=max(20, round(1000 / fps)),
                loop=0,
            )
        else:
            writer = imageio.get_writer(
                tmp,
                format="FFMPEG",
                mode="I",
                fps=fps,
                codec="libx264",
                macro_block_size=16,
                ffmpeg_log_level="error",
                pixelformat="yuv420p",
            )
            try:
                writer.append_data(_pad_to(np.asarray(first, dtype=np.uint8), 16))
                for f in frames:
                    writer.append_data(_pad_to(np.asarray(f, dtype=np.uint8), 16))
            finally:
                writer.close()
