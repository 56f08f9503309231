"""Helpers of the baseline tests: plain-Python reference filters and synthetic scenes.

The reference filters are written straight from the behaviour of the original
programs (``../shared/data/golden/README.md``), one event at a
time with ``collections.deque`` queues, float delays compared and truncated
exactly as the C++ does (``int(t_old + d2)``). They are slow and obviously
shaped like the originals; the compiled filters must agree with them event
for event.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from edeflare.events import EVENT_DTYPE

# --------------------------------------------------------------------------------------
# EFR, as the original program runs


class _Cell:
    __slots__ = ("acc", "q1", "q2", "q3", "q4")

    def __init__(self) -> None:
        self.q1: deque = deque()
        self.q2: deque = deque()
        self.q3: deque = deque()
        self.q4: deque = deque()
        self.acc = 0.0


def efr_reference(
    events,
    sensor_size,
    frequency_hz: int = 50,
    rho1: float = 0.6,
    merge_us: int = 10_000,
    threshold: float = 0.7,
    bias=None,
):
    """EFR outputs (no warm-up kept, no shift) in emission order, as a list of (t, x, y, p)."""
    d1 = float(1_000_000 // frequency_hz)  # int division, then stored in a double
    d2 = d1 / 10
    rho2 = 1 - (1 - rho1) / 10
    cells: dict[tuple[int, int], _Cell] = {}
    out: list[tuple[int, int, int, int]] = []

    def sampler(c, t, x, y):
        while c.acc >= threshold or c.acc <= -threshold:
            if c.acc >= threshold:
                out.append((t, x, y, 1))
                c.acc -= threshold
            else:
                out.append((t, x, y, 0))
                c.acc += threshold

    def q4(c, t, v, x, y):
        while c.q4 and t - c.q4[0][0] >= d2:
            ft, fv = c.q4[0]
            c.q4.append([int(d2 + ft), fv])
            c.acc += fv
            sampler(c, int(d2 + ft), x, y)
            c.q4.popleft()
        if c.q4 and abs(c.q4[-1][0] - t) < merge_us:
            c.q4[-1][1] += v
        else:
            c.q4.append([t, v])

    def q3(c, t, v, x, y):
        c.q3.append([t, v])
        while t - c.q3[0][0] >= d2:
            q4(c, int(c.q3[0][0] + d2), -rho2 * c.q3[0][1], x, y)
            c.q3.popleft()
        q4(c, t, v, x, y)

    def q2(c, t, v, x, y):
        while c.q2 and t - c.q2[0][0] >= d1:
            ft, fv = c.q2[0]
            c.q2.append([int(d1 + ft), rho1 * fv])
            q3(c, int(d1 + ft), rho1 * fv, x, y)
            c.q2.popleft()
        if c.q2 and abs(c.q2[-1][0] - t) < merge_us:
            c.q2[-1][1] += v
        else:
            c.q2.append([t, v])

    for t, x, y, p in as_tuples(events):
        c = cells.setdefault((x, y), _Cell())
        b = 0.0 if bias is None else float(bias[y, x])
        u = (1 if p else -1) - b
        c.q1.append([t, u])
        while t - c.q1[0][0] >= d1:
            q2(c, int(c.q1[0][0] + d1), -c.q1[0][1], x, y)
            c.q1.popleft()
        q2(c, t, u, x, y)
    return out


# --------------------------------------------------------------------------------------
# PFD, as the event-by-event program PFDs runs


def pfd_reference(
    events,
    sensor_size,
    score: str = "A",
    delta_t0: int = 20_000,
    delta_t: int = 20_000,
    var: int = 1,
    neibor: int = 3,
    fifo_size: int = 5,
    polupd: bool = False,
    dscore: bool = False,
):
    """The keep mask of PFDs (bool list, input order)."""
    width, height = sensor_size
    p_time = [[0.0] * width for _ in range(height)]
    n_time = [[0.0] * width for _ in range(height)]
    latest = [[0.0] * width for _ in range(height)]
    stored = [[0] * width for _ in range(height)]
    flips = [[deque(maxlen=fifo_size) for _ in range(width)] for _ in range(height)]
    keep = []
    for t, x, y, p in as_tuples(events):
        pol = 1 if p else -1
        if stored[y][x] == 0:
            stored[y][x] = pol
        else:
            if stored[y][x] * pol == -1:
                flips[y][x].append(t)
            if polupd:
                stored[y][x] = pol
        same = p_time if pol == 1 else n_time
        same[y][x] = t
        support = 0
        for ii in (-1, 0, 1):
            for jj in (-1, 0, 1):
                if (ii or jj) and 0 <= y + ii < height and 0 <= x + jj < width:
                    other = same[y + ii][x + jj]
                    if t - other < delta_t0 and other != 0:
                        support += 1
        first = support >= var
        latest[y][x] = t
        n_active = 0
        c_nbr = 0
        c_self = sum(1 for ts in flips[y][x] if t - ts <= delta_t)
        for ii in (-1, 0, 1):
            for jj in (-1, 0, 1):
                if (ii or jj) and 0 <= y + ii < height and 0 <= x + jj < width:
                    if t - latest[y + ii][x + jj] <= delta_t:
                        n_active += 1
                    c_nbr += sum(1 for ts in flips[y + ii][x + jj] if t - ts <= delta_t)
        if n_active == 0:
            keep.append(False)  # the original divides by zero here; n_active > neibor fails
            continue
        if score == "A":
            value = abs(c_self - c_nbr / float(n_active))
        else:
            value = abs(c_nbr) / float(n_active)
        ok = value <= 1 if dscore else int(value) <= 1
        keep.append(bool(n_active > neibor and ok and first))
    return keep


# --------------------------------------------------------------------------------------
# Synthetic scenes: pixels firing when their log intensity crosses a threshold


def threshold_events(log_intensity, xs, ys, duration_us, rng, step_us=20, jitter_us=20.0):
    """Events of pixels ``(xs, ys)`` whose log intensity is ``log_intensity(t_us) -> (n,)``.

    Contrast thresholds C_on ~ N(0.15, 0.015), C_off ~ N(0.20, 0.02) per pixel;
    times interpolated to the crossing, jittered, rounded to µs.
    """
    n = len(xs)
    c_on = rng.normal(0.15, 0.015, n).clip(0.05)
    c_off = rng.normal(0.20, 0.02, n).clip(0.05)
    ref = log_intensity(0.0) + rng.uniform(-0.05, 0.05, n)
    prev = log_intensity(0.0)
    ts, ids, ps = [], [], []
    for t in np.arange(step_us, duration_us, step_us, dtype=np.float64):
        cur = log_intensity(t)
        while True:
            up = cur - ref >= c_on
            down = ref - cur >= c_off
            if not (up.any() or down.any()):
                break
            for mask, sign, c in ((up, 1, c_on), (down, 0, c_off)):
                idx = np.flatnonzero(mask)
                if idx.size == 0:
                    continue
                level = ref[idx] + (c[idx] if sign else -c[idx])
                span = cur[idx] - prev[idx]
                frac = np.where(span != 0, (level - prev[idx]) / np.where(span == 0, 1, span), 1)
                ts.append(t - step_us + step_us * frac.clip(0, 1))
                ids.append(idx)
                ps.append(np.full(idx.size, sign, dtype=np.uint8))
                ref[idx] = level
        prev = cur
    if not ts:
        return np.zeros(0, dtype=EVENT_DTYPE)
    t_all = np.concatenate(ts) + rng.normal(0, jitter_us, sum(len(a) for a in ts))
    i_all = np.concatenate(ids)
    ev = np.empty(t_all.size, dtype=EVENT_DTYPE)
    ev["t"] = np.clip(np.rint(t_all), 0, duration_us - 1).astype(np.int64)
    ev["x"] = np.asarray(xs)[i_all]
    ev["y"] = np.asarray(ys)[i_all]
    ev["p"] = np.concatenate(ps)
    return ev[np.argsort(ev["t"], kind="stable")]


def flicker_block(frequency_hz, x0, y0, size, duration_us, rng, amplitude=0.25):
    """A ``size`` x ``size`` block whose log intensity is a sinusoid at ``frequency_hz``."""
    yy, xx = np.mgrid[y0 : y0 + size, x0 : x0 + size]
    xs, ys = xx.ravel(), yy.ravel()
    amp = amplitude * (1 + rng.normal(0, 0.05, xs.size))
    phase = rng.uniform(0, 2 * np.pi) + rng.normal(0, 0.05, xs.size)

    def log_intensity(t):
        return amp * np.sin(2 * np.pi * frequency_hz * t * 1e-6 + phase)

    return threshold_events(log_intensity, xs, ys, duration_us, rng)


def square_flicker(
    frequency_hz, x0, y0, size, duration_us, rng, n_on=1, n_off=(1,), sync=True, jitter_us=300.0
):
    """A block of pixels firing ``n_on`` ON events, half a period later some OFF events.

    Like a lamp seen by pixels just above threshold. Each pixel and period draws its
    number of OFF events from ``n_off``: ``n_on=2, n_off=(1, 2)`` gives the 4 ON : 3 OFF
    of pixels with C_on < C_off (golden README). Events of a burst are T/16 apart; each
    pixel's phase is the block's plus a little spread (``sync``) or its own; every event
    is jittered.
    """
    period = 1e6 / frequency_hz
    yy, xx = np.mgrid[y0 : y0 + size, x0 : x0 + size]
    xs, ys = xx.ravel(), yy.ravel()
    if sync:
        phase = rng.uniform(0, period / 4) + rng.normal(0, period / 50, xs.size).clip(0)
    else:
        phase = rng.uniform(0, period, xs.size)
    ts, ps = [], []
    for k in range(int(duration_us / period) + 1):
        start = phase + k * period
        for j in range(n_on):
            ts.append(start + j * period / 16)
            ps.append(1)
        count = rng.choice(np.asarray(n_off), xs.size)
        for j in range(max(n_off)):
            off = start + period / 2 + j * period / 16
            ts.append(np.where(j < count, off, -1e12))  # far before 0: no event
            ps.append(0)
    t = np.stack(ts, axis=1) + rng.normal(0, jitter_us, (xs.size, len(ts)))
    p = np.broadcast_to(np.array(ps, dtype=np.uint8), t.shape)
    ok = (t >= 0) & (t < duration_us)
    ev = np.empty(int(ok.sum()), dtype=EVENT_DTYPE)
    ev["t"] = np.rint(t[ok]).astype(np.int64)
    ev["x"] = np.broadcast_to(xs[:, None], t.shape)[ok]
    ev["y"] = np.broadcast_to(ys[:, None], t.shape)[ok]
    ev["p"] = p[ok]
    return ev[np.argsort(ev["t"], kind="stable")]


def moving_edge(x_start, x_end, y0, height, duration_us, rng, contrast=0.6, width=12):
    """A bright bar ``width`` px wide moving right from ``x_start`` to ``x_end``."""
    yy, xx = np.mgrid[y0 : y0 + height, max(0, x_start - width) : x_end + 1]
    xs, ys = xx.ravel(), yy.ravel()
    centres = xs.astype(np.float64) + 0.5

    def log_intensity(t):
        lead = x_start + (x_end - x_start) * t / duration_us
        inside = np.clip(lead - (centres - 0.5), 0, 1) * np.clip(
            (centres + 0.5) - (lead - width), 0, 1
        )
        return contrast * inside

    return threshold_events(log_intensity, xs, ys, duration_us, rng)


def background_noise(rate_hz_per_pixel, sensor_size, duration_us, rng, region=None):
    """Uniform background activity: isolated events, 50/50 polarity.

    ``region = (x0, y0, w, h)`` limits it to a rectangle (default: the whole sensor).
    """
    x0, y0, width, height = (0, 0, *sensor_size) if region is None else region
    n = rng.poisson(rate_hz_per_pixel * width * height * duration_us * 1e-6)
    ev = np.empty(n, dtype=EVENT_DTYPE)
    ev["t"] = np.sort(rng.integers(0, duration_us, n))
    ev["x"] = x0 + rng.integers(0, width, n)
    ev["y"] = y0 + rng.integers(0, height, n)
    ev["p"] = rng.integers(0, 2, n)
    return ev


def merge(*streams):
    """One stream, stably sorted by time."""
    ev = np.concatenate(streams)
    return ev[np.argsort(ev["t"], kind="stable")]


def as_tuples(events):
    """Events as a list of (t, x, y, p) tuples (to compare with the references)."""
    return list(
        zip(
            events["t"].tolist(),
            events["x"].tolist(),
            events["y"].tolist(),
            events["p"].tolist(),
            strict=True,
        )
    )
