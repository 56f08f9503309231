"""Tests of edeflare.sim.optics: pupils, PSFs, the clean/perturbed pair."""

from __future__ import annotations

import numpy as np
import pytest

from edeflare.sim._validation import SimError
from edeflare.sim.optics import (
    PSFConfig,
    airy_first_zero_px,
    draw_perturbation,
    luminosity,
    psf_from_pupil,
    psf_pair,
    pupil,
)


def polar(psf):
    n = psf.shape[0]
    yy, xx = np.mgrid[:n, :n] - n // 2
    return np.hypot(xx, yy), np.degrees(np.arctan2(yy, xx)) % 360


def radial_profile(psf, bin_px=0.1, r_max=30.0):
    r, _ = polar(psf)
    edges = np.arange(0, r_max + bin_px, bin_px)
    sums = np.histogram(r, edges, weights=psf)[0]
    counts = np.histogram(r, edges)[0]
    centres = 0.5 * (edges[1:] + edges[:-1])
    keep = counts > 0
    return centres[keep], sums[keep] / counts[keep]


def darkest(radii, profile, lo, hi):
    """Radius of the darkest ring between ``lo`` and ``hi`` pixels."""
    sel = (radii >= lo) & (radii <= hi)
    return radii[sel][np.argmin(profile[sel])]


@pytest.mark.parametrize("wavelength", [550.0, 700.0])
def test_clean_circular_aperture_has_its_first_dark_ring_where_theory_says(wavelength):
    # Airy: first zero at 1.2197 lambda / D. With 8x padding one pixel is lambda_ref / (8 D),
    # so the ring lies at 1.2197 * 8 * lambda / lambda_ref = 9.757 px (550 nm), 12.418 (700 nm).
    config = PSFConfig(grid=256, pad=8.0, wavelengths_nm=(wavelength,))
    expected = 1.2197 * 8 * wavelength / 550
    assert airy_first_zero_px(config, wavelength) == pytest.approx(expected, rel=1e-4)
    psf = psf_pair(config, rng=0).clean
    radii, profile = radial_profile(psf.astype(np.float64))
    # The only dark ring within +-40 % of the prediction (the next ones are at 1.83x, 2.66x).
    assert darkest(radii, profile, 0.6 * expected, 1.4 * expected) == pytest.approx(
        expected, abs=0.25
    )
    second = 2.2331 * 8 * wavelength / 550  # Airy's second dark ring
    assert darkest(radii, profile, 0.85 * second, 1.15 * second) == pytest.approx(second, abs=0.4)
    assert profile[np.abs(radii - expected) < 0.15].mean() < 1e-3 * profile.max()


def test_three_orientation_star_filter_gives_six_spikes_sixty_degrees_apart():
    config = PSFConfig(star_orientations=3, star_rotation_deg=10.0)
    psf = psf_pair(config, rng=3).perturbed.astype(np.float64)
    r, theta = polar(psf)
    ring = (r > 20) & (r < 200)
    energy = np.histogram(theta[ring], np.arange(361), weights=psf[ring])[0]
    # local maxima on the circle, strongest six
    left, right = np.roll(energy, 1), np.roll(energy, -1)
    peaks = np.flatnonzero((energy > left) & (energy >= right))
    top = np.sort(peaks[np.argsort(energy[peaks])[-6:]])
    assert np.allclose(np.diff(np.append(top, top[0] + 360)), 60, atol=2)
    assert np.abs((top - 10 + 30) % 60 - 30).max() <= 2  # along 10 + 60 k degrees
    assert energy[top].min() > 10 * np.median(energy)
    # the clean lens has no spikes: far less light along the same directions
    clean = psf_pair(config, rng=3).clean.astype(np.float64)
    e_clean = np.histogram(theta[ring], np.arange(361), weights=clean[ring])[0]
    assert (energy[top] > 10 * e_clean[top]).all()


def test_psfs_have_unit_energy_and_the_perturbation_moves_light_out_of_the_core():
    config = PSFConfig(grid=256, dust_count=40, scratch_count=4, random_phase_rms=0.5)
    pair = psf_pair(config, rng=1)
    for psf in (pair.clean, pair.perturbed):
        assert psf.dtype == np.float32 and psf.shape == (256, 256)
        assert float(psf.sum(dtype=np.float64)) == pytest.approx(1.0, abs=1e-6)
        assert (psf >= 0).all()
    r, _ = polar(pair.clean)
    core = r <= airy_first_zero_px(config)
    assert pair.clean[core].sum() > 0.75  # ideal Airy core: 83.8 % (spectrum-averaged)
    assert pair.perturbed[core].sum() < pair.clean[core].sum() - 0.02
    assert pair.perturbed[r > 30].sum() > 3 * pair.clean[r > 30].sum()


def test_no_perturbation_gives_identical_psfs_and_seeds_are_reproducible():
    config = PSFConfig(grid=128)
    pair = psf_pair(config, rng=0)
    assert np.array_equal(pair.clean, pair.perturbed)
    noisy = PSFConfig(grid=128, dust_count=10, star_orientations=2)
    a, b, c = (psf_pair(noisy, rng=s).perturbed for s in (5, 5, 6))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_polygonal_aperture_gives_spikes_from_its_edges():
    # A hexagon has 3 pairs of parallel edges: 6 spikes, perpendicular to the edges.
    psf = psf_pair(PSFConfig(grid=256, blades=6), rng=0).clean.astype(np.float64)
    r, theta = polar(psf)
    ring = (r > 15) & (r < 110)
    energy = np.histogram(theta[ring], np.arange(0, 361, 2), weights=psf[ring])[0]
    left, right = np.roll(energy, 1), np.roll(energy, -1)
    peaks = np.flatnonzero((energy > left) & (energy >= right))
    top = np.sort(peaks[np.argsort(energy[peaks])[-6:]]) * 2
    assert np.allclose(np.diff(np.append(top, top[0] + 360)), 60, atol=4)


def test_defocus_spreads_the_clean_psf():
    sharp = psf_pair(PSFConfig(grid=128, wavelengths_nm=(550,)), rng=0).clean
    blurred = psf_pair(PSFConfig(grid=128, defocus_waves=1.0, wavelengths_nm=(550,)), rng=0).clean
    assert blurred.max() < 0.5 * sharp.max()


def test_pupil_scales_with_wavelength_and_psf_from_pupil_normalises():
    config = PSFConfig(grid=64, pad=4.0)
    area_ref = np.abs(pupil(config, 550.0)).sum()
    area_red = np.abs(pupil(config, 700.0)).sum()
    assert area_red / area_ref == pytest.approx((550 / 700) ** 2, rel=0.02)
    psf = psf_from_pupil(pupil(config))
    assert psf.sum() == pytest.approx(1.0)
    with pytest.raises(SimError, match="transmits no light"):
        psf_from_pupil(np.zeros((8, 8)))


def test_luminosity_peaks_in_the_green():
    v = luminosity(np.array([450.0, 555.0, 650.0]))
    assert v[1] > 0.99 and v[0] < 0.1 and v[2] < 0.15


def test_config_is_validated():
    with pytest.raises(SimError, match=r"pad must lie in \[2.0"):
        PSFConfig(pad=1.5)
    with pytest.raises(SimError, match="blades must be 0"):
        PSFConfig(blades=2)
    with pytest.raises(SimError, match=r"unknown key\(s\) \['dust'\]"):
        PSFConfig.from_dict({"dust": 3})
    with pytest.raises(SimError, match="grid must be an even int"):
        PSFConfig(grid=15)
    cfg = PSFConfig(dust_count=3, wavelengths_nm=[500, 600])
    assert PSFConfig.from_dict(cfg.to_dict()) == cfg
    p = draw_perturbation(cfg, rng=0)
    assert p.dust.shape == (3, 3) and (np.hypot(p.dust[:, 0], p.dust[:, 1]) <= 1).all()
