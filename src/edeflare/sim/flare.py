r"""Images of a light source, its scattering flare and its reflective ghosts (8-bit linear scale).

All images are float32 ``(H, W)`` linear intensity on the 8-bit scale
(:data:`WHITE` = 255 is the white of an 8-bit frame). A position ``(x, y)`` is
in pixels, pixel ``(row i, column j)`` centred on ``(j, i)``.

- **Ideal lens** (what the ground truth sees): the light source itself, a disc
  of radius :math:`r` with a one-pixel soft edge, or a Gaussian of standard
  deviation :math:`r`.
- **Scattering flare**: the light source convolved with a perturbed PSF
  (:mod:`edeflare.sim.optics`), :math:`I_f = I_{light} * \mathrm{PSF}_{ob}`
  (FFT convolution), plus an optional procedural glare around the source,

  .. math::

      G(\rho, \theta) = g \left(\frac{\rho_0}{\rho + \rho_0}\right)^{\gamma}
      \Big(1 + s \sum_{j<n} e^{-\delta_j(\theta)^2 / 2w^2}\Big),

  a :math:`1/\rho` core (``falloff`` :math:`\gamma = 1`) with ``streaks``
  :math:`n` angular streaks of width :math:`w` (:math:`\delta_j` is the angle to
  streak :math:`j`).
- **Reflective flare** (ghosts): lens reflections image the source along the
  line through the image centre :math:`c` and the source :math:`L`: ghost
  :math:`j` sits at :math:`c + k_j (L - c)` (:math:`k_j` roughly in
  :math:`[-5, 1]`), a soft disc of radius :math:`R_j` whose centre is dimmer
  than its rim (``hollow``). Each ghost is drawn as red, green and blue discs
  at slightly different :math:`k` and radius (colour fringes), weighted by
  their luminance (0.2126, 0.7152, 0.0722). Ghosts belong to the flare video
  only, never to the ground truth.
- **Flare7K++ assets** (optional, the user's own copy): ``Compound_Flare`` /
  ``Light_Source`` image pairs found by file name; sRGB-like 8-bit values are
  linearised as :math:`255\,(v/255)^{\gamma}` with :math:`\gamma` drawn in
  [1.8, 2.2], then reduced to luminance.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from PIL import Image
from scipy import signal

from ..errors import EventFileError
from ._validation import SimError, check_range

__all__ = [
    "FLARE7K_COMPOUND",
    "FLARE7K_LIGHT",
    "WHITE",
    "GhostSpec",
    "GlareSpec",
    "find_flare7k_pairs",
    "glare",
    "light_source",
    "load_flare7k_pair",
    "render_ghosts",
    "scattering_flare",
]

WHITE = 255.0
"""White of an 8-bit frame: the intensity scale of every rendered image."""
FLARE7K_COMPOUND = "Compound_Flare"
"""Folder of Flare7K++'s flare images (light source included)."""
FLARE7K_LIGHT = "Light_Source"
"""Folder of Flare7K++'s matching light-source-only images."""

_LUMA = (0.2126, 0.7152, 0.0722)
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _shape(shape: Sequence[int]) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in shape)
    except (TypeError, ValueError):
        raise SimError(f"shape must be (height, width), got {shape!r}") from None
    if h <= 0 or w <= 0:
        raise SimError(f"shape must be positive (height, width), got {shape!r}")
    return h, w


def light_source(
    shape: Sequence[int],
    center_xy: Sequence[float],
    radius_px: float,
    level: float = WHITE,
    *,
    profile: str = "disc",
) -> np.ndarray:
    """The ideal-lens image of a light source: a soft-edged disc or a Gaussian.

    Parameters
    ----------
    shape : (height, width)
    center_xy : (x, y)
        Centre in pixels.
    radius_px : float
        Disc radius (the edge ramps over one pixel) or Gaussian sigma.
    level : float
        Peak intensity (8-bit scale; may exceed :data:`WHITE` for radiance).
    profile : {"disc", "gaussian"}

    Returns
    -------
    numpy.ndarray
        float32 ``(height, width)``.

    Examples
    --------
    >>> img = light_source((9, 9), (4, 4), 2.0)
    >>> float(img[4, 4]), float(img[4, 6]), float(img[4, 7])
    (255.0, 127.5, 0.0)
    """
    h, w = _shape(shape)
    radius = check_range("radius_px", radius_px, 0, lo_open=True)
    cx, cy = (float(v) for v in center_xy)
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot(xx - cx, yy - cy)
    if profile == "disc":
        img = np.clip(radius - r + 0.5, 0.0, 1.0)
    elif profile == "gaussian":
        img = np.exp(-0.5 * (r / radius) ** 2)
    else:
        raise SimError(f"profile must be 'disc' or 'gaussian', got {profile!r}")
    return (level * img).astype(np.float32)


def scattering_flare(light: np.ndarray, psf: np.ndarray) -> np.ndarray:
    """The light source seen through a lens with this PSF: ``light * psf`` (FFT, same size).

    The PSF's centre sample is ``(rows // 2, cols // 2)``; energy is conserved
    up to what falls outside the image.

    Examples
    --------
    >>> psf = np.zeros((5, 5)); psf[2, 2] = 0.5; psf[2, 4] = 0.5
    >>> light = np.zeros((7, 7)); light[3, 3] = 100.0
    >>> out = scattering_flare(light, psf)
    >>> float(out[3, 3]), float(out[3, 5])
    (50.0, 50.0)
    """
    light = np.asarray(light, dtype=np.float64)
    psf = np.asarray(psf, dtype=np.float64)
    if light.ndim != 2 or psf.ndim != 2:
        raise SimError(f"light and psf must be 2-D, got {light.shape} and {psf.shape}")
    full = signal.fftconvolve(light, psf, mode="full")
    r0, c0 = psf.shape[0] // 2, psf.shape[1] // 2
    out = full[r0 : r0 + light.shape[0], c0 : c0 + light.shape[1]]
    out = np.where(out > 1e-9 * max(float(light.max()), 1e-30), out, 0.0)  # FFT round-off
    return out.astype(np.float32)


@dataclass(frozen=True)
class GlareSpec:
    """Procedural glare around a light source (see the module docstring).

    Parameters
    ----------
    level : float
        Intensity at the source centre's distance ``core_px`` scale (8-bit units).
    core_px : float
        :math:`\\rho_0`, the size of the core.
    falloff : float
        Exponent :math:`\\gamma` (1 gives a 1/r core).
    streaks : int
        Number of angular streaks.
    streak_gain : float
        Streak contrast :math:`s`.
    streak_width_deg : float
        Angular width :math:`w` of a streak.
    rotation_deg : float
        Angle of the first streak.

    Examples
    --------
    >>> GlareSpec(level=20.0, streaks=6).streak_gain
    2.0
    """

    level: float = 60.0
    core_px: float = 6.0
    falloff: float = 1.0
    streaks: int = 0
    streak_gain: float = 2.0
    streak_width_deg: float = 1.5
    rotation_deg: float = 0.0

    def __post_init__(self) -> None:
        check_range("glare level", self.level, 0)
        check_range("core_px", self.core_px, 0, lo_open=True)
        check_range("falloff", self.falloff, 0, lo_open=True)
        if not isinstance(self.streaks, (int, np.integer)) or self.streaks < 0:
            raise SimError(f"streaks must be an int >= 0, got {self.streaks!r}")
        check_range("streak_gain", self.streak_gain, 0)
        check_range("streak_width_deg", self.streak_width_deg, 0, lo_open=True)


def glare(shape: Sequence[int], center_xy: Sequence[float], spec: GlareSpec) -> np.ndarray:
    """Render :class:`GlareSpec` centred on ``center_xy``; float32 ``(height, width)``.

    Examples
    --------
    >>> g = glare((11, 11), (5, 5), GlareSpec(level=10.0, core_px=2.0))
    >>> float(g[5, 5]), round(float(g[5, 7]), 2)  # 10 * (2 / (2 + 2))
    (10.0, 5.0)
    """
    h, w = _shape(shape)
    cx, cy = (float(v) for v in center_xy)
    yy, xx = np.mgrid[:h, :w]
    dx, dy = xx - cx, yy - cy
    rho = np.hypot(dx, dy)
    out = spec.level * (spec.core_px / (rho + spec.core_px)) ** spec.falloff
    if spec.streaks:
        theta = np.degrees(np.arctan2(dy, dx))
        mod = np.zeros_like(out)
        for j in range(spec.streaks):
            a = spec.rotation_deg + 360.0 * j / spec.streaks
            delta = (theta - a + 180.0) % 360.0 - 180.0
            mod += np.exp(-0.5 * (delta / spec.streak_width_deg) ** 2)
        out *= 1.0 + spec.streak_gain * mod
    return out.astype(np.float32)


@dataclass(frozen=True)
class GhostSpec:
    """One reflective ghost (see the module docstring).

    Parameters
    ----------
    k : float
        Position factor: the ghost sits at ``c + k (L - c)``.
    radius_px : float
        Radius of the green disc.
    level : float
        Peak intensity at the rim (8-bit units).
    softness : float
        Width of the soft edge as a fraction of the radius.
    hollow : float
        How much dimmer the centre is than the rim (0: flat, 1: black centre).
    fringe : float
        Relative spread of ``k`` and radius between red and blue (colour fringes).

    Examples
    --------
    >>> GhostSpec(k=-2.0, radius_px=12.0, level=8.0).hollow
    0.3
    """

    k: float
    radius_px: float
    level: float
    softness: float = 0.15
    hollow: float = 0.3
    fringe: float = 0.02

    def __post_init__(self) -> None:
        check_range("ghost k", self.k)
        check_range("ghost radius_px", self.radius_px, 0, lo_open=True)
        check_range("ghost level", self.level, 0)
        check_range("ghost softness", self.softness, 0, 1, lo_open=True)
        check_range("ghost hollow", self.hollow, 0, 1)
        check_range("ghost fringe", self.fringe, 0, 0.5)


def render_ghosts(
    out: np.ndarray,
    light_xy: Sequence[float],
    ghosts: Sequence[GhostSpec],
    *,
    center_xy: Sequence[float] | None = None,
    gain: float = 1.0,
) -> np.ndarray:
    """Add the ghosts of a light at ``light_xy`` to ``out`` (float32 ``(H, W)``, in place).

    Parameters
    ----------
    out : numpy.ndarray
        The image to add to.
    light_xy : (x, y)
        Position of the light source.
    ghosts : sequence of GhostSpec
    center_xy : (x, y), optional
        The optical centre; defaults to the image centre ``((W - 1) / 2, (H - 1) / 2)``.
    gain : float
        Multiplies every ghost's level (e.g. the light's flicker).

    Returns
    -------
    numpy.ndarray
        ``out``.

    Examples
    --------
    >>> img = np.zeros((21, 41), dtype=np.float32)
    >>> _ = render_ghosts(img, (30, 10), [GhostSpec(k=-1.0, radius_px=3, level=8, hollow=0)])
    >>> round(float((img.sum(axis=0) * np.arange(41)).sum() / img.sum()))  # mirror of x = 30
    10
    """
    if not isinstance(out, np.ndarray) or out.ndim != 2 or out.dtype != np.float32:
        raise SimError("out must be a float32 (height, width) array")
    h, w = out.shape
    cx, cy = ((w - 1) / 2.0, (h - 1) / 2.0) if center_xy is None else map(float, center_xy)
    lx, ly = (float(v) for v in light_xy)
    n = len(ghosts)
    gx, gy, gr, gl, gs, gh = (np.empty(3 * n) for _ in range(6))
    for i, g in enumerate(ghosts):
        for c, offset in enumerate((1.0, 0.0, -1.0)):  # red, green, blue
            k = g.k * (1.0 + g.fringe * offset)
            j = 3 * i + c
            gx[j] = cx + k * (lx - cx)
            gy[j] = cy + k * (ly - cy)
            gr[j] = g.radius_px * (1.0 + 0.5 * g.fringe * offset)
            gl[j] = gain * g.level * _LUMA[c]
            gs[j] = max(g.softness * gr[j], 0.5)
            gh[j] = g.hollow
    _splat_discs(out, gx, gy, gr, gl, gs, gh)
    return out


@numba.njit(cache=True, nogil=True)
def _splat_discs(out, cx, cy, radius, level, soft, hollow):  # pragma: no cover - compiled
    """Add soft discs (rim-bright by ``hollow``) within their bounding boxes."""
    h, w = out.shape
    for j in range(cx.size):
        if level[j] <= 0.0:
            continue
        reach = radius[j] + soft[j]
        y0 = max(0, math.floor(cy[j] - reach))
        y1 = min(h, math.ceil(cy[j] + reach) + 1)
        x0 = max(0, math.floor(cx[j] - reach))
        x1 = min(w, math.ceil(cx[j] + reach) + 1)
        inv_r = 1.0 / radius[j]
        for y in range(y0, y1):
            dy = y - cy[j]
            for x in range(x0, x1):
                dx = x - cx[j]
                d = math.sqrt(dx * dx + dy * dy)
                edge = min(1.0, max(0.0, (radius[j] - d) / soft[j] + 0.5))
                if edge > 0.0:
                    q = min(1.0, d * inv_r)
                    out[y, x] += level[j] * edge * (1.0 - hollow[j] * (1.0 - q * q))


def find_flare7k_pairs(root: str | os.PathLike[str]) -> list[tuple[Path, Path]]:
    """Every ``Compound_Flare/NAME`` under ``root`` whose ``../Light_Source/NAME`` exists.

    Flare7K++ keeps each flare image and its light-source-only twin under the
    same name in sibling folders (``Flare7K/Scattering_Flare/{Compound_Flare,
    Light_Source}``, ``Flare-R/{Compound_Flare, Light_Source}``). Sorted by path.

    Raises
    ------
    EventFileError
        If ``root`` is not a folder or holds no pair.
    """
    root = Path(root)
    if not root.is_dir():
        raise EventFileError(root, "not a folder; pass the root of a Flare7K++ copy")
    pairs = []
    for folder in sorted(root.rglob(FLARE7K_COMPOUND)):
        light_dir = folder.parent / FLARE7K_LIGHT
        if not folder.is_dir() or not light_dir.is_dir():
            continue
        lights = {p.stem: p for p in light_dir.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES}
        for p in sorted(folder.iterdir()):
            if p.suffix.lower() in _IMAGE_SUFFIXES and p.stem in lights:
                pairs.append((p, lights[p.stem]))
    if not pairs:
        raise EventFileError(
            root,
            f"no {FLARE7K_COMPOUND}/NAME with a matching {FLARE7K_LIGHT}/NAME image was found",
        )
    return pairs


def _load_linear(path: Path, gamma: float) -> np.ndarray:
    try:
        with Image.open(path) as im:
            rgb = np.asarray(im.convert("RGB"), dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise EventFileError(path, f"cannot read the image ({exc})") from None
    lin = WHITE * (rgb / 255.0) ** gamma
    return (lin @ np.array(_LUMA)).astype(np.float32)


def load_flare7k_pair(compound: Path, light: Path, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """Load one Flare7K++ pair as linear luminance ``(flare, light)`` on the 8-bit scale.

    Parameters
    ----------
    compound, light : Path
        The two images (same size).
    gamma : float
        Linearisation exponent (the simulator draws it in [1.8, 2.2]).
    """
    check_range("gamma", gamma, 1.0, 3.0)
    flare = _load_linear(Path(compound), gamma)
    src = _load_linear(Path(light), gamma)
    if flare.shape != src.shape:
        raise EventFileError(
            light, f"size {src.shape[::-1]} differs from its flare image's {flare.shape[::-1]}"
        )
    return flare, src
