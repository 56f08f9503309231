"""A no-reference flare score: energy around a light source relative to the source itself.

Lens flare spreads a light source's energy into halos and streaks around it;
de-flaring should remove that spread and keep the source. The score needs no
ground truth: it is computed on one energy map ``E`` (``(H, W)``, non-negative),
such as the event counts of a window (:func:`event_energy`) or the magnitude
``|L|`` of a reconstructed image (:mod:`edeflare.eval.reconstruct`).

Definition (:func:`flare_score`):

1. **Source.** The centre ``c`` is the brightest compact region of ``E``,
   found by the project's one light-source detector,
   :func:`edeflare.lights.detect_light_source` (3x3 median against hot
   pixels, a Gaussian of standard deviation ``2 r_s``, the region above
   half its maximum; its centroid, rounded). Compare streams on the same
   geometry: locate the source once, on the input, and score every stream
   with it.
2. **Regions.** With ``d`` the distance to ``c``: the *source* disc
   ``d <= r_s``, the *flare* annulus ``r_s < d <= r_f``, the *far field*
   ``d > r_f``. Defaults: ``r_s = max(2, 0.04 min(W, H))``,
   ``r_f = 0.4 min(W, H)`` (10 and 104 pixels at 346x260).
3. **Background.** ``b`` = the median of ``E`` over the far field (0 when it
   is empty); each region's energy is ``sum(max(E - b, 0))`` over its pixels.
4. **Score.** ``flare score = E_flare / E_source``: 0 for a source without
   flare, large when the halo and streaks carry much more energy than the
   source. NaN when the source region holds no energy above the background
   (nothing to measure). A ratio has a heavy tail (a mislocated source makes
   ``E_source`` small), so aggregate scores with the median.

Lower after de-flaring means less flare; a method that also erases the light
source raises the score (the denominator shrinks), as it should.
:func:`region_energies` gives the two energies themselves: compared with the
input's on the same regions, they say how much of the flare a method left
and how much of the source it kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..events import SensorSize, count_map
from ..lights import detect_light_source

__all__ = [
    "FlareGeometry",
    "event_energy",
    "flare_geometry",
    "flare_score",
    "region_energies",
]


@dataclass(frozen=True)
class FlareGeometry:
    """Where the source is and how far its flare is measured (pixels)."""

    center: tuple[int, int]
    """``(x, y)`` of the source."""
    source_radius_px: float
    flare_radius_px: float

    def masks(self, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Boolean ``(source, flare, far)`` masks for an ``(H, W)`` map."""
        h, w = shape
        yy, xx = np.ogrid[:h, :w]
        d2 = (xx - self.center[0]) ** 2 + (yy - self.center[1]) ** 2
        source = d2 <= self.source_radius_px**2
        within = d2 <= self.flare_radius_px**2
        return source, within & ~source, ~within


def event_energy(events: np.ndarray, sensor_size: SensorSize) -> np.ndarray:
    """Events per pixel (both polarities): a ``float64`` ``(H, W)`` energy map.

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> event_energy(make_events([0, 1, 2], [1, 1, 0], [0, 0, 0], [1, 0, 1]), (2, 1)).tolist()
    [[1.0, 2.0]]
    """
    return count_map(events, sensor_size).astype(np.float64)


def _check_energy(energy: np.ndarray) -> np.ndarray:
    energy = np.asarray(energy, dtype=np.float64)
    if energy.ndim != 2 or energy.size == 0:
        raise ParameterError(f"energy must be a non-empty (H, W) map, got shape {energy.shape}")
    if not np.isfinite(energy).all() or (energy < 0).any():
        raise ParameterError("energy must be finite and non-negative")
    return energy


def _default_radii(
    shape: tuple[int, int], source_radius_px: float | None, flare_radius_px: float | None
) -> tuple[float, float]:
    short = min(shape)
    rs = max(2.0, 0.04 * short) if source_radius_px is None else float(source_radius_px)
    rf = 0.4 * short if flare_radius_px is None else float(flare_radius_px)
    if not (math.isfinite(rs) and math.isfinite(rf) and 0 < rs < rf):
        raise ParameterError(f"need 0 < source_radius_px < flare_radius_px, got {rs!r} and {rf!r}")
    return rs, rf


def flare_geometry(
    energy: np.ndarray,
    *,
    source_radius_px: float | None = None,
    flare_radius_px: float | None = None,
) -> FlareGeometry:
    """Locate the source on ``energy`` and fix the radii (defaults: see the module docstring).

    Examples
    --------
    >>> e = np.zeros((100, 100)); e[40:43, 60:63] = 5.0
    >>> flare_geometry(e)
    FlareGeometry(center=(61, 41), source_radius_px=4.0, flare_radius_px=40.0)
    """
    energy = _check_energy(energy)
    rs, rf = _default_radii(energy.shape, source_radius_px, flare_radius_px)
    try:
        (light,) = detect_light_source(energy, sigma_px=2.0 * rs, max_sources=1, min_area_px=1)
    except ParameterError:  # no energy left after the median filter: nothing to centre on
        return FlareGeometry((energy.shape[1] // 2, energy.shape[0] // 2), rs, rf)
    return FlareGeometry((round(light.cx), round(light.cy)), rs, rf)


def flare_score(
    energy: np.ndarray,
    geometry: FlareGeometry | None = None,
    *,
    source_radius_px: float | None = None,
    flare_radius_px: float | None = None,
) -> float:
    """Flare-to-source energy ratio of an energy map (lower: less flare).

    Parameters
    ----------
    energy : numpy.ndarray
        Non-negative ``(H, W)`` map (event counts, or ``|L|`` of a reconstruction).
    geometry : FlareGeometry, optional
        Source and radii, e.g. located on the input to score a de-flared
        output on the same regions; default :func:`flare_geometry` of ``energy``.
    source_radius_px, flare_radius_px : float, optional
        Radii when ``geometry`` is not given.

    Returns
    -------
    float
        ``sum over r_s < d <= r_f of max(E - b, 0)`` over ``sum over d <= r_s
        of max(E - b, 0)``, ``b`` the far-field median; NaN if the source
        region holds no energy above ``b``.

    Examples
    --------
    A source alone scores 0; the same source with two streaks scores more:

    >>> e = np.zeros((60, 80)); e[29:32, 39:42] = 10.0
    >>> flare_score(e)
    0.0
    >>> e[30, 42:60] = 4.0; e[30, 20:39] = 4.0
    >>> round(flare_score(e), 4)  # (68 + 72) / (90 + 8): r_s = 2.4, r_f = 24 pixels
    1.4286
    """
    energy = _check_energy(energy)
    if geometry is None:
        geometry = flare_geometry(
            energy, source_radius_px=source_radius_px, flare_radius_px=flare_radius_px
        )
    e_source, e_flare = region_energies(energy, geometry)
    return e_flare / e_source if e_source > 0 else math.nan


def region_energies(energy: np.ndarray, geometry: FlareGeometry) -> tuple[float, float]:
    """``(E_source, E_flare)``: the energies above the far-field median of the two regions.

    :func:`flare_score` is their ratio. Compared with the same regions of
    the input, they tell *how* a method changed the score: the share of the
    flare energy it left and the share of the source energy it kept.

    Examples
    --------
    >>> e = np.zeros((50, 50)); e[25, 25] = 10.0; e[25, 30] = 4.0; e[0, 0] = 7.0
    >>> region_energies(e, FlareGeometry((25, 25), 2.0, 20.0))
    (10.0, 4.0)
    """
    energy = _check_energy(energy)
    source, flare, far = geometry.masks(energy.shape)
    b = float(np.median(energy[far])) if far.any() else 0.0
    excess = np.maximum(energy - b, 0.0)
    return float(excess[source].sum()), float(excess[flare].sum())
