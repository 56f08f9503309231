"""Where the light test finds no light, what flare is left to a learned head?

Per recording, aligned 20 ms windows (the models' window): the share of windows in which
the light test (`WindowContext.has_lights`, what every light feature and rule reads) finds
a light, the share of the flare events (the annotation's halo and ghost; for simulated
pairs every input event of the flare stream that the ground truth lacks: no hot pixel,
nothing of the source's own) that lie in
windows without one, and, for those, three of `learned`'s features: `support` (log(1 +
other events in the 5x5 square)), `crowded` and `field` (the light-free rules' evidence).

Run: python experiments/light-test/light_free.py FAERY_DATA SIM_FOLDER [SIM_FOLDER ...]
(FAERY_DATA: faery 0.7.1's tests/data; SIM_FOLDER: simulated pairs, e.g. the test splits
of `edeflare simulate TRAIN --recipe eflare-train`); writes results/light_free.json.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import REAL  # noqa: E402

from edeflare.eval.score import classify_events  # noqa: E402
from edeflare.io import read_events  # noqa: E402
from edeflare.io.sequence import read_sequence  # noqa: E402
from edeflare.lights import bundled_lights, load_lights  # noqa: E402
from edeflare.lights.cells import covered_us  # noqa: E402
from edeflare.models.event_features import window_features  # noqa: E402
from edeflare.models.head_training import _component, keep_labels  # noqa: E402
from edeflare.rules.context import WindowContext  # noqa: E402

WINDOW_US = 20_000
COLUMNS = ("support", "crowded", "field")


def windows(events: np.ndarray, start: int, end: int):
    t = events["t"]
    for s in range(start, end, WINDOW_US):
        lo, hi = np.searchsorted(t, [s, s + WINDOW_US])
        if hi > lo:
            yield s, slice(lo, hi)


def measure(
    events: np.ndarray, size: tuple[int, int], flare: np.ndarray, light: np.ndarray
) -> dict:
    """The light test's verdicts over ``events``, the light-free flare's features, and
    how fast the light's own events (``light``) fire: per window, its events over its
    pixels and the window's milliseconds (the test asks 0.55 of a light's pixels)."""
    start, end = int(events["t"][0]) // WINDOW_US * WINDOW_US, int(events["t"][-1]) + 1
    lit = n_windows = 0
    free = np.zeros(events.size, bool)
    cols = {c: [] for c in COLUMNS}
    rates = []
    for s, part in windows(events, start, end):
        ev = events[part]
        own = ev[light[part]]
        if own.size:
            pixels = np.unique(own["y"].astype(np.int64) * size[0] + own["x"]).size
            rates.append(own.size / pixels / (WINDOW_US / 1000))
        ctx = WindowContext(ev, size, covered_us(ev, s, WINDOW_US))
        n_windows += 1
        if ctx.has_lights:
            lit += 1
            continue
        free[part] = True
        mine = flare[part]
        if mine.any():
            f = window_features(ctx, np.zeros(ev.size, np.float32), COLUMNS)
            for i, c in enumerate(COLUMNS):
                cols[c].append(f[mine, i])
    out = {
        "windows": n_windows,
        "windows with a light": round(lit / max(n_windows, 1), 4),
        "flare events": int(flare.sum()),
        "flare in light-free windows": round(float((flare & free).sum()) / max(flare.sum(), 1), 4),
        "light: events per pixel and ms": round(float(np.median(rates)), 3) if rates else None,
    }
    for c in COLUMNS:
        v = np.concatenate(cols[c]) if cols[c] else np.zeros(0)
        out[f"light-free flare: mean {c}"] = round(float(v.mean()), 3) if v.size else None
    return out


def real_rows(faery: Path) -> list[dict]:
    rows = []
    recordings = [
        (r, REAL / r, bundled_lights(r))
        for r in ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")
    ]
    night = faery / "evt3.raw"
    recordings.append(("night recording (faery evt3.raw)", night, ROOT / "benchmarks" /
                       "night_recording_lights.json"))  # fmt: skip
    for name, path, lights_file in recordings:
        events, size = read_events(path)
        regions = classify_events(events, load_lights(lights_file, size), size)
        flare = regions.mask("halo") | regions.mask("ghost")
        rows.append({"data": name, **measure(events, size, flare, regions.mask("light"))})
        print(rows[-1], flush=True)
    return rows


def sim_rows(folders: list[Path]) -> list[dict]:
    rows = []
    for folder in folders:
        files = sorted(folder.glob("*.h5"))
        acc: dict[str, list] = {}
        for path in files:
            inp, gt, size, *_ = read_sequence(path)
            flare = ~keep_labels(inp, gt)
            scattered = _component(path, "flare")
            if scattered is not None:  # hot pixels are neither the truth nor flare
                flare &= keep_labels(inp, scattered)
            light = _component(path, "light")
            own = np.zeros(inp.size, bool) if light is None else keep_labels(inp, light)
            row = measure(inp, size, flare & ~own, own)
            for k, v in row.items():
                acc.setdefault(k, []).append(v)
        w = np.array(acc["flare events"], float)
        summary = {"data": str(folder), "sequences": len(files)}
        for k, v in acc.items():
            vals = np.array([np.nan if x is None else x for x in v], float)
            if k == "light: events per pixel and ms":  # the median over sequences
                ok = np.isfinite(vals)
                summary[k] = round(float(np.median(vals[ok])), 3) if ok.any() else None
            elif k in ("windows", "flare events"):
                summary[k] = int(vals.sum())
            else:  # weighted by each sequence's flare events (windows: by their count)
                weight = np.array(acc["windows"], float) if k == "windows with a light" else w
                ok = np.isfinite(vals) & (weight > 0)
                mean = np.average(vals[ok], weights=weight[ok]) if ok.any() else None
                summary[k] = None if mean is None else round(float(mean), 4)
        rows.append(summary)
        print(summary, flush=True)
    return rows


def main() -> None:
    faery, sims = Path(sys.argv[1]), [Path(p) for p in sys.argv[2:]]
    rows = real_rows(faery) + sim_rows(sims)
    out = Path(__file__).resolve().parent / "results" / "light_free.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
