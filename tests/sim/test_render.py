"""Tests of edeflare.sim.render: the flare and light videos of one script."""

from __future__ import annotations

import tracemalloc
import types

import numpy as np
import pytest
from test_flare import centroid, flare7k_tree

from edeflare.sim._validation import SimError
from edeflare.sim.flare import GhostSpec
from edeflare.sim.optics import PSFConfig
from edeflare.sim.render import Renderer, build_templates, flare7k_names, render
from edeflare.sim.script import Affine, FlareScript, Flicker, LightSpec, Trajectory, draw_script

SMALL_PSF = PSFConfig(grid=128, dust_count=10, wavelengths_nm=(500.0, 600.0))


def moving_script(**kw):
    base = dict(
        duration_us=40_000,
        fps=1000.0,
        trajectory=Trajectory(start=(0.3, 0.4), direction_deg=30.0, travel_px=60.0),
        affine=Affine(rotation_deg=40.0, scale=1.3, translate=(0.05, -0.1), shear_deg=15.0),
        light=LightSpec(radius_px=3.0, exposure=50.0, peak=220.0),
        psf=SMALL_PSF,
    )
    base.update(kw)
    return FlareScript(**base)


def test_the_light_follows_its_trajectory():
    script = moving_script()
    frames = list(render(script, (160, 120)))
    assert len(frames) == 41
    for t, flare, light in frames:
        x, y = script.position_px(t, (160, 120))
        assert centroid(light) == pytest.approx((x, y), abs=0.05)
        # the flare frame saturates around the light (the dust PSF is centro-symmetric)
        assert centroid(np.where(flare >= 0.99 * flare.max(), 1.0, 0.0)) == pytest.approx(
            (x, y), abs=0.5
        )
    # start (0.3 + 0.05, 0.4 - 0.1) of 160x120, then 60 px at 30 degrees
    assert script.position_px(0, (160, 120)) == pytest.approx((56.0, 36.0))
    end = script.position_px(40_000, (160, 120))
    assert end == pytest.approx((56.0 + 60 * np.cos(np.pi / 6), 36.0 + 60 * np.sin(np.pi / 6)))


@pytest.mark.parametrize(
    ("hz", "waveform"), [(120.0, "sine"), (100.0, "square"), (137.0, "triangle")]
)
def test_flicker_frequency_is_recovered_from_the_rendered_intensity(hz, waveform):
    script = moving_script(
        duration_us=250_000,
        fps=48 * hz,
        flicker=Flicker(frequency_hz=hz, waveform=waveform, depth=0.6, phase=0.3),
    )
    total = np.array([light.sum(dtype=np.float64) for _, _, light in render(script, (160, 120))])
    # Hann window, 16x zero padding: 0.24 Hz bins around the fundamental.
    padded = 16 * total.size
    spectrum = np.abs(np.fft.rfft((total - total.mean()) * np.hanning(total.size), padded))
    freqs = np.fft.rfftfreq(padded, 1 / script.fps)
    assert freqs[np.argmax(spectrum)] == pytest.approx(hz, abs=0.3)
    # the light's intensity is the flicker factor times a constant (to resampling accuracy)
    ratio = total / script.intensity(script.frame_times_us())
    assert np.allclose(ratio, ratio.mean(), rtol=0.01)


def test_without_flicker_the_light_energy_is_constant():
    frames = render(moving_script(), (160, 120))
    total = np.array([light.sum(dtype=np.float64) for _, _, light in frames])
    assert total.std() / total.mean() < 3e-3  # bilinear resampling under the affine map


def test_render_streams_float32_frames_without_holding_them():
    script = moving_script(duration_us=300_000, fps=1000.0)
    stream = render(script, (640, 480))
    assert isinstance(stream, types.GeneratorType) or hasattr(stream, "__next__")
    t0, flare, light = next(stream)
    assert t0 == 0 and flare.dtype == light.dtype == np.float32 and flare.shape == (480, 640)
    tracemalloc.start()
    count = 0
    for _t, _f, _l in stream:
        count += 1
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert count == 300
    assert peak < 8 * 1024 * 1024  # a few frames, never the 300 x 2 x 1.2 MB video


def test_ghosts_are_in_the_flare_video_only():
    ghosts = (
        GhostSpec(k=-1.0, radius_px=10.0, level=20.0),
        GhostSpec(k=0.5, radius_px=6.0, level=9.0),
    )
    script = moving_script(ghosts=ghosts, psf=PSFConfig(grid=64, wavelengths_nm=(550.0,)))
    t, flare, light = next(render(script, (160, 120)))
    x, y = script.position_px(t, (160, 120))
    gx, gy = 79.5 - (x - 79.5), 59.5 - (y - 59.5)  # k = -1: mirrored through the centre
    assert flare[round(gy), round(gx)] > 10.0  # 20 * (1 - hollow 0.3) = 14 in the centre
    assert light[round(gy), round(gx)] == 0.0
    yy, xx = np.mgrid[:120, :160]
    far = np.hypot(xx - x, yy - y) > 12  # radius 3 px, scaled 1.3x and sheared, blurred
    assert light[far].max() == 0.0
    assert flare[far].max() > 0.0


def test_frames_are_clipped_at_white_and_nonnegative():
    script = draw_script(rng=11)
    renderer = Renderer(script, (96, 72))
    for t in script.frame_times_us()[:20]:
        for img in renderer.frame(int(t)):
            assert img.min() >= 0 and img.max() <= 255


def test_clean_lens_ground_truth_adds_only_the_airy_glow():
    ideal = build_templates(moving_script(), (160, 120))
    clean = build_templates(moving_script(gt_lens="clean"), (160, 120))
    # The over-exposed source (50x white) shows the clean lens's Airy rings, but far less
    # light than the dusty lens scatters.
    assert clean.light.shape[0] > ideal.light.shape[0]
    assert ideal.light.sum() < clean.light.sum() < clean.flare.sum()
    assert clean.light.max() == ideal.light.max() == 220.0


def test_flare7k_assets_drive_the_templates(tmp_path):
    flare7k_tree(tmp_path)
    names = flare7k_names(tmp_path)
    assert names == [
        "Flare-R/Compound_Flare/a.png",
        "Flare7K/Scattering_Flare/Compound_Flare/000001.png",
    ]
    script = draw_script(rng=1, flare7k_names=names[1:])
    tp = build_templates(script, (32, 24), flare7k=tmp_path)
    # 12x16 images scaled to the sensor height (24): x2; grey 128 -> 255 (128/255)^gamma * peak/255
    g = script.flare7k.gamma
    assert tp.flare.shape == (24, 32)
    assert tp.flare[5, 5] == pytest.approx(
        255 * (128 / 255) ** g * script.light.peak / 255, rel=1e-4
    )
    assert tp.light_anchor == pytest.approx((15.5, 11.5), abs=0.01)  # uniform image: its centre
    with pytest.raises(SimError, match="pass the folder holding it"):
        build_templates(script, (32, 24))
    frames = list(render(script, (32, 24), flare7k=tmp_path))
    assert len(frames) == script.frame_times_us().size
