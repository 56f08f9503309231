"""Prototype: a halo prior (events near a window's lights) via the ghost-shift hook."""

import sys

import numpy as np
from scipy import ndimage

import edeflare.models.infer as infer
from edeflare.models.ghosts import LIGHT_RATE

EXTENT = float(sys.argv[2]) if len(sys.argv) > 2 else 6.0
TAPER = sys.argv[3] if len(sys.argv) > 3 else "flat"


def halo_weight(events, sensor_size, window_us, cell=8, margin=2.0):
    width, height = sensor_size
    h, w = -(-height // cell), -(-width // cell)
    counts = np.bincount(
        (events["y"] // cell).astype(np.int64) * w + events["x"] // cell, minlength=h * w
    ).reshape(h, w)
    lights = counts >= LIGHT_RATE * cell * cell * window_us / 1000.0
    out = np.zeros(events.size)
    if not lights.any():
        return out
    lab, n = ndimage.label(lights, structure=np.ones((3, 3)))
    pix = np.bincount(
        events["y"].astype(np.int64) * width + events["x"], minlength=width * height
    ).reshape(height, width)
    bright = pix >= LIGHT_RATE * window_us / 1000.0
    x = events["x"].astype(float)
    y = events["y"].astype(float)
    cl = lab[events["y"] // cell, events["x"] // cell]
    for k in range(1, n + 1):
        m = np.kron(lab == k, np.ones((cell, cell), bool))[:height, :width] & bright
        if not m.any():
            continue
        yy, xx = np.nonzero(m)
        wts = pix[yy, xx]
        cx, cy = np.average(xx, weights=wts), np.average(yy, weights=wts)
        r = max(np.sqrt(m.sum() / np.pi), 1.0)
        d = np.hypot(x - cx, y - cy)
        inside = (d > r + margin) & (d <= EXTENT * r) & (cl == 0)
        if TAPER == "linear":
            wgt = np.clip((EXTENT * r - d) / ((EXTENT - 1) * r), 0, 1)
        else:
            wgt = np.ones_like(d)
        out = np.maximum(out, np.where(inside, wgt, 0.0))
    # the light's own dense cells and their neighbours are never shifted
    near = ndimage.binary_dilation(lights, iterations=1)
    out[near[events["y"] // cell, events["x"] // cell]] = 0.0
    return out


infer.in_ghost_prior = halo_weight
sys.argv = [sys.argv[0], f"ghost_shift={sys.argv[1]}"]
exec(open("experiments/ghosts/real_check.py").read())
