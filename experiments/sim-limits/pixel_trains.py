"""python experiments/sim-limits/pixel_trains.py: do a pixel's own events in a 20 ms window
tell a simulated light's glare from the light? Not adopted.

Over the 30 ``eflare-r-sim`` sequences, per aligned window, the pixels of its bright lights
(:func:`~edeflare.models.halos.window_lights`), each labelled true (the ground truth has
an event there in the window) or flare-only. Per pixel: its events, the span from its
first to its last (over the window's covered span), its ON share, the share of its
events in its busiest 2 ms, and its polarity switches per event pair. Prints each
cue's ROC AUC for "true" (0.5: no use; below 0.5: higher means flare).

Then the switch rate of the real lamps: on the DAVIS346 lamps (100 Hz flicker) the
lamps' own pixels switch polarity as often as the simulated glare does, so a cut on it
would erode them.
"""

from pathlib import Path

import numpy as np

from edeflare.eval.score import classify_events, load_lights
from edeflare.io import open_events
from edeflare.models.ghosts import covered_us
from edeflare.models.halos import LIGHT_CORE_RATE, _lights, window_lights

WIN_US = 20_000
SPLIT = Path("benchmarks/.data/eflare-r-sim/test")
CUES = ("events", "span", "ON share", "busiest 2 ms share", "switch rate")


def auc(score: np.ndarray, label: np.ndarray) -> float:
    """The probability that a random true pixel scores above a random flare-only one."""
    rank = np.empty(score.size)
    rank[np.argsort(score, kind="stable")] = np.arange(score.size)
    n1 = label.sum()
    return float((rank[label].sum() - n1 * (n1 - 1) / 2) / (n1 * (label.size - n1)))


def light_mask(ev: np.ndarray, size: tuple[int, int], span: int) -> np.ndarray:
    """The window's bright lights' pixels, (height, width) bool."""
    w, h = size
    mask = np.zeros((h, w), dtype=bool)
    lights = window_lights(ev, size, span)
    if not lights.any():
        return mask
    _, found, at = _lights(ev, size, span, 8, lights)
    for ys, xs, own, _ in found:
        if np.median(at.counts[ys, xs][own]) >= LIGHT_CORE_RATE * span / 1000:
            mask[ys, xs] |= own
    return mask


def cues(ev: np.ndarray, width: int, start: int, span: int):
    """Per pixel that fired: its key and the five cues (n_pixels, 5)."""
    key = ev["y"].astype(np.int64) * width + ev["x"]
    order = np.lexsort((ev["t"], key))
    k, t, pol = key[order], ev["t"][order].astype(np.int64), ev["p"][order].astype(int)
    pixels, first, n = np.unique(k, return_index=True, return_counts=True)
    last = first + n - 1
    on = np.add.reduceat(pol, first)
    slot = (t - start) // 2000
    cells, per = np.unique(k * 16 + slot, return_counts=True)
    busiest = np.zeros(pixels.size)
    np.maximum.at(busiest, np.searchsorted(pixels, cells // 16), per)
    switch = np.r_[0, (np.diff(pol) != 0) & (np.diff(k) == 0)]
    switches = np.add.reduceat(switch, first)
    return pixels, np.c_[
        n, (t[last] - t[first]) / span, on / n, busiest / n, switches / np.maximum(n - 1, 1)
    ]


def simulated() -> None:
    feats, labels = [], []
    for path in sorted(SPLIT.glob("*.h5")):
        src = open_events(path, group="input")
        inp, size = src.read(), src.sensor_size
        gt = open_events(path, group="gt").read()
        w, h = size
        for s in range(0, int(inp["t"][-1]) + 1, WIN_US):
            a, b = np.searchsorted(inp["t"], [s, s + WIN_US])
            ev = inp[a:b]
            if ev.size == 0:
                continue
            span = covered_us(ev, s, WIN_US)
            mask = light_mask(ev, size, span)
            ev = ev[mask[ev["y"], ev["x"]]]
            if ev.size == 0:
                continue
            g = gt[np.searchsorted(gt["t"], s) : np.searchsorted(gt["t"], s + WIN_US)]
            true = np.zeros(h * w, dtype=bool)
            true[g["y"].astype(np.int64) * w + g["x"]] = True
            pixels, f = cues(ev, w, s, span)
            feats.append(f)
            labels.append(true[pixels])
    f, true = np.concatenate(feats), np.concatenate(labels)
    print(f"eflare-r-sim lights' pixels: {true.size}, true {100 * true.mean():.1f} %")
    for i, name in enumerate(CUES):
        print(
            f"  {name}: AUC {auc(f[:, i], true):.3f} (mean true {f[true, i].mean():.3f}, "
            f"flare-only {f[~true, i].mean():.3f})"
        )


def davis_lamps() -> None:
    src = open_events("../shared/data/real/davis346_flicker_lamps.aedat4")
    inp, size = src.read(), src.sensor_size
    lights = load_lights("src/edeflare/assets/lights/davis346_flicker_lamps.json", size)
    lamp = classify_events(inp, lights, size).light
    rates = []
    for s in range(int(inp["t"][0]) // WIN_US * WIN_US, int(inp["t"][-1]) + 1, WIN_US):
        a, b = np.searchsorted(inp["t"], [s, s + WIN_US])
        ev = inp[a:b][lamp[a:b]]
        if ev.size:
            rates.append(cues(ev, size[0], s, covered_us(inp[a:b], s, WIN_US))[1][:, 4])
    print(f"DAVIS346 lamps' own pixels: switch rate {np.concatenate(rates).mean():.3f}")


if __name__ == "__main__":
    simulated()
    davis_lamps()
