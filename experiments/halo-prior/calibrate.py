"""python experiments/halo-prior/calibrate.py [SET]: the halo shift that the simulator's
labels ask for, fitted without the real recordings.

On a set of simulated sequences with keep-only targets (default: the ghost benchmark's
eflare-night-sparse-640x480 test split, never trained on), the default model's keep
logits (one aligned windowing) of the events inside the halo prior, against whether
each is a scene event (keep) or flare: the shift ``s`` minimising the binary cross
entropy of ``logit - s`` is the log odds ratio the network misses there (a calibration,
as temperature scaling is). Prints it, with the share of flare in the prior and
elsewhere."""

import sys

import numpy as np
from scipy.optimize import minimize_scalar

from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.models.halos import in_halo_prior
from edeflare.models.infer import ModelDeflarer, bundled_weights

W = 20_000

if __name__ == "__main__":
    folder = (
        sys.argv[1] if len(sys.argv) > 1 else "benchmarks/.data/eflare-night-sparse-640x480/test"
    )
    net = ModelDeflarer(bundled_weights(), halo_shift=0.0, ghost_shift=0.0)
    logits, keep, prior = [], [], []
    for seq in list_sequences(folder):
        inp, size = read_dsec(seq, "input")
        gt, _ = read_dsec(seq, "gt")
        k = np.isin(event_keys(inp, size), event_keys(gt, size))
        win = inp["t"] // W
        starts = np.unique(win)
        batch = [(int(s) * W, inp[win == s]) for s in starts]
        for (_, ev), lg in zip(batch, net.window_logits(batch, size), strict=True):
            logits.append(lg)
            prior.append(in_halo_prior(ev, size, W))
        keep.append(np.concatenate([k[win == s] for s in starts]))
    lg, kp, pr = (np.concatenate(a) for a in (logits, keep, prior))

    def bce(s, sel):
        z = lg[sel] - s
        return float(np.mean(np.logaddexp(0, -z) * kp[sel] + np.logaddexp(0, z) * ~kp[sel]))

    fit = minimize_scalar(lambda s: bce(s, pr), bounds=(-20, 20), method="bounded")
    rest = minimize_scalar(lambda s: bce(s, ~pr), bounds=(-20, 20), method="bounded")
    print(
        f"{folder}: {pr.sum()} events in the halo prior ({100 * pr.mean():.1f} %), flare "
        f"{100 * (~kp[pr]).mean():.1f} % there, {100 * (~kp[~pr]).mean():.1f} % elsewhere"
    )
    print(
        f"fitted shift inside the prior: {fit.x:.2f} (BCE {bce(0, pr):.4f} -> {fit.fun:.4f}); "
        f"outside: {rest.x:.2f} (BCE {bce(0, ~pr):.4f} -> {rest.fun:.4f})"
    )
