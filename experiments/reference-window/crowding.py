"""python experiments/reference-window/crowding.py: which isolated events crowd
(``edeflare.models.scatter.crowded_isolated``, z = 3), in the light-free 20 ms windows of
the reference window's proxy (its flare and the rest apart), of ``eflare-r-sim`` (the
test set of ``benchmarks/flare_targets.py``, in ``benchmarks/.data``) and of the real
recordings, in both windowings of the model (5 ms apart). Per set: the isolated events
(fewer than 2 others in their 5x5 square), the share of them that crowd, and the share
of a window's events that are crowded isolated ones (median and maximum over windows)."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from reference_window import LIGHTS, SENSOR, reference_window

from edeflare.eval.score import classify_events, load_lights
from edeflare.io import open_events, read_events
from edeflare.models.flaremask import event_support
from edeflare.models.ghosts import covered_us
from edeflare.models.halos import window_lights
from edeflare.models.scatter import crowded_isolated

W = 20_000
REAL = ROOT.parent / "shared" / "data" / "real"


def light_free_windows(ev, size):
    """Index arrays of the light-free windows, both windowings."""
    for phase in (0, W // 4):
        t0 = (int(ev["t"][0]) - phase) // W * W + phase
        k = (ev["t"].astype(np.int64) - t0) // W
        bounds = np.searchsorted(k, np.arange(k[-1] + 2))
        for i, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            e = ev[lo:hi]
            if e.size >= 20 and not window_lights(e, size, covered_us(e, t0 + i * W, W)).any():
                yield np.arange(lo, hi)


def tally(name, ev, size, flare=None):
    iso_n, crowd_n, shares = {}, {}, []
    for idx in light_free_windows(ev, size):
        e = ev[idx]
        iso = event_support(e, size) < 2
        crowded = crowded_isolated(e, size, iso, z=3.0)
        shares.append(crowded.mean())
        groups = {"all": np.ones(e.size, bool)}
        if flare is not None:
            groups = {"flare": flare[idx], "rest": ~flare[idx]}
        for g, m in groups.items():
            iso_n[g] = iso_n.get(g, 0) + int((iso & m).sum())
            crowd_n[g] = crowd_n.get(g, 0) + int((crowded & m).sum())
    parts = ", ".join(f"{g}: {iso_n[g]} isolated, {crowd_n[g] / max(iso_n[g], 1):.3f} crowd"
                      for g in iso_n)  # fmt: skip
    share = f"{np.median(shares):.3f} / {np.max(shares):.3f}" if shares else "-"
    print(f"{name:32s} {len(shares):4d} windows; {parts}; window share {share}")


def main() -> None:
    lights = load_lights(LIGHTS, SENSOR)
    for core in (1, 4, 8):
        ev = reference_window(core)
        flare = np.isin(classify_events(ev, lights, SENSOR).labels, ["halo", "ghost"])
        tally(f"proxy, core {core}", ev, SENSOR, flare)
    files = sorted((ROOT / "benchmarks" / ".data" / "eflare-r-sim" / "test").glob("*.h5"))
    if files:
        evs = [open_events(p, group="input") for p in files]
        size = evs[0].sensor_size
        merged = [s.read() for s in evs]
        for k, e in enumerate(merged):  # one after another, 1 s apart
            e["t"] += k * 1_000_000
        tally("eflare-r-sim", np.concatenate(merged), size)
    for name in ("davis346_street_cars.aedat4", "davis346_lowlight_cradle.aedat4",
                 "prophesee_gen41_street.raw"):  # fmt: skip
        if (REAL / name).is_file():
            rec = read_events(REAL / name)
            tally(name, rec.events, rec.sensor_size)


if __name__ == "__main__":
    main()
