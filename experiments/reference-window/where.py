"""python experiments/reference-window/where.py [name=value...]: where the default's kept
flare lies on the reference window's proxy (core 4), by part, and each part's support.

``name=value`` is a parameter of the model method (e.g. ``scatter_shift=0``). Parts:
the four lights, the halo by distance from the night light's centre (the bloom just
outside it, then further out), the ghost and the rest (sensor noise)."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from reference_window import LIGHTS, SENSOR, WINDOW_US, reference_window

from edeflare.deflare import deflare
from edeflare.eval.score import classify_events, load_lights
from edeflare.events import event_keys
from edeflare.models.flaremask import event_support

CENTRE = (463.3, 289.6)  # the night light (reference_window_lights.json)


def main(params: dict[str, float]) -> None:
    ev = reference_window(4)
    labels = classify_events(ev, load_lights(LIGHTS, SENSOR), SENSOR).labels
    out = deflare(ev, SENSOR, "model", rng=0, **params)
    kept = np.isin(event_keys(ev, SENSOR), event_keys(out, SENSOR))
    support = np.empty(ev.size, np.int64)  # per 20 ms window, as the model counts it
    bounds = np.searchsorted(ev["t"], np.arange(0, 10 * WINDOW_US + 1, 20_000))
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        support[lo:hi] = event_support(ev[lo:hi], SENSOR)
    d = np.hypot(ev["x"] - CENTRE[0], ev["y"] - CENTRE[1])
    halo = labels == "halo"
    parts = {
        "lights": labels == "light",
        "halo, 18-45 px (bloom)": halo & (d < 45),
        "halo, 45-100 px": halo & (d >= 45) & (d < 100),
        "halo, 100-200 px": halo & (d >= 100) & (d < 200),
        "halo, 200+ px": halo & (d >= 200),
        "ghost": labels == "ghost",
        "rest": ~np.isin(labels, ["light", "halo", "ghost"]),
    }
    print(params or "the card's parameters")
    print(f"{'part':24s} {'events':>7s} {'kept':>6s} {'support>=2':>11s} {'>=6':>5s}")
    for name, m in parts.items():
        s = support[m]
        print(f"{name:24s} {m.sum():7d} {kept[m].mean():6.3f} {np.mean(s >= 2):11.2f} "
              f"{np.mean(s >= 6):5.2f}")  # fmt: skip


if __name__ == "__main__":
    main({k: float(v) for k, v in (a.split("=", 1) for a in sys.argv[1:])})
