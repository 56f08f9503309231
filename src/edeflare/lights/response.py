"""How long a moving light's pixels keep firing after it has passed them.

Every pixel a moving light's disc covers fires a train: OFF events as the light
arrives, ON events as it leaves, and the last ON events come after the disc has left
the pixel, while its photoreceptor settles. Those are the light's own events on its own
pixels, not scattered light, so a scorer counts the disc's recent path (a comet) as the
light: :attr:`~edeflare.lights.LightSource.response_us` says how far back.
:func:`light_response` measures it from a recording: for each pixel the disc passes
well inside its rim, the time from the disc's exit to the pixel's last event, and a
high quantile of those delays over the pixels.

Examples
--------
>>> from edeflare.events import make_events
>>> track = LightSource.track([[0, 10, 20, 4], [60_000, 70, 20, 4]])  # 1 px per ms
>>> px = np.arange(10, 71)
>>> exit_us = (px - 10 + 4) * 1000.0  # the disc leaves a pixel 4 px after reaching it
>>> ev = make_events(np.sort(exit_us + 650), px, np.full(px.size, 20), np.ones(px.size, int))
>>> light_response(ev, track).response_us  # 0.65 ms, rounded up to 0.1 ms
700.0
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial import cKDTree

from ..events import check_events
from .source import LightSource

__all__ = ["LightResponse", "light_response"]

RESPONSE_QUANTILE = 0.95
"""The share of a light's pixels whose last event comes within its response time (the
quantile the Gen3 annotation's response time was measured at)."""


@dataclasses.dataclass(frozen=True)
class LightResponse:
    """What :func:`light_response` found.

    ``response_us`` is None where the light does not move or no pixel qualifies;
    ``delays_us`` holds each measured pixel's last event minus the disc's exit
    (negative: it stopped firing before); ``after_share`` the share of their trains'
    events that come after the exit; ``trains`` (when asked for) a few pixels' events
    as ``(time - exit, polarity)`` rows, for a picture.
    """

    response_us: float | None
    delays_us: np.ndarray
    speed_px_per_us: float
    after_share: float = 0.0
    trains: tuple[np.ndarray, ...] = ()

    def record(self) -> dict:
        """Plain numbers for an annotation's checks."""
        q = np.quantile(self.delays_us, [0.5, 0.9, 0.95, 0.99]) if self.delays_us.size else []
        return {
            "response_pixels": int(self.delays_us.size),
            "response_events_after_exit_share": round(self.after_share, 4),
            "response_last_event_after_exit_us_p50_p90_p95_p99": [round(float(v)) for v in q],
            "response_quantile": RESPONSE_QUANTILE,
            "blob_speed_px_per_ms": round(self.speed_px_per_us * 1000, 2),
        }


def light_response(
    events: np.ndarray,
    source: LightSource,
    *,
    quantile: float = RESPONSE_QUANTILE,
    trains: int = 0,
) -> LightResponse:
    """Measure how long the pixels a moving light covered keep firing after it left.

    For each pixel whose distance ``m`` to the light's path is below ``r - 2`` px and
    which the disc passes between 10 ms after the recording's start and 15 ms before
    its end, the disc leaves it ``sqrt(r^2 - m^2) / v`` after its closest approach
    (``v`` the light's mean speed); its train is its events from 10 ms before the
    approach to 30 ms after. The response time is the ``quantile`` of (last event -
    exit), rounded up to 0.1 ms and at least 0.

    Parameters
    ----------
    events : numpy.ndarray
        The recording (sorted).
    source : LightSource
        A ``track`` or ``steps`` light; its median radius is used.
    quantile : float
        The share of pixels whose last event comes within the response time.
    trains : int
        Also return the trains of about this many pixels (for a picture).

    Returns
    -------
    LightResponse
        ``response_us`` None for a light whose path spans less than its diameter
        (however long a jittering track is), or where no pixel qualifies.
    """
    check_events(events)
    table = source.table[np.isfinite(source.table[:, 1])]
    none = LightResponse(None, np.zeros(0), 0.0)
    if source.kind not in ("track", "steps") or len(table) < 2 or events.size == 0:
        return none
    r = float(np.median(table[:, 3]))
    tt = np.linspace(table[0, 0], table[-1, 0], 5_000)
    tx, ty, _ = source.at(tt)
    ok = np.isfinite(tx)
    tt, tx, ty = tt[ok], tx[ok], ty[ok]
    path = float(np.hypot(np.diff(tx), np.diff(ty)).sum())
    if math.hypot(np.ptp(tx), np.ptp(ty)) < 2 * r or tt[-1] <= tt[0]:
        # a light that stays where it is (a detected lamp's track only jitters): its
        # pixels never see it leave
        return none
    speed = path / float(tt[-1] - tt[0])  # px/us
    t = events["t"].astype(np.int64)
    width = int(events["x"].max()) + 1
    pix = events["y"].astype(np.int64) * width + events["x"]
    order = np.lexsort((t, pix))
    pix_s, t_s, p_s = pix[order], t[order], events["p"][order]
    uniq, start, count = np.unique(pix_s, return_index=True, return_counts=True)
    ux, uy = (uniq % width).astype(np.float64), (uniq // width).astype(np.float64)
    # each pixel's closest approach: the nearest of the path's samples
    dist, nearest = cKDTree(np.c_[tx, ty]).query(np.c_[ux, uy])
    passed = tt[nearest]
    chosen = np.flatnonzero((dist < r - 2) & (passed > t[0] + 10_000) & (passed < t[-1] - 15_000))
    delays, kept_trains, after, total = [], [], 0, 0
    for n, k in enumerate(chosen):
        sl = slice(start[k], start[k] + count[k])
        ts = t_s[sl]
        keep = (ts > passed[k] - 10_000) & (ts < passed[k] + 30_000)
        if not keep.any():
            continue
        rel = ts[keep] - (passed[k] + np.sqrt(r * r - dist[k] ** 2) / speed)
        delays.append(rel[-1])
        after += int((rel > 0).sum())
        total += rel.size
        if trains and n % max(1, chosen.size // trains) == 0 and len(kept_trains) < trains:
            kept_trains.append(np.c_[rel, p_s[sl][keep]])
    if not delays:
        return LightResponse(None, np.zeros(0), speed)
    delays_us = np.asarray(delays, dtype=np.float64)
    q = float(np.quantile(delays_us, quantile))
    return LightResponse(max(0.0, float(np.ceil(q / 100.0) * 100.0)), delays_us, speed,
                         after / total, tuple(kept_trains))  # fmt: skip
