"""python experiments/reference-window/field_rate.py: how densely the events fire where a
scattered-light field lies (``edeflare.models.scatter.scatter_field`` without its rate
condition), in the light-free 20 ms windows of the reference window's proxy (cores 1, 4,
8), of ``eflare-r-sim`` and of the real recordings, both windowings of the model. Per set:
the field's events out of the light-free windows' events, and the 5th, 50th and 95th
percentiles and the maximum of the rate of the events in their square (events per pixel
and second over the time the window's events cover), the quantity ``FIELD_MAX_RATE`` caps."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from crowding import REAL, W, light_free_windows
from reference_window import SENSOR, reference_window

import edeflare.models.scatter as scatter
from edeflare.io import open_events, read_events
from edeflare.models.flaremask import event_support


def tally(name, ev, size):
    rates, in_field, total = [], 0, 0
    for idx in light_free_windows(ev, size):
        e = ev[idx]
        total += e.size
        squares = scatter._Squares(size, scatter.SCATTER_CELL, None, e)
        crowded = scatter._crowded(squares, event_support(e, size) < 2, 3.0)
        field = scatter._field(squares, crowded, True)  # every square taken as dark
        if not field.any():
            continue
        # covered_us without the window's start: the events' own extent, within [W/4, W]
        span = min(W, max(int(e["t"][-1] - e["t"][0]) + 1, W // 4))
        every = squares.counts().ravel()[squares.flat]
        pixels = squares.cells.ravel()[squares.flat] * scatter.SCATTER_CELL**2
        rates.append((every / pixels / (span * 1e-6))[field])
        in_field += int(field.sum())
    if not rates:
        print(f"{name:34s} no field ({total} events)")
        return
    r = np.concatenate(rates)
    p5, p50, p95 = np.percentile(r, [5, 50, 95])
    print(f"{name:34s} field {in_field}/{total} events; rate p5 {p5:.2f} p50 {p50:.2f} "
          f"p95 {p95:.2f} max {r.max():.2f} per pixel and second")  # fmt: skip


def main() -> None:
    for core in (1, 4, 8):
        tally(f"proxy, core {core}", reference_window(core), SENSOR)
    files = sorted((ROOT / "benchmarks" / ".data" / "eflare-r-sim" / "test").glob("*.h5"))
    if files:
        merged = [open_events(p, group="input").read() for p in files]
        size = open_events(files[0], group="input").sensor_size
        for k, e in enumerate(merged):  # one after another, 1 s apart
            e["t"] += k * 1_000_000
        tally("eflare-r-sim", np.concatenate(merged), size)
    for name in ("davis346_street_cars.aedat4", "davis346_lowlight_cradle.aedat4",
                 "prophesee_gen41_street.raw", "davis346_flicker_lamps.aedat4"):  # fmt: skip
        if (REAL / name).is_file():
            rec = read_events(REAL / name)
            tally(name, rec.events, rec.sensor_size)


if __name__ == "__main__":
    main()
