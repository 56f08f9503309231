"""Tests of edeflare.sim.flare: light source, scattering flare, glare, ghosts, Flare7K++ assets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from edeflare.errors import EventFileError
from edeflare.sim._validation import SimError
from edeflare.sim.flare import (
    GhostSpec,
    GlareSpec,
    find_flare7k_pairs,
    glare,
    light_source,
    load_flare7k_pair,
    render_ghosts,
    scattering_flare,
)


def centroid(img):
    yy, xx = np.mgrid[: img.shape[0], : img.shape[1]]
    total = img.sum(dtype=np.float64)
    return float((xx * img).sum() / total), float((yy * img).sum() / total)


def test_light_source_disc_and_gaussian_have_the_right_energy_and_centre():
    disc = light_source((40, 50), (20.3, 17.6), 5.0, level=200.0)
    assert disc.dtype == np.float32 and disc.shape == (40, 50)
    assert disc.max() == 200.0
    assert disc.sum() == pytest.approx(200.0 * math.pi * 25, rel=0.01)  # level * pi r^2
    assert centroid(disc) == pytest.approx((20.3, 17.6), abs=0.03)  # sampled soft edge
    gauss = light_source((60, 60), (30.0, 29.0), 3.0, level=10.0, profile="gaussian")
    assert gauss.sum() == pytest.approx(10.0 * 2 * math.pi * 9, rel=1e-3)  # level * 2 pi sigma^2
    with pytest.raises(SimError, match="profile must be 'disc' or 'gaussian'"):
        light_source((4, 4), (1, 1), 1.0, profile="square")
    with pytest.raises(SimError, match=r"radius_px must lie in \(0"):
        light_source((4, 4), (1, 1), 0.0)


def test_scattering_flare_of_a_point_is_the_psf_and_conserves_energy(rng):
    psf = rng.random((31, 31))
    psf /= psf.sum()
    light = np.zeros((80, 90))
    light[40, 50] = 1000.0
    out = scattering_flare(light, psf)
    assert out.dtype == np.float32
    assert np.allclose(out[25:56, 35:66], 1000.0 * psf, rtol=1e-5, atol=1e-6)
    assert out.sum() == pytest.approx(1000.0, rel=1e-5)
    # Linear: two sources give the sum of their flares.
    other = np.zeros_like(light)
    other[10, 20] = 300.0
    both = scattering_flare(light + other, psf)
    assert np.allclose(both, out + scattering_flare(other, psf), atol=1e-3)


def test_glare_has_a_one_over_r_core_and_streaks_at_the_given_angles():
    spec = GlareSpec(level=40.0, core_px=4.0, streaks=4, streak_gain=3.0, rotation_deg=10.0)
    g = glare((201, 201), (100, 100), spec)
    plain = glare((201, 201), (100, 100), GlareSpec(level=40.0, core_px=4.0))
    assert plain[100, 112] == pytest.approx(40.0 * 4 / (4 + 12))  # 1/r: a quarter at r = 3 core
    assert plain[100, 160] == pytest.approx(40.0 * 4 / 64)
    # Along a streak the glare is (1 + gain) times the plain core; between streaks it is not.
    for angle in (10.0, 100.0, 190.0, 280.0):
        x = 100 + 60 * math.cos(math.radians(angle))
        y = 100 + 60 * math.sin(math.radians(angle))
        ix, iy = round(x), round(y)
        assert g[iy, ix] > 2.5 * plain[iy, ix]
    ix, iy = (
        round(100 + 60 * math.cos(math.radians(55))),
        round(100 + 60 * math.sin(math.radians(55))),
    )
    assert g[iy, ix] == pytest.approx(plain[iy, ix], rel=1e-3)


@pytest.mark.parametrize("k", [-4.0, -1.5, 0.4, 1.0])
def test_ghosts_lie_on_the_line_through_the_centre_and_the_light(k):
    img = np.zeros((300, 400), dtype=np.float32)
    light = (290.0, 60.0)
    centre = (199.5, 149.5)
    render_ghosts(img, light, [GhostSpec(k=k, radius_px=6.0, level=10.0, fringe=0.0)])
    expected = (centre[0] + k * (light[0] - centre[0]), centre[1] + k * (light[1] - centre[1]))
    inside = 6 < expected[0] < 394 and 6 < expected[1] < 294
    if inside:
        assert centroid(img) == pytest.approx(expected, abs=0.05)
    else:
        assert img.sum() == 0 or centroid(img) != pytest.approx(expected, abs=1)


def test_ghost_profile_is_dimmer_in_the_centre_and_has_colour_fringes():
    img = np.zeros((101, 101), dtype=np.float32)
    spec = GhostSpec(k=1.0, radius_px=20.0, level=12.0, softness=0.1, hollow=0.5, fringe=0.0)
    render_ghosts(img, (50, 50), [spec], center_xy=(50, 50))
    assert img[50, 50] == pytest.approx(12.0 * 0.5)  # centre: level * (1 - hollow)
    assert img[50, 50 + 18] == pytest.approx(12.0 * (1 - 0.5 * (1 - 0.9**2)), rel=1e-5)
    assert img[50, 50 + 25] == 0.0
    # Fringes: the red disc (k * 1.1) reaches beyond the green one on the far side.
    img = np.zeros((101, 301), dtype=np.float32)
    fringed = GhostSpec(k=2.0, radius_px=10.0, level=10.0, softness=0.05, hollow=0.0, fringe=0.1)
    render_ghosts(img, (200, 50), [fringed], center_xy=(150, 50))
    # green at x = 250 (radius 10), red at 150 + 2.2 * 50 = 260 (radius 10.5), blue at 240 (9.5)
    assert img[50, 265] == pytest.approx(10.0 * 0.2126, rel=1e-4)  # only red reaches here
    assert img[50, 235] == pytest.approx(10.0 * 0.0722, rel=1e-4)  # only blue
    assert img[50, 250] == pytest.approx(10.0 * (0.2126 + 0.7152), rel=1e-4)  # red and green


def test_ghost_gain_scales_and_out_must_be_float32():
    a = np.zeros((50, 50), dtype=np.float32)
    b = np.zeros((50, 50), dtype=np.float32)
    spec = [GhostSpec(k=-1.0, radius_px=5.0, level=8.0)]
    render_ghosts(a, (40, 30), spec)
    render_ghosts(b, (40, 30), spec, gain=0.25)
    assert np.allclose(b, 0.25 * a)
    with pytest.raises(SimError, match="float32"):
        render_ghosts(np.zeros((5, 5)), (1, 1), spec)
    with pytest.raises(SimError, match="ghost hollow must lie in"):
        GhostSpec(k=1.0, radius_px=3.0, level=1.0, hollow=2.0)


def write_png(path, rgb):
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.asarray(rgb, dtype=np.uint8)).save(path)


def flare7k_tree(root):
    """A tiny Flare7K++ layout: two pairs in two sub-datasets, plus strays that must be ignored."""
    grey = np.full((12, 16, 3), 128)
    red = np.zeros((12, 16, 3))
    red[..., 0] = 255
    base = root / "Flare7K" / "Scattering_Flare"
    write_png(base / "Compound_Flare" / "000001.png", grey)
    write_png(base / "Light_Source" / "000001.png", red)
    write_png(base / "Compound_Flare" / "000002.png", grey)  # no light twin: ignored
    write_png(root / "Flare-R" / "Compound_Flare" / "a.png", red)
    write_png(root / "Flare-R" / "Light_Source" / "a.png", grey)
    (root / "Flare-R" / "Light_Source" / "notes.txt").write_text("not an image")


def test_flare7k_pairs_are_found_by_name_and_linearised(tmp_path):
    flare7k_tree(tmp_path)
    pairs = find_flare7k_pairs(tmp_path)
    names = [(p.relative_to(tmp_path).as_posix(), q.name) for p, q in pairs]
    assert names == [
        ("Flare-R/Compound_Flare/a.png", "a.png"),
        ("Flare7K/Scattering_Flare/Compound_Flare/000001.png", "000001.png"),
    ]
    flare, light = load_flare7k_pair(*pairs[1], gamma=2.2)
    assert flare.dtype == np.float32 and flare.shape == (12, 16)
    assert flare[0, 0] == pytest.approx(255 * (128 / 255) ** 2.2, rel=1e-5)  # 55.98
    assert light[0, 0] == pytest.approx(255 * 0.2126, rel=1e-5)  # pure red: its luminance
    flare18, _ = load_flare7k_pair(*pairs[1], gamma=1.8)
    assert flare18[0, 0] == pytest.approx(255 * (128 / 255) ** 1.8, rel=1e-5)


def test_flare7k_errors_name_the_problem(tmp_path):
    with pytest.raises(EventFileError, match="not a folder"):
        find_flare7k_pairs(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(EventFileError, match="no Compound_Flare/NAME with a matching"):
        find_flare7k_pairs(tmp_path / "empty")
    write_png(tmp_path / "x" / "Compound_Flare" / "b.png", np.zeros((4, 4, 3)))
    write_png(tmp_path / "x" / "Light_Source" / "b.png", np.zeros((5, 4, 3)))
    (p, q) = find_flare7k_pairs(tmp_path / "x")[0]
    with pytest.raises(EventFileError, match=r"size \(4, 5\) differs"):
        load_flare7k_pair(p, q, 2.0)
    (tmp_path / "x" / "Compound_Flare" / "c.png").write_bytes(b"not a png")
    write_png(tmp_path / "x" / "Light_Source" / "c.png", np.zeros((4, 4, 3)))
    bad = next(pq for pq in find_flare7k_pairs(tmp_path / "x") if pq[0].name == "c.png")
    with pytest.raises(EventFileError, match="cannot read the image"):
        load_flare7k_pair(*bad, 2.0)
