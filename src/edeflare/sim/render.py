r"""Intensity videos of one script: the flare video (real lens) and the light video (ideal lens).

:func:`render` streams ``(t_us, flare_frame, light_frame)`` with float32
``(H, W)`` frames on the 8-bit linear scale; nothing is kept between frames
but two small templates, so 600 frames of 640x480 never sit in memory at once.

Templates (built once per script, centred on the light at ``anchor``):

- synthetic (default): a light of radiance :math:`R = \mathrm{exposure}\cdot
  \mathrm{peak}` (radius and profile from the script), convolved with the
  script's perturbed PSF, plus the glare; then *exposed* like a Flare7K++ asset,
  :math:`T_f = \min(W\,[R\,(I_{light} * \mathrm{PSF}_{ob}) + G], \mathrm{peak})`
  with :math:`W` a round window that fades the template out at its border.
  The light template is :math:`T_l = \min(R\,I_{light}, \mathrm{peak})`
  (``gt_lens="ideal"``) or the same through the clean PSF (``"clean"``).
- Flare7K++ (``script.flare7k`` and a ``flare7k`` folder): the chosen
  ``Compound_Flare`` / ``Light_Source`` pair, linearised with the script's
  gamma, scaled to the sensor height and by ``peak / 255``; the anchor is the
  centroid of the light image's brightest pixels.

Before use, templates are blurred by a Gaussian of 0.6 output pixels so that
resampling their clipped, hard-edged sources at moving sub-pixel positions
does not alias (the light's total intensity stays constant to about 0.1 %).

Frame :math:`i` at :math:`t_i`: with the flicker factor :math:`f(t)`, the
light position :math:`p(t)` (:meth:`FlareScript.position_px`) and the affine
matrix :math:`A`, each template is resampled bilinearly at
:math:`A^{-1}(\mathbf x - p(t)) + \mathrm{anchor}` and scaled by :math:`f(t)`;
the flare frame adds the ghosts of a light at :math:`p(t)` (also scaled by
:math:`f(t)`) and is clipped at :data:`~edeflare.sim.flare.WHITE`. Frame 0 is
at :math:`t = 0`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from scipy import ndimage

from ..errors import EventFileError
from ..events import SensorSize, check_sensor_size
from ._validation import SimError
from .flare import (
    WHITE,
    find_flare7k_pairs,
    glare,
    light_source,
    load_flare7k_pair,
    render_ghosts,
    scattering_flare,
)
from .optics import psf_pair
from .script import FlareScript

__all__ = ["Renderer", "Templates", "build_templates", "flare7k_names", "render"]

_ONE = np.uint64(1)


@dataclass(frozen=True)
class Templates:
    """The static flare and light images of a script and where the light sits in each (x, y)."""

    flare: np.ndarray
    light: np.ndarray
    flare_anchor: tuple[float, float]
    light_anchor: tuple[float, float]


def flare7k_names(root: str | os.PathLike[str]) -> list[str]:
    """Names (paths relative to ``root``) of the Flare7K++ pairs under ``root``, for scripts.

    See :func:`edeflare.sim.flare.find_flare7k_pairs` for the layout and the errors.
    """
    root = Path(root)
    return [p.relative_to(root).as_posix() for p, _ in find_flare7k_pairs(root)]


def build_templates(
    script: FlareScript,
    sensor_size: SensorSize = (640, 480),
    *,
    flare7k: str | os.PathLike[str] | None = None,
) -> Templates:
    """Build the flare and light templates of ``script`` (see the module docstring).

    Examples
    --------
    >>> from edeflare.sim.optics import PSFConfig
    >>> tp = build_templates(FlareScript(psf=PSFConfig(grid=64, dust_count=5)))
    >>> tp.flare.shape, float(tp.light.max()) == FlareScript().light.peak  # 64 + 2 (4 r + 2)
    ((100, 100), True)
    """
    _width, height = check_sensor_size(sensor_size)
    peak = script.light.peak
    if script.flare7k is not None:
        if flare7k is None:
            raise SimError(
                f"the script uses the Flare7K++ pair {script.flare7k.name!r}; "
                "pass the folder holding it (flare7k=...)"
            )
        root = Path(flare7k)
        pairs = {p.relative_to(root).as_posix(): (p, q) for p, q in find_flare7k_pairs(root)}
        if script.flare7k.name not in pairs:
            raise EventFileError(root, f"holds no Flare7K++ pair named {script.flare7k.name!r}")
        flare, light = load_flare7k_pair(*pairs[script.flare7k.name], script.flare7k.gamma)
        zoom = height / flare.shape[0]
        flare = ndimage.zoom(flare, zoom, order=1) * (peak / WHITE)
        light = ndimage.zoom(light, zoom, order=1) * (peak / WHITE)
        yy, xx = np.nonzero(light >= 0.5 * light.max())
        if yy.size == 0:
            raise EventFileError(pairs[script.flare7k.name][1], "the light-source image is black")
        w = light[yy, xx]
        anchor = (float((xx * w).sum() / w.sum()), float((yy * w).sum() / w.sum()))
        return Templates(flare.astype(np.float32), light.astype(np.float32), anchor, anchor)

    pair = psf_pair(script.psf, rng=script.psf_seed)
    lt = script.light
    margin = math.ceil(4 * lt.radius_px) + 2
    size = script.psf.grid + 2 * margin
    c = size // 2
    radiance = lt.exposure * peak
    src = light_source((size, size), (c, c), lt.radius_px, radiance, profile=lt.profile)
    flare = scattering_flare(src, pair.perturbed)
    if script.glare is not None:
        flare += glare((size, size), (c, c), script.glare)
    light = scattering_flare(src, pair.clean) if script.gt_lens == "clean" else src
    flare *= _round_window(size)
    flare = np.minimum(flare, peak)
    light = np.minimum(light, peak)
    # Keep the light template small: its support is a few pixels around the source.
    lo, hi = _support(light, peak * 1e-4)
    light = np.ascontiguousarray(light[lo[0] : hi[0], lo[1] : hi[1]], dtype=np.float32)
    return Templates(
        flare.astype(np.float32), light, (float(c), float(c)), (float(c - lo[1]), float(c - lo[0]))
    )


def _round_window(size: int) -> np.ndarray:
    """1 within 80 % of the half-size, a cosine down to 0 at it: no template edge shows."""
    yy, xx = np.mgrid[:size, :size] - size // 2
    rho = np.hypot(xx, yy) / (size / 2)
    edge = np.clip((rho - 0.8) / 0.2, 0.0, 1.0)
    return (np.cos(0.5 * np.pi * edge) ** 2).astype(np.float32)


def _support(img: np.ndarray, threshold: float) -> tuple[tuple[int, int], tuple[int, int]]:
    rows = np.flatnonzero((img > threshold).any(axis=1))
    cols = np.flatnonzero((img > threshold).any(axis=0))
    if rows.size == 0:
        return (0, 0), img.shape
    return (int(rows[0]), int(cols[0])), (int(rows[-1]) + 1, int(cols[-1]) + 1)


def _shift(anchor: tuple[float, float], by: float) -> tuple[float, float]:
    return anchor[0] + by, anchor[1] + by


def _padded(img: np.ndarray, anchor: tuple[float, float]) -> tuple[np.ndarray, tuple[float, float]]:
    """The template with a 2-pixel zero border (what :func:`_warp_add` expects)."""
    return np.pad(np.asarray(img, dtype=np.float32), 2), _shift(anchor, 2.0)


def _antialias(img: np.ndarray, scale: float) -> np.ndarray:
    """Blur a template just enough (sigma 0.6 px at the output scale) that resampling it at
    moving sub-pixel positions does not alias: clipped sources have hard edges."""
    return ndimage.gaussian_filter(img, 0.6 / min(scale, 1.0), mode="constant")


class Renderer:
    """Frames of one script on one sensor, computed on demand (see :func:`render`).

    Parameters
    ----------
    script : FlareScript
    sensor_size : (width, height)
    flare7k : path, optional
        Folder of a Flare7K++ copy, needed when ``script.flare7k`` is set.

    Examples
    --------
    >>> from edeflare.sim.script import draw_script
    >>> r = Renderer(draw_script(rng=0), (64, 48))
    >>> flare, light = r.frame(0)
    >>> flare.shape, flare.dtype, bool((flare >= light).mean() > 0.9)
    ((48, 64), dtype('float32'), True)
    """

    def __init__(
        self,
        script: FlareScript,
        sensor_size: SensorSize = (640, 480),
        *,
        flare7k: str | os.PathLike[str] | None = None,
    ) -> None:
        if not isinstance(script, FlareScript):
            raise SimError(f"script must be a FlareScript, got {type(script).__name__}")
        self.script = script
        self.sensor_size = check_sensor_size(sensor_size)
        self.templates = build_templates(script, self.sensor_size, flare7k=flare7k)
        self._inverse = np.linalg.inv(script.affine.matrix())
        tp = self.templates
        scale = script.affine.scale
        self._sources = (
            _padded(_antialias(tp.flare, scale), tp.flare_anchor),
            _padded(_antialias(np.pad(tp.light, 3), scale), _shift(tp.light_anchor, 3)),
        )

    def frame(self, t_us: float) -> tuple[np.ndarray, np.ndarray]:
        """The flare frame and the light frame at ``t_us``: float32 ``(H, W)`` each."""
        width, height = self.sensor_size
        s = self.script
        gain = float(s.intensity(t_us))
        px, py = s.position_px(t_us, self.sensor_size)
        flare = np.zeros((height, width), dtype=np.float32)
        light = np.zeros((height, width), dtype=np.float32)
        m = self._inverse
        for (img, (ax, ay)), out in zip(self._sources, (flare, light), strict=True):
            _warp_add(img, out, m[0, 0], m[0, 1], m[1, 0], m[1, 1], px, py, ax, ay, gain)
        if s.ghosts:
            render_ghosts(flare, (px, py), s.ghosts, gain=gain)
        np.minimum(flare, WHITE, out=flare)
        np.minimum(light, WHITE, out=light)
        return flare, light

    def __iter__(self) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        for t in self.script.frame_times_us().tolist():
            flare, light = self.frame(t)
            yield t, flare, light


def render(
    script: FlareScript,
    sensor_size: SensorSize = (640, 480),
    *,
    flare7k: str | os.PathLike[str] | None = None,
) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Stream ``(t_us, flare_frame, light_frame)`` for every frame of ``script``.

    Parameters
    ----------
    script : FlareScript
    sensor_size : (width, height)
    flare7k : path, optional
        Folder of a Flare7K++ copy, needed when ``script.flare7k`` is set.

    Yields
    ------
    (int, numpy.ndarray, numpy.ndarray)
        Time in µs and two float32 ``(H, W)`` linear intensity frames (8-bit
        scale): through the flare lens, and through an ideal lens (no
        scattering flare, no ghosts).

    Examples
    --------
    >>> from edeflare.sim.script import FlareScript
    >>> frames = list(render(FlareScript(duration_us=1000, fps=2000.0), (32, 24)))
    >>> [t for t, _, _ in frames], bool(frames[0][2].max() > 100)
    ([0, 500, 1000], True)
    """
    return iter(Renderer(script, sensor_size, flare7k=flare7k))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _x_range(c, b, hi, lo_x, hi_x):  # pragma: no cover - compiled
    """The ``x`` in ``[lo_x, hi_x]`` with ``0 <= c x + b <= hi``, as floats (empty: lo > hi)."""
    if c > 0.0:
        return max(lo_x, -b / c), min(hi_x, (hi - b) / c)
    if c < 0.0:
        return max(lo_x, (hi - b) / c), min(hi_x, -b / c)
    if 0.0 <= b <= hi:
        return lo_x, hi_x
    return 1.0, 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _warp_add(tpl, out, m00, m01, m10, m11, px, py, ax, ay, gain):  # pragma: no cover - compiled
    """``out[y, x] += gain * tpl(M (x - px, y - py) + anchor)``, bilinear.

    ``tpl`` has a border of zeros at least one pixel wide, so sampling it
    anywhere in ``[0, size - 1]`` needs no bounds test; each row visits only
    the pixels whose sample falls there.
    """
    th, tw = tpl.shape
    h, w = out.shape
    qx_hi = tw - 1.000001
    qy_hi = th - 1.000001
    for y in range(h):
        dy = y - py
        bx = m01 * dy + ax - m00 * px  # qx = m00 x + bx
        by = m11 * dy + ay - m10 * px  # qy = m10 x + by
        lo1, hi1 = _x_range(m00, bx, qx_hi, 0.0, w - 1.0)
        lo2, hi2 = _x_range(m10, by, qy_hi, lo1, hi1)
        if lo2 > hi2:
            continue
        x0 = max(0, math.ceil(lo2 - 1e-9))
        x1 = min(w - 1, math.floor(hi2 + 1e-9))
        row = out[y]
        # Unsigned indices (the samples are clamped >= 0): no negative-index checks, so the
        # loop vectorises.
        for x in range(np.uint64(x0), np.uint64(x1 + 1)):
            qx = min(max(m00 * x + bx, 0.0), qx_hi)
            qy = min(max(m10 * x + by, 0.0), qy_hi)
            ix = np.uint64(qx)
            iy = np.uint64(qy)
            fx = qx - np.float64(ix)
            fy = qy - np.float64(iy)
            top = (1.0 - fx) * tpl[iy, ix] + fx * tpl[iy, ix + _ONE]
            bottom = (1.0 - fx) * tpl[iy + _ONE, ix] + fx * tpl[iy + _ONE, ix + _ONE]
            row[x] += gain * ((1.0 - fy) * top + fy * bottom)
