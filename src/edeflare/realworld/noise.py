"""Background noise: the sensor's background rate, and Poisson noise drawn at it."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..events import EVENT_DTYPE, SensorSize, check_events, check_sensor_size, merge_events
from ..lights.detect import count_map_of
from ._common import _check_mask, _positive_int


@dataclass(frozen=True)
class NoiseEstimate:
    """The sensor's background activity, measured by :func:`estimate_background_rate`.

    Attributes
    ----------
    rate_hz : float
        Background events per second per pixel.
    on_fraction : float
        Fraction of ON events in the background.
    pixels : int
        Pixels the estimate pools (the quiet tiles' usable pixels).
    tiles : int
        Quiet tiles pooled.
    """

    rate_hz: float
    on_fraction: float
    pixels: int
    tiles: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return dataclasses.asdict(self)


def estimate_background_rate(
    data: np.ndarray,
    duration_us: int,
    sensor_size: SensorSize | None = None,
    *,
    on_counts: np.ndarray | None = None,
    exclude: np.ndarray | None = None,
    tile_px: int = 16,
    quantile: float = 0.25,
    hot_factor: float = 10.0,
) -> NoiseEstimate:
    """Per-pixel background event rate (Hz) from the quiet regions of a recording.

    1. Pixels in ``exclude`` (e.g. light sources and their glare) and hot
       pixels (more than ``hot_factor`` times the median count + 1) are unusable.
    2. The sensor is cut into ``tile_px`` x ``tile_px`` tiles; tiles with
       fewer than half their pixels usable are dropped. Each tile's rate is
       its usable pixels' mean count over the duration.
    3. The floor is the ``quantile`` of the tile rates; quiet tiles are those
       within three Poisson standard errors of the floor (so on a sensor that
       sees only noise nearly every tile is quiet, and in a busy scene only
       the static ones are).
    4. The rate is the pooled mean over the quiet tiles' usable pixels, and
       the ON fraction their pooled ON share.

    Parameters
    ----------
    data : numpy.ndarray
        Events (with ``sensor_size``) or an ``(H, W)`` count map.
    duration_us : int
        Span the counts were collected over (µs).
    on_counts : numpy.ndarray, optional
        ``(H, W)`` ON counts, for the ON fraction with a count map (else 0.5).
    exclude : numpy.ndarray of bool, optional
        ``(H, W)`` pixels to ignore.

    Returns
    -------
    NoiseEstimate

    Examples
    --------
    >>> counts = np.random.default_rng(0).poisson(3.0, (64, 64))  # 3 events in 2 s
    >>> counts[:16, :16] += 50  # a busy corner
    >>> est = estimate_background_rate(counts, 2_000_000)
    >>> round(est.rate_hz, 1), est.tiles
    (1.5, 15)
    """
    duration_us = _positive_int("duration_us", duration_us)
    if isinstance(data, np.ndarray) and data.dtype == EVENT_DTYPE and on_counts is None:
        counts = count_map_of(data, sensor_size)
        on_counts = count_map_of(data[data["p"] == 1], sensor_size)
    else:
        counts = count_map_of(data, sensor_size)
    height, width = counts.shape
    if on_counts is not None:
        on_counts = np.asarray(on_counts, dtype=np.float64)
        if on_counts.shape != counts.shape:
            raise ParameterError(f"on_counts shape {on_counts.shape} differs from {counts.shape}")
    usable = np.ones_like(counts, dtype=bool)
    if exclude is not None:
        exclude, _ = _check_mask(exclude, (width, height))
        usable &= ~exclude
    if not 0 < quantile < 1:
        raise ParameterError(f"quantile must lie in (0, 1), got {quantile}")
    tile_px = _positive_int("tile_px", tile_px)
    if usable.any():
        usable &= counts <= hot_factor * (float(np.median(counts[usable])) + 1.0)
    yy, xx = np.mgrid[:height, :width]
    n_tx = -(-width // tile_px)
    tile = ((yy // tile_px) * n_tx + xx // tile_px)[usable]
    n_tiles = n_tx * -(-height // tile_px)
    n_px = np.bincount(tile, minlength=n_tiles).astype(np.float64)
    sums = np.bincount(tile, weights=counts[usable], minlength=n_tiles)
    on_sums = (
        np.bincount(tile, weights=on_counts[usable], minlength=n_tiles)
        if on_counts is not None
        else None
    )
    tile_area = np.bincount(
        ((yy // tile_px) * n_tx + xx // tile_px).ravel(), minlength=n_tiles
    ).astype(np.float64)
    good = n_px >= 0.5 * tile_area
    if not good.any():
        raise ParameterError(
            "no quiet region to measure the background rate in (everything excluded); "
            "give the rate explicitly"
        )
    seconds = duration_us / 1e6
    rates = sums[good] / n_px[good] / seconds
    floor = float(np.quantile(rates, quantile))
    typical_px = float(np.median(n_px[good]))
    se = math.sqrt(max(floor, 1.0 / seconds) * seconds * typical_px) / (seconds * typical_px)
    quiet = rates <= floor + 3.0 * se
    total_px = float(n_px[good][quiet].sum())
    total = float(sums[good][quiet].sum())
    rate = total / total_px / seconds
    on_fraction = 0.5
    if on_sums is not None and total > 0:
        on_fraction = float(on_sums[good][quiet].sum()) / total
    return NoiseEstimate(float(rate), float(on_fraction), int(total_px), int(quiet.sum()))


def draw_noise(
    sensor_size: SensorSize,
    rate_hz: float,
    t_start_us: int,
    t_end_us: int,
    *,
    mask: np.ndarray | None = None,
    on_fraction: float = 0.5,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """Poisson background events: ``rate_hz`` per pixel on the mask's pixels over a span.

    Every pixel of ``mask`` (all pixels by default) fires as an independent
    Poisson process of rate ``rate_hz`` over ``[t_start_us, t_end_us)``;
    polarities are ON with probability ``on_fraction``. Draws: the total
    count, then pixels, times and polarities, so a seed gives one stream.

    Examples
    --------
    >>> ev = draw_noise((100, 100), 2.0, 0, 1_000_000, rng=0)  # 2 Hz x 10,000 pixels x 1 s
    >>> 19_500 < ev.size < 20_500, bool((np.diff(ev["t"]) >= 0).all())
    (True, True)
    """
    width, height = check_sensor_size(sensor_size)
    rate = float(rate_hz)
    if not math.isfinite(rate) or rate < 0:
        raise ParameterError(f"rate_hz must be a finite number >= 0, got {rate_hz}")
    if not 0 <= on_fraction <= 1:
        raise ParameterError(f"on_fraction must lie in [0, 1], got {on_fraction}")
    if t_end_us < t_start_us:
        raise ParameterError(f"t_end_us {t_end_us} precedes t_start_us {t_start_us}")
    rng = np.random.default_rng(rng)
    if mask is None:
        pixels = None
        n_pixels = width * height
    else:
        mask, _ = _check_mask(mask, (width, height))
        pixels = np.flatnonzero(mask)
        n_pixels = pixels.size
    expected = rate * (int(t_end_us) - int(t_start_us)) / 1e6 * n_pixels
    n = int(rng.poisson(expected)) if expected > 0 else 0
    which = rng.integers(0, max(n_pixels, 1), n)
    flat = which if pixels is None else pixels[which]
    t = rng.integers(int(t_start_us), max(int(t_end_us), int(t_start_us) + 1), n)
    p = rng.random(n) < on_fraction
    order = np.argsort(t, kind="stable")
    out = np.empty(n, dtype=EVENT_DTYPE)
    out["t"] = t[order]
    out["x"] = (flat % width)[order]
    out["y"] = (flat // width)[order]
    out["p"] = p[order]
    return out


def inject_noise(
    events: np.ndarray,
    sensor_size: SensorSize,
    rate_hz: float,
    t_start_us: int,
    t_end_us: int,
    *,
    mask: np.ndarray | None = None,
    on_fraction: float = 0.5,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """``events`` merged with :func:`draw_noise` (a new sorted stream; ties keep ``events`` first).

    Parameters
    ----------
    events : numpy.ndarray
        The cleaned reference (not modified).
    sensor_size : (width, height)
    rate_hz : float
        Per-pixel rate, e.g. :attr:`NoiseEstimate.rate_hz`.
    t_start_us, t_end_us : int
        Span of the noise.
    mask : numpy.ndarray of bool, optional
        ``(H, W)`` pixels that get noise (e.g. the glare zone that cleaning
        emptied); all pixels by default.
    on_fraction : float
    rng : numpy.random.Generator or int, optional

    Examples
    --------
    >>> from edeflare.events import make_events
    >>> ev = make_events([10], [0], [0], [1])
    >>> out = inject_noise(ev, (10, 10), 100.0, 0, 100_000, rng=1)
    >>> out.size > ev.size, ev.size
    (True, 1)
    """
    check_events(events, sensor_size)
    noise = draw_noise(
        sensor_size, rate_hz, t_start_us, t_end_us, mask=mask, on_fraction=on_fraction, rng=rng
    )
    return merge_events(events, noise)
