"""What the default model's priors cost in time, on recordings with bright lights.

The halo prior (``edeflare.rules.halo``), the ghost prior (``edeflare.rules.ghost``)
and the diffraction-spike prior (``edeflare.rules.streak``), all on in the bundled
default, are per-window work after the network: a light test on 8x8 cells, around each
light the distances of the events near it, the ghosts' cells with a neighbourhood count
of the events in them, and around each light the events binned by angle and ring. A
window without a light costs one cell count. Each case de-flares one recording in
memory (``edeflare.methods``, the model loaded and warmed once per row), best of
``--repeat`` runs. The reference in the same run is the same model with every prior
off (``halo_shift=0, ghost_shift=0, streak_shift=0``, and no light-free or far shift):
``ratio`` is each row's time over it. The far shift (``far_shift``) costs a distance
transform on the cells per group of lights, the ghosts' cells and the spike prior.

Cases: the two annotated real recordings with lights (Prophesee Gen3 rotating light,
640x480, 50 ms; DAVIS346 lamps, 130 ms) and a synthetic 1280x720 second with a
bright disc of radius 20 px crossing the sensor over uniform background events
(1 M events/s), the largest sensor size; and the same background under 50 still lights
of 10x10 px (a street of lamps: each window's lights share one sorted pass over its
events).

Run: ``python benchmarks/bench_priors.py [--repeat N]``; writes
``results/priors.json``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import REAL, random_events, report

from edeflare.events import EVENT_DTYPE, merge_events
from edeflare.io import read_events
from edeflare.methods import create_method

OFF = {"halo_shift": 0.0, "ghost_shift": 0.0, "streak_shift": 0.0}
SHIFTS_OFF = {"light_free_shift": 0.0, "far_shift": 0.0}
ROWS = {
    "default, priors off (reference)": {**OFF, **SHIFTS_OFF},
    "default, halo prior only": {"ghost_shift": 0.0, "streak_shift": 0.0, **SHIFTS_OFF},
    "default without the spike prior": {"streak_shift": 0.0, **SHIFTS_OFF},
    "default without the far shift": {"far_shift": 0.0},
    "default (halo, ghost and spike priors, light-free and far shifts)": {},
}


def moving_light(size: tuple[int, int], span_us: int = 1_000_000) -> np.ndarray:
    """A disc of radius 20 px crossing the sensor, 40 events per pixel and 20 ms."""
    width, height = size
    yy, xx = np.mgrid[-20:21, -20:21]
    disc = np.hypot(xx, yy) <= 20
    dx, dy = xx[disc], yy[disc]
    chunks = []
    for k in range(span_us // 500):  # a step every 0.5 ms, one event per disc pixel
        t = k * 500
        cx = int(40 + (width - 80) * t / span_us)
        ev = np.empty(dx.size, dtype=EVENT_DTYPE)
        ev["t"], ev["x"], ev["y"], ev["p"] = t, cx + dx, height // 2 + dy, k % 2
        chunks.append(ev)
    return np.concatenate(chunks)


def many_lights(size: tuple[int, int], n: int = 50, span_us: int = 1_000_000) -> np.ndarray:
    """``n`` still lights (10x10 px, 1 event per pixel every 2 ms) at seeded places."""
    width, height = size
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:10, 0:10]
    x0 = rng.integers(0, width - 10, n)[:, None] + xx.ravel()
    y0 = rng.integers(0, height - 10, n)[:, None] + yy.ravel()
    steps = np.arange(0, span_us, 2_000)
    ev = np.empty(steps.size * x0.size, dtype=EVENT_DTYPE)
    ev["t"] = np.repeat(steps, x0.size)
    ev["x"] = np.tile(x0.ravel(), steps.size)
    ev["y"] = np.tile(y0.ravel(), steps.size)
    ev["p"] = 1
    return ev


def cases():
    for name in ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4"):
        ev, size = read_events(REAL / name)
        yield name.split(".")[0], ev, size
    size = (1280, 720)
    ev = merge_events(moving_light(size), random_events(1_000_000, size, 0, 1_000_000))
    yield "1280x720, a moving light, 1 M ev/s", ev, size
    ev = merge_events(many_lights(size), random_events(1_000_000, size, 0, 1_000_000, seed=1))
    yield "1280x720, 50 still lights, 1 M ev/s", ev, size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    methods = {label: create_method("model", **kw) for label, kw in ROWS.items()}
    rows = []
    for case, ev, size in cases():
        span = (int(ev["t"][-1]) - int(ev["t"][0])) / 1e6
        ref = None
        for label, method in methods.items():
            method(ev[: min(ev.size, 50_000)], size, rng=0)  # load and warm up
            times = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                out = method(ev, size, rng=0)
                times.append(time.perf_counter() - t0)
            best = min(times)
            ref = best if ref is None else ref
            rows.append({"case": case, "method": label, "events": ev.size, "kept": out.size,
                         "seconds": round(best, 3), "rtf": round(best / span, 2),
                         "ratio": round(best / ref, 3)})  # fmt: skip
    report("priors", rows, ["case", "method", "events", "kept", "seconds", "rtf", "ratio"])


if __name__ == "__main__":
    main()
