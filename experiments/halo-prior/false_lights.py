"""python experiments/halo-prior/false_lights.py [SIM_FOLDER...]: which groups of light cells
are lights, by the median rate of their bright pixels (events per pixel and ms).

The light test (``edeflare.models.ghosts.light_cells``: a cell firing 0.25 events per
pixel and ms) and ``light_pixels`` (a solid disc of radius >= 2) also pass dense scene.
For each group that ``light_pixels`` calls a light, this prints the median rate of its
bright pixels:

- on the real recordings, per window (two windowings, 5 ms apart, the lights' rates over
  the covered part of each window as the model counts them);
- on ``eflare-night`` test sequences (``SIM_FOLDER/test/*.h5``, 8 each), binned by that
  rate: how many groups, and the share of their events that are the light source's own
  (the sequence's ``light`` group). A true light holds about half its events from the
  source; a group of the street's texture none.
"""

import glob
import sys

import numpy as np

from edeflare.io import open_events, read_events
from edeflare.models.ghosts import covered_us
from edeflare.models.halos import light_pixels

REAL = "../shared/data/real/"
RECORDINGS = (
    "prophesee_gen3_rotating_light.raw",
    "davis346_flicker_lamps.aedat4",
    "prophesee_gen41_street.raw",
    "davis346_lowlight_cradle.aedat4",
)


def groups(ev, size, start, window_us=20_000):
    """Per light of the window: its median bright-pixel rate, radius, and its pixels."""
    w = ev[(ev["t"] >= start) & (ev["t"] < start + window_us)]
    if w.size == 0:
        return []
    span = covered_us(w, start, window_us)
    labels, radii = light_pixels(w, size, span)
    width, height = size
    pix = w["y"].astype(np.int64) * width + w["x"]
    rate = np.bincount(pix, minlength=width * height).reshape(height, width) / (span / 1000)
    return [
        (float(np.median(rate[labels == k])), float(radii[k - 1]), labels == k, w, span)
        for k in range(1, len(radii) + 1)
    ]


def windows(ev, phase):
    first = (int(ev["t"][0]) - phase) // 20_000 * 20_000 + phase
    return range(first, int(ev["t"][-1]) + 1, 20_000)


for name in RECORDINGS:
    rec = read_events(REAL + name)
    rates = [
        (round(r, 2), round(rad, 1))
        for phase in (0, 5_000)
        for s in windows(rec.events, phase)
        for r, rad, *_ in groups(rec.events, rec.sensor_size, s)
    ]
    print(f"{name}: {len(rates)} lights (median rate, radius): {sorted(rates)[:12]}")

for folder in sys.argv[1:]:
    rows = []
    for f in sorted(glob.glob(folder + "/test/*.h5"))[:8]:
        ev = open_events(f, group="input").read()
        light = open_events(f, group="light")
        size, lt = light.sensor_size, light.read()
        for s in windows(ev, 0):
            lw = lt[(lt["t"] >= s) & (lt["t"] < s + 20_000)]
            own = np.bincount(
                lw["y"].astype(np.int64) * size[0] + lw["x"], minlength=size[0] * size[1]
            ).reshape(size[1], size[0])
            for r, rad, mask, w, _ in groups(ev, size, s):
                pix = w["y"].astype(np.int64) * size[0] + w["x"]
                total = np.bincount(pix, minlength=size[0] * size[1]).reshape(size[1], size[0])
                rows.append((r, own[mask].sum() / max(total[mask].sum(), 1), rad))
    a = np.array(rows)
    print(f"{folder}: {len(a)} lights")
    for lo, hi in ((0, 0.4), (0.4, 0.55), (0.55, 0.8), (0.8, 1.5), (1.5, np.inf)):
        sel = (a[:, 0] >= lo) & (a[:, 0] < hi)
        if sel.any():
            print(
                f"  median rate {lo}-{hi}: {sel.sum()} lights; the source's share of their "
                f"events: median {np.median(a[sel, 1]):.2f}, max {a[sel, 1].max():.2f}; "
                f"radius median {np.median(a[sel, 2]):.1f}"
            )
