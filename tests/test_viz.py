"""Pictures: exact pixel colours, grid geometry, voxel shading, GIF/MP4 files that decode."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from edeflare.errors import EdeflareError, EventsError
from edeflare.events import make_events
from edeflare.viz import (
    OFF_COLOR,
    ON_COLOR,
    event_frame,
    grid,
    save_animation,
    save_image,
    voxel_montage,
)


def test_event_frame_colours_by_net_polarity():
    # (0,0): 2 ON 1 OFF -> red; (1,0): 1 ON 2 OFF -> blue; (2,0): 1 ON 1 OFF -> mix; (0,1) empty.
    ev = make_events(
        [0, 1, 2, 3, 4, 5, 6, 7],
        [0, 0, 0, 1, 1, 1, 2, 2],
        [0, 0, 0, 0, 0, 0, 0, 0],
        [1, 1, 0, 1, 0, 0, 1, 0],
    )
    img = event_frame(ev, (3, 2))
    assert img.shape == (2, 3, 3) and img.dtype == np.uint8
    assert tuple(img[0, 0]) == ON_COLOR
    assert tuple(img[0, 1]) == OFF_COLOR
    assert tuple(img[0, 2]) == tuple((a + b) // 2 for a, b in zip(ON_COLOR, OFF_COLOR, strict=True))
    assert tuple(img[1, 0]) == (255, 255, 255)
    dark = event_frame(ev, (3, 2), background="black")
    assert tuple(dark[1, 2]) == (0, 0, 0)


def test_event_frame_rejects_bad_input():
    ev = make_events([0], [5], [0], [1])
    with pytest.raises(EventsError, match="x out of range"):
        event_frame(ev, (5, 1))
    with pytest.raises(EdeflareError, match="background"):
        event_frame(ev, (6, 1), background="grey")


def test_event_frame_does_not_modify_input():
    ev = make_events([0, 1], [0, 1], [0, 1], [1, 0])
    before = ev.copy()
    event_frame(ev, (2, 2))
    assert np.array_equal(ev, before)


def test_grid_places_images_row_major_with_padding():
    red = np.zeros((10, 20, 3), np.uint8)
    red[..., 0] = 255
    green = np.zeros((10, 20, 3), np.uint8)
    green[..., 1] = 255
    out = grid([red, green, green, red], ncols=2, pad=4)
    # 2 columns of 20 px + 3 pads; 2 rows of 10 px + 3 pads; no labels.
    assert out.shape == (2 * 10 + 3 * 4, 2 * 20 + 3 * 4, 3)
    assert tuple(out[4, 4]) == (255, 0, 0)  # first cell starts after one pad
    assert tuple(out[4, 4 + 20 + 4]) == (0, 255, 0)  # second column
    assert tuple(out[4 + 10 + 4, 4]) == (0, 255, 0)  # second row, first column
    assert tuple(out[0, 0]) == (255, 255, 255)  # padding keeps the background


def test_grid_labels_add_a_title_band_with_text():
    im = np.full((10, 30, 3), 255, np.uint8)
    plain = grid([im, im])
    titled = grid([im, im], labels=["input", "output"], font_size=14)
    assert titled.shape[0] == plain.shape[0] + 14 + 2 * 4
    band = titled[: 14 + 2 * 4]
    assert (band < 128).any()  # some dark text was drawn
    with pytest.raises(EdeflareError):
        grid([])


def test_voxel_montage_shades_sign_and_labels_bins():
    v = np.zeros((2, 4, 5), np.float32)
    v[0, 1, 2] = 3.0
    v[1, 3, 4] = -3.0
    out = voxel_montage(v, vmax=3.0)
    assert out.dtype == np.uint8 and out.ndim == 3
    colours = {tuple(c) for c in out.reshape(-1, 3)}
    assert ON_COLOR in colours and OFF_COLOR in colours
    half = voxel_montage(v, vmax=6.0)  # half intensity: between white and the colour
    mid_on = tuple(round(255 + 0.5 * (c - 255)) for c in ON_COLOR)
    assert mid_on in {tuple(c) for c in half.reshape(-1, 3)}
    with pytest.raises(EdeflareError):
        voxel_montage(np.full((1, 2, 2), np.nan))
    with pytest.raises(EdeflareError):
        voxel_montage(np.zeros((2, 2)))


def test_save_image_round_trip(tmp_path):
    img = np.random.default_rng(0).integers(0, 255, (7, 9, 3), dtype=np.uint8)
    path = tmp_path / "x.png"
    save_image(path, img)
    assert np.array_equal(np.asarray(Image.open(path)), img)
    assert [p.name for p in tmp_path.iterdir()] == ["x.png"]  # no temporary left


def test_gif_has_every_frame(tmp_path):
    frames = [np.full((8, 8, 3), v, np.uint8) for v in (0, 128, 255)]
    path = tmp_path / "a.gif"
    save_animation(path, frames, fps=5)
    with Image.open(path) as im:
        assert im.n_frames == 3
        assert im.info["duration"] == 200


def test_mp4_decodes_with_padded_size(tmp_path):
    frames = [np.full((30, 50, 3), v, np.uint8) for v in (0, 255, 0, 255)]
    path = tmp_path / "a.mp4"
    save_animation(path, frames, fps=4)
    video = _read_mp4(path, width=64, height=32)  # padded to multiples of 16
    assert len(video) == 4
    assert video[1][:30, :50].mean() > 200 > video[0][:30, :50].mean()


def test_animation_rejects_empty_and_unknown(tmp_path):
    with pytest.raises(EdeflareError):
        save_animation(tmp_path / "a.gif", [])
    with pytest.raises(EdeflareError):
        save_animation(tmp_path / "a.avi", [np.zeros((4, 4, 3), np.uint8)])
    assert list(tmp_path.iterdir()) == []


def _read_mp4(path, width, height):
    """Decode with the ffmpeg binary shipped by imageio-ffmpeg into (n, H, W, 3) frames."""
    import subprocess

    import imageio_ffmpeg

    probe = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-i", str(path)], capture_output=True, text=True
    )
    assert f"{width}x{height}" in probe.stderr
    raw = subprocess.run(
        [
            imageio_ffmpeg.get_ffmpeg_exe(),
            "-v",
            "error",
            "-i",
            str(path),
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-",
        ],
        capture_output=True,
        check=True,
    ).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, height, width, 3)
