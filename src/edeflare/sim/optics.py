r"""Point spread functions from pupil functions: clean lens and perturbed lens (Fourier optics).

The paper's real-data model (Sec. 3.3): a lens with pupil :math:`P(\mathbf u)`
has :math:`\mathrm{PSF} = |\mathcal F\{P\}|^2`; a filter or dirt in front of it
multiplies the pupil, :math:`P_{ob} = P_{clean}\,T(\mathbf u)`. This module
samples both pupils on a grid and returns the pair of PSFs, each normalised
to unit energy.

Grid. ``grid`` samples across with the pupil of diameter ``grid / pad``
samples (``pad >= 2``: the PSF is an autocorrelation of the pupil in frequency,
so 2x zero padding is the Nyquist rate of the intensity). One PSF sample is one
image pixel at the reference wavelength; the first dark ring of the clean
circular aperture lies at :math:`1.2197\,\mathrm{pad}\,\lambda/\lambda_{ref}`
pixels.

Pupil pieces (coordinates in units of the pupil radius, :math:`\rho^2 = u^2+v^2`):

- aperture: the unit disc, or a regular ``blades``-gon inscribed in it
  (spikes from its straight edges), anti-aliased over one sample;
- defocus: phase :math:`2\pi W_{020}\,(\lambda_{ref}/\lambda)\,\rho^2`
  (``defocus_waves`` = :math:`W_{020}` in reference waves), part of the clean lens;
- dust: opaque discs (broad halos);
- scratches: thin random polylines of low transmission (streaks
  perpendicular to each segment);
- star filter: ``star_orientations`` = k line gratings at 180/k degrees
  apart, lines of amplitude transmission ``star_transmission``; each grating
  diffracts along its normal, so k = 3 gives 6 spikes 60 degrees apart;
  jittered spacing turns the diffraction orders into continuous streaks;
  lines and scratches have Gaussian cross-sections, whose spectra fall off
  smoothly instead of aliasing around the grid;
- random-pattern filter: a smooth random phase screen (a diffuser) of RMS
  ``random_phase_rms`` radians at the reference wavelength.

Colour. The PSF is computed at each of ``wavelengths_nm``: the physical pupil
spans ``grid / pad * lambda_ref / lambda`` samples (so the pattern scales as
:math:`\lambda/\lambda_{ref}`), phases scale as :math:`\lambda_{ref}/\lambda`;
each monochromatic PSF is normalised and weighted by the photopic luminosity
:math:`V(\lambda) \approx 1.019\,e^{-285.4(\lambda_{\mu m} - 0.559)^2}`.
The FFT makes the PSF periodic; a cosine taper over the outer tenth of the grid
hides what little light wraps around. Both PSFs are then scaled to unit sum.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from ._validation import SimError, check_range, dataclass_from_dict, make_rng

__all__ = [
    "PSFConfig",
    "PSFPair",
    "Perturbation",
    "airy_first_zero_px",
    "draw_perturbation",
    "luminosity",
    "psf_from_pupil",
    "psf_pair",
    "pupil",
]


@dataclass(frozen=True)
class PSFConfig:
    """Lens and filter of one PSF pair (defaults: a clean circular lens, no filter).

    Parameters
    ----------
    grid : int
        FFT size; the PSF is ``grid x grid`` pixels.
    pad : float
        ``grid`` over the pupil diameter in samples, at least 2.
    blades : int
        0 for a circular aperture, else the number of aperture blades (>= 3).
    blade_rotation_deg : float
        Rotation of the polygonal aperture.
    defocus_waves : float
        Defocus :math:`W_{020}` at the pupil edge, in waves at the reference wavelength.
    dust_count : int
        Opaque dust particles on the pupil.
    dust_radius : (float, float)
        Range of their radii, in pupil radii.
    scratch_count : int
        Scratches (random polylines of ``scratch_segments`` segments).
    scratch_width : float
        Their full width at half maximum, in pupil radii.
    scratch_transmission : float
        Their amplitude transmission.
    scratch_segments : int
        Segments per scratch.
    star_orientations : int
        Number of line gratings (0: no star filter).
    star_rotation_deg : float
        Angle of the first grating's normal (the direction of its spikes).
    star_period : float
        Mean line spacing, in pupil diameters.
    star_line_width : float
        Line full width at half maximum, as a fraction of the spacing.
    star_transmission : float
        Amplitude transmission of the lines.
    star_jitter : float
        Random variation of the spacing (fraction; 0 gives discrete orders).
    random_phase_rms : float
        RMS of the random phase screen, radians at the reference wavelength.
    random_phase_scale : float
        Correlation length of the screen, in pupil diameters.
    wavelengths_nm : tuple of float
        Wavelengths summed into the luminance PSF.
    reference_nm : float
        The wavelength at which one PSF sample is one pixel.

    Examples
    --------
    >>> PSFConfig.from_dict({"star_orientations": 3}).star_orientations
    3
    """

    grid: int = 512
    pad: float = 2.0
    blades: int = 0
    blade_rotation_deg: float = 0.0
    defocus_waves: float = 0.0
    dust_count: int = 0
    dust_radius: tuple[float, float] = (0.01, 0.04)
    scratch_count: int = 0
    scratch_width: float = 0.012
    scratch_transmission: float = 0.2
    scratch_segments: int = 4
    star_orientations: int = 0
    star_rotation_deg: float = 0.0
    star_period: float = 0.04
    star_line_width: float = 0.15
    star_transmission: float = 0.3
    star_jitter: float = 0.3
    random_phase_rms: float = 0.0
    random_phase_scale: float = 0.05
    wavelengths_nm: tuple[float, ...] = (400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0)
    reference_nm: float = 550.0

    def __post_init__(self) -> None:
        for name in ("grid", "blades", "dust_count", "scratch_count", "scratch_segments"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise SimError(f"{name} must be a non-negative int, got {value!r}")
        if self.grid < 16 or self.grid % 2:
            raise SimError(f"grid must be an even int >= 16, got {self.grid!r}")
        check_range("pad", self.pad, 2.0, self.grid / 4)
        if self.blades in (1, 2):
            raise SimError(f"blades must be 0 (circular) or >= 3, got {self.blades}")
        if not isinstance(self.star_orientations, (int, np.integer)) or self.star_orientations < 0:
            raise SimError(f"star_orientations must be an int >= 0, got {self.star_orientations!r}")
        lo, hi = _pair("dust_radius", self.dust_radius)
        if not 0 < lo <= hi <= 1:
            raise SimError(f"dust_radius must satisfy 0 < lo <= hi <= 1, got {self.dust_radius!r}")
        object.__setattr__(self, "dust_radius", (lo, hi))
        check_range("scratch_width", self.scratch_width, 0, 1, lo_open=True)
        check_range("scratch_transmission", self.scratch_transmission, 0, 1)
        check_range("star_period", self.star_period, 0, 1, lo_open=True)
        check_range("star_line_width", self.star_line_width, 0, 1, lo_open=True, hi_open=True)
        check_range("star_transmission", self.star_transmission, 0, 1)
        check_range("star_jitter", self.star_jitter, 0, 0.9)
        check_range("random_phase_rms", self.random_phase_rms, 0)
        check_range("random_phase_scale", self.random_phase_scale, 0, 1, lo_open=True)
        check_range("reference_nm", self.reference_nm, 100, 2000)
        try:
            waves = tuple(float(w) for w in self.wavelengths_nm)
        except (TypeError, ValueError):
            raise SimError(f"wavelengths_nm must be numbers, got {self.wavelengths_nm!r}") from None
        if not waves or not all(100 <= w <= 2000 for w in waves):
            raise SimError(f"wavelengths_nm must be 1+ values in [100, 2000], got {waves!r}")
        object.__setattr__(self, "wavelengths_nm", waves)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PSFConfig:
        """Build from a mapping (e.g. parsed JSON); unknown keys are an error."""
        return dataclass_from_dict(cls, data)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (lists for tuples)."""
        return {
            k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()
        }


def _pair(name: str, value: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise SimError(f"{name} must be a pair of numbers, got {value!r}") from None
    return lo, hi


@dataclass(frozen=True)
class Perturbation:
    """The random geometry of the pupil perturbation :math:`T`, in pupil radii.

    Drawn once by :func:`draw_perturbation` and rasterised at every wavelength.
    """

    dust: np.ndarray  # (n, 3): x, y, radius
    scratches: tuple[np.ndarray, ...]  # each (segments + 1, 2) vertices
    star_lines: tuple[np.ndarray, ...]  # per orientation: sorted line offsets along its normal
    phase_screen: np.ndarray | None  # (m, m) over [-1, 1]^2, unit RMS


@dataclass(frozen=True)
class PSFPair:
    """The clean PSF (``T = 1``) and the perturbed one, each ``(grid, grid)`` float32, sum 1."""

    clean: np.ndarray
    perturbed: np.ndarray


def luminosity(wavelength_nm: float | np.ndarray) -> float | np.ndarray:
    """Photopic luminosity :math:`V(\\lambda)` (Gaussian fit, peak 1.019 at 559 nm).

    Examples
    --------
    >>> round(float(luminosity(555.0)), 3)
    1.014
    """
    lam_um = np.asarray(wavelength_nm, dtype=np.float64) / 1000.0
    return 1.019 * np.exp(-285.4 * (lam_um - 0.559) ** 2)


def airy_first_zero_px(config: PSFConfig, wavelength_nm: float | None = None) -> float:
    """Radius (pixels) of the first dark ring of the clean circular aperture.

    Examples
    --------
    >>> round(airy_first_zero_px(PSFConfig(pad=4.0)), 3)
    4.879
    """
    lam = config.reference_nm if wavelength_nm is None else float(wavelength_nm)
    return 1.2196698912665045 * config.pad * lam / config.reference_nm


def draw_perturbation(
    config: PSFConfig, *, rng: np.random.Generator | int | None = None
) -> Perturbation:
    """Draw the dust, scratches, star-filter lines and phase screen that ``config`` asks for.

    Examples
    --------
    >>> p = draw_perturbation(PSFConfig(dust_count=5, star_orientations=2), rng=0)
    >>> p.dust.shape, len(p.star_lines)
    ((5, 3), 2)
    """
    gen = make_rng(rng)
    # Dust anywhere on the pupil (uniform over the disc).
    n = config.dust_count
    rho = np.sqrt(gen.random(n))
    phi = gen.uniform(0, 2 * np.pi, n)
    radii = gen.uniform(*config.dust_radius, n)
    dust = np.stack([rho * np.cos(phi), rho * np.sin(phi), radii], axis=1)
    # Scratches: random walks with gently turning segments.
    scratches = []
    for _ in range(config.scratch_count):
        start = gen.uniform(-0.8, 0.8, 2)
        heading = gen.uniform(0, 2 * np.pi)
        pts = [start]
        for _ in range(config.scratch_segments):
            heading += gen.normal(0, 0.35)
            length = gen.uniform(0.1, 0.5)
            pts.append(pts[-1] + length * np.array([np.cos(heading), np.sin(heading)]))
        scratches.append(np.array(pts))
    # Star filter: line offsets along each grating's normal, spacing jittered.
    lines = []
    spacing = 2.0 * config.star_period  # pupil diameters -> pupil radii
    for _ in range(config.star_orientations):
        count = int(np.ceil(3.0 / spacing)) + 2
        steps = spacing * (1 + config.star_jitter * gen.uniform(-1, 1, count))
        offsets = np.cumsum(steps) - 1.5 - gen.uniform(0, spacing)
        lines.append(np.sort(offsets))
    screen = None
    if config.random_phase_rms > 0:
        m = 256
        noise = gen.standard_normal((m, m))
        sigma_px = config.random_phase_scale * m / 2.0  # diameters over [-1, 1]
        screen = ndimage.gaussian_filter(noise, sigma_px, mode="wrap")
        screen = (screen - screen.mean()) / screen.std()
    return Perturbation(dust, tuple(scratches), tuple(lines), screen)


def _coords(config: PSFConfig, wavelength_nm: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Pupil coordinates (pupil radii) of the sampling grid at one wavelength, and one sample."""
    scale = wavelength_nm / config.reference_nm
    radius_samples = config.grid / (2.0 * config.pad)
    step = scale / radius_samples
    axis = (np.arange(config.grid) - config.grid // 2) * step
    return axis[None, :], axis[:, None], step


def _aperture(u: np.ndarray, v: np.ndarray, step: float, config: PSFConfig) -> np.ndarray:
    if config.blades:
        n = config.blades
        rot = math.radians(config.blade_rotation_deg)
        # Inscribed regular polygon: inside when every edge normal projection <= cos(pi / n).
        proj = np.full(np.broadcast(u, v).shape, -np.inf)
        for k in range(n):
            a = rot + (2 * k + 1) * math.pi / n
            proj = np.maximum(proj, u * math.cos(a) + v * math.sin(a))
        dist = math.cos(math.pi / n) - proj
    else:
        dist = 1.0 - np.sqrt(u * u + v * v)
    return np.clip(0.5 + dist / step, 0.0, 1.0)


def _transmission(
    u: np.ndarray, v: np.ndarray, step: float, scale: float, config: PSFConfig, pert: Perturbation
) -> np.ndarray:
    """Complex transmission ``T`` on the grid (1 where nothing perturbs the pupil)."""
    grid = config.grid
    t = np.ones((grid, grid), dtype=np.complex128)
    ax = u[0]
    c = grid // 2

    def box(x0: float, x1: float, y0: float, y1: float) -> tuple[slice, slice] | None:
        i0 = max(0, int(np.floor(y0 / step)) + c - 1)
        i1 = min(grid, int(np.ceil(y1 / step)) + c + 2)
        j0 = max(0, int(np.floor(x0 / step)) + c - 1)
        j1 = min(grid, int(np.ceil(x1 / step)) + c + 2)
        return (slice(i0, i1), slice(j0, j1)) if i0 < i1 and j0 < j1 else None

    for x, y, r in pert.dust:
        sl = box(x - r, x + r, y - r, y + r)
        if sl is None:
            continue
        d = np.hypot(ax[sl[1]][None, :] - x, ax[sl[0]][:, None] - y) - r
        t[sl] *= np.clip(0.5 + d / step, 0.0, 1.0)
    half = 0.5 * config.scratch_width
    reach = 3.0 * max(half, step)
    for pts in pert.scratches:
        for p0, p1 in itertools.pairwise(pts):
            lo, hi = np.minimum(p0, p1) - reach, np.maximum(p0, p1) + reach
            sl = box(lo[0], hi[0], lo[1], hi[1])
            if sl is None:
                continue
            xx = ax[sl[1]][None, :] - p0[0]
            yy = ax[sl[0]][:, None] - p0[1]
            seg = p1 - p0
            f = np.clip((xx * seg[0] + yy * seg[1]) / max(seg @ seg, 1e-12), 0.0, 1.0)
            d = np.hypot(xx - f * seg[0], yy - f * seg[1])
            t[sl] *= 1.0 - (1.0 - config.scratch_transmission) * _gauss_line(d, half, step)
    if pert.star_lines:
        half = 0.5 * config.star_line_width * 2.0 * config.star_period
        for k, offsets in enumerate(pert.star_lines):
            a = math.radians(config.star_rotation_deg) + k * math.pi / len(pert.star_lines)
            s = u * math.cos(a) + v * math.sin(a)
            i = np.clip(np.searchsorted(offsets, s), 1, offsets.size - 1)
            d = np.minimum(np.abs(s - offsets[i - 1]), np.abs(s - offsets[i]))
            t *= 1.0 - (1.0 - config.star_transmission) * _gauss_line(d, half, step)
    if pert.phase_screen is not None:
        m = pert.phase_screen.shape[0]
        # Pupil [-1, 1] -> screen index [0, m - 1]; evaluated at this wavelength's coordinates.
        rows = (np.broadcast_to(v, (grid, grid)) + 1.0) * (m - 1) / 2.0
        cols = (np.broadcast_to(u, (grid, grid)) + 1.0) * (m - 1) / 2.0
        phase = ndimage.map_coordinates(pert.phase_screen, [rows, cols], order=1, mode="nearest")
        t *= np.exp(1j * config.random_phase_rms / scale * phase)
    return t


def _gauss_line(d: np.ndarray, half_width: float, step: float) -> np.ndarray:
    """Line profile at distance ``d``: Gaussian of FWHM ``2 half_width`` (at least 1.5 samples)."""
    sigma = max(2.0 * half_width, 1.5 * step) / 2.3548200450309493
    return np.exp(-0.5 * (d / sigma) ** 2)


def pupil(
    config: PSFConfig,
    wavelength_nm: float | None = None,
    perturbation: Perturbation | None = None,
) -> np.ndarray:
    """The complex pupil function ``(grid, grid)`` at one wavelength: clean, or times ``T``.

    Examples
    --------
    >>> p = pupil(PSFConfig(grid=64, pad=4.0))
    >>> p.shape, round(float(np.abs(p).sum()), 1)  # a disc of radius 8 samples: 64 pi = 201.1
    ((64, 64), 200.7)
    """
    lam = config.reference_nm if wavelength_nm is None else float(wavelength_nm)
    u, v, step = _coords(config, lam)
    scale = lam / config.reference_nm
    p = _aperture(u, v, step, config).astype(np.complex128)
    if config.defocus_waves:
        p *= np.exp(2j * np.pi * config.defocus_waves / scale * (u * u + v * v))
    if perturbation is not None:
        p *= _transmission(u, v, step, scale, config, perturbation)
    return p


def psf_from_pupil(p: np.ndarray) -> np.ndarray:
    """``|FFT(p)|**2``, centred (``fftshift``), normalised to unit sum, as float64.

    Examples
    --------
    >>> psf = psf_from_pupil(pupil(PSFConfig(grid=64, pad=4.0)))
    >>> round(float(psf.sum()), 12), np.unravel_index(psf.argmax(), psf.shape)
    (1.0, (np.int64(32), np.int64(32)))
    """
    field = sfft.fft2(sfft.ifftshift(p))
    psf = sfft.fftshift(field.real**2 + field.imag**2)
    total = psf.sum()
    if not total > 0:
        raise SimError("the pupil transmits no light (an opaque aperture); check the PSF config")
    return psf / total


def psf_pair(
    config: PSFConfig | None = None,
    *,
    perturbation: Perturbation | None = None,
    rng: np.random.Generator | int | None = None,
) -> PSFPair:
    """Luminance PSFs of the clean and the perturbed lens, each of unit energy.

    Parameters
    ----------
    config : PSFConfig, optional
    perturbation : Perturbation, optional
        The pupil perturbation; drawn from ``rng`` when omitted.
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    PSFPair
        ``clean`` and ``perturbed``, float32 ``(grid, grid)``, centred on
        ``(grid // 2, grid // 2)``.

    Examples
    --------
    >>> pair = psf_pair(PSFConfig(grid=64, dust_count=3, wavelengths_nm=(550,)), rng=0)
    >>> round(float(pair.clean.sum()), 5), round(float(pair.perturbed.sum()), 5)
    (1.0, 1.0)
    >>> bool(pair.perturbed.max() < pair.clean.max())  # dust scatters light out of the core
    True
    """
    config = config or PSFConfig()
    if perturbation is None:
        perturbation = draw_perturbation(config, rng=rng)
    weights = np.asarray(luminosity(np.array(config.wavelengths_nm)), dtype=np.float64)
    weights = weights / weights.sum()
    clean = np.zeros((config.grid, config.grid))
    perturbed = np.zeros((config.grid, config.grid))
    for w, lam in zip(weights, config.wavelengths_nm, strict=True):
        clean += w * psf_from_pupil(pupil(config, lam))
        perturbed += w * psf_from_pupil(pupil(config, lam, perturbation))
    taper = _taper(config.grid)
    return PSFPair(_unit(clean * taper), _unit(perturbed * taper))


def _taper(grid: int) -> np.ndarray:
    """1 inside 90 % of the half-width, a cosine down to 0 at the edge (per axis)."""
    x = np.abs(np.arange(grid) - grid // 2) / (grid / 2)
    edge = np.clip((x - 0.9) / 0.1, 0.0, 1.0)
    w = np.cos(0.5 * np.pi * edge) ** 2
    return w[:, None] * w[None, :]


def _unit(psf: np.ndarray) -> np.ndarray:
    psf = np.maximum(psf, 0.0)
    return (psf / psf.sum()).astype(np.float32)
