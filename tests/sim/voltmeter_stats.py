"""Statistics of DVS-Voltmeter runs, as the golden ``*_stats.npz`` files define them.

See ``../shared/data/golden/voltmeter/README.md``. One run's events give one
:class:`RunStats`; :func:`simulate_runs` produces them for our simulator on a
golden input video.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from edeflare.sim.dvs import DVS346_K, VoltmeterParams, VoltmeterSimulator

FRAME_US = 1000


@dataclass
class RunStats:
    total: int
    on: int
    pix_count: np.ndarray  # (H, W)
    pix_on: np.ndarray
    time_hist: np.ndarray  # (200,) 1 ms bins
    time_hist_on: np.ndarray
    isi_hist: np.ndarray  # (91,)
    isi_hist_flip: np.ndarray
    first_t: np.ndarray  # (H, W), NaN where the pixel never fired
    static_on: int
    static_off: int
    static_on_phase: np.ndarray  # (10,)
    static_off_phase: np.ndarray
    at_prev_frame: int
    at_frame: int
    residual: np.ndarray  # (H, W)
    nth_t_mean: np.ndarray | None  # (6,) ramp only
    nth_t_std: np.ndarray | None


def load_video(folder: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    data = np.load(folder / f"{name}_input.npz")
    return data["frames"], data["t_us"]


def run_stats(
    events: np.ndarray,
    frames: np.ndarray,
    isi_edges: np.ndarray,
    residual: np.ndarray,
    nth: int = 0,
) -> RunStats:
    """Statistics of one run on a 1000-fps golden video (see the README's key table)."""
    n_frames, height, width = frames.shape
    t = events["t"].astype(np.int64)
    x = events["x"].astype(np.int64)
    y = events["y"].astype(np.int64)
    p = events["p"].astype(np.int64)
    flat = y * width + x
    on = p == 1
    pix_count = np.bincount(flat, minlength=width * height).reshape(height, width)
    pix_on = np.bincount(flat[on], minlength=width * height).reshape(height, width)
    edges = np.arange(n_frames + 1) * FRAME_US
    time_hist = np.histogram(t, edges)[0]
    time_hist_on = np.histogram(t[on], edges)[0]

    order = np.lexsort((t, flat))  # by pixel, then time
    fs, ts, ps = flat[order], t[order], p[order]
    same = fs[1:] == fs[:-1]
    isi = (ts[1:] - ts[:-1])[same]
    flip = (ps[1:] != ps[:-1])[same]
    isi_hist = np.histogram(isi, isi_edges)[0]
    isi_hist_flip = np.histogram(isi[flip], isi_edges)[0]

    first = np.full(width * height, np.nan)
    starts = np.ones(fs.size, dtype=bool)
    starts[1:] = ~same
    first[fs[starts]] = ts[starts]

    inside = t % FRAME_US != 0
    k = t // FRAME_US
    fr = frames.reshape(n_frames, -1)
    kk = np.minimum(k, n_frames - 2)
    static = inside & (fr[kk, flat] == fr[kk + 1, flat])
    phase_edges = np.arange(0, FRAME_US + 1, 100)
    phase = t % FRAME_US

    nth_mean = nth_std = None
    if nth:
        rank = np.arange(fs.size) - np.maximum.accumulate(np.where(starts, np.arange(fs.size), 0))
        nth_mean = np.array([ts[rank == j].mean() for j in range(nth)])
        nth_std = np.array([ts[rank == j].std(ddof=1) for j in range(nth)])

    return RunStats(
        total=int(t.size),
        on=int(on.sum()),
        pix_count=pix_count,
        pix_on=pix_on,
        time_hist=time_hist,
        time_hist_on=time_hist_on,
        isi_hist=isi_hist,
        isi_hist_flip=isi_hist_flip,
        first_t=first.reshape(height, width),
        static_on=int((static & on).sum()),
        static_off=int((static & ~on).sum()),
        static_on_phase=np.histogram(phase[static & on], phase_edges)[0],
        static_off_phase=np.histogram(phase[static & ~on], phase_edges)[0],
        at_prev_frame=0,  # filled by simulate_runs, which knows each event's interval
        at_frame=0,
        residual=residual,
        nth_t_mean=nth_mean,
        nth_t_std=nth_std,
    )


def simulate_runs(
    folder: Path, name: str, seeds: range, *, against_drift: str = "original"
) -> list[RunStats]:
    """Run our Voltmeter on a golden video once per seed; statistics of each run."""
    frames, t_us = load_video(folder, name)
    ref = np.load(folder / f"{name}_stats.npz")
    params = VoltmeterParams(k=DVS346_K, against_drift=against_drift)
    out = []
    for seed in seeds:
        sim = VoltmeterSimulator((frames.shape[2], frames.shape[1]), params, rng=seed)
        chunks = []
        at_prev = at_frame = 0
        for frame, t in zip(frames, t_us, strict=True):
            t_prev = sim.t_us
            ev = sim.feed(frame, int(t))
            if ev.size:
                at_prev += int((ev["t"] == t_prev).sum())
                at_frame += int((ev["t"] == t).sum())
            chunks.append(ev)
        events = np.concatenate(chunks)
        stats = run_stats(
            events, frames, ref["isi_edges"], sim.residual, 6 if name == "ramp" else 0
        )
        stats.at_prev_frame, stats.at_frame = at_prev, at_frame
        out.append(stats)
    return out
