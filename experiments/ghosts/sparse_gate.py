"""python experiments/ghosts/sparse_gate.py MAX_NEIGHBOURS SCRIPT [ARGS...]: run
``real_check.py`` or ``../halo-prior/sim_check.py`` with the ghost prior gated by
sparsity. The prior then covers only events whose 3x3 neighbourhood holds at most
MAX_NEIGHBOURS events of the window, the event itself included. Ghost rings reach real
sensors as scattered specks; the scene edges the prior also covers (the DAVIS bench)
are connected.

Example: ``python experiments/ghosts/sparse_gate.py 3 experiments/ghosts/real_check.py
ghost_shift=1``.

This is how ``edeflare.models.ghosts.GHOST_MAX_NEIGHBOURS`` (4) was chosen; the library now
gates by itself, so this script stacks a second, stricter gate on it (a MAX of 4 or more
changes nothing).
"""

import runpy
import sys

import numpy as np
from scipy import ndimage

import edeflare.models.infer as infer
from edeflare.models.ghosts import in_ghost_prior

LIMIT = int(sys.argv[1])


def gated(events, sensor_size, window_us, *, cell=8, lights=None):
    inside = in_ghost_prior(events, sensor_size, window_us, cell=cell, lights=lights)
    if not inside.any():
        return inside
    w, h = sensor_size
    counts = np.bincount(events["y"].astype(np.int64) * w + events["x"], minlength=w * h)
    near = ndimage.uniform_filter(counts.reshape(h, w).astype(np.float64), 3, mode="constant")
    near = np.rint(near * 9).astype(np.int64)
    return inside & (near[events["y"], events["x"]] <= LIMIT)


infer.in_ghost_prior = gated
sys.argv = sys.argv[2:]
runpy.run_path(sys.argv[0], run_name="__main__")
