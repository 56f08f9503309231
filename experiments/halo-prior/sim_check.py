"""python experiments/halo-prior/sim_check.py [name=value ...] ...: the default model with
each parameter set (one argument per set, fields joined by commas, e.g. halo_shift=1 or
halo_shift=1,ghost_shift=2; none: the card's) on the ghost benchmark's set
(benchmarks/.data/eflare-night-sparse-640x480, made by benchmarks/ghost_removal.py),
whose keep-only targets say which input events are flare.

Per set: the flare events dropped (ghosts, and the rest), the scene events kept, and
the scene events kept among those the halo prior covers (what the prior costs), each a
mean over the sequences holding at least 100 events of the kind; the harmonic mean of
the first three."""

import sys
from pathlib import Path

import numpy as np

from edeflare.deflare import create_method
from edeflare.events import event_keys
from edeflare.io.sequence import list_sequences
from edeflare.models.halos import in_halo_prior

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from ghost_removal import labelled_events

SET = "benchmarks/.data/eflare-night-sparse-640x480/test"
W = 20_000


def halo_prior(events, size):
    """Membership of each event in the halo prior of its aligned window."""
    out = np.zeros(events.size, dtype=bool)
    win = events["t"] // W
    edges = np.flatnonzero(np.diff(win)) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, events.size], strict=True):
        out[a:b] = in_halo_prior(events[a:b], size, W)
    return out


if __name__ == "__main__":
    sets = [dict((k, float(v)) for k, v in (p.split("=") for p in a.split(",")))
            for a in sys.argv[1:]] or [{}]  # fmt: skip
    methods = [create_method("model", **s) for s in sets]
    kinds = ("ghost", "other", "keep", "keep in halo")
    res = [{k: [] for k in kinds} for _ in sets]
    for seq in list_sequences(SET):
        inp, size, keep, ghost = labelled_events(seq)
        keys = event_keys(inp, size)
        sel = {"ghost": ~keep & ghost, "other": ~keep & ~ghost, "keep": keep,
               "keep in halo": keep & halo_prior(inp, size)}  # fmt: skip
        for m, r in zip(methods, res, strict=True):
            kept = np.isin(keys, event_keys(m(inp, size, rng=0), size))
            for k, s in sel.items():
                if s.sum() >= 100:
                    r[k].append(float((kept[s] if k.startswith("keep") else ~kept[s]).mean()))
    for s, r in zip(sets, res, strict=True):
        g, o, k, kh = (np.mean(r[x]) if r[x] else float("nan") for x in kinds)
        print(
            f"{s or 'card'}: ghosts dropped {g:.3f}, other flare dropped {o:.3f}, scene kept "
            f"{k:.3f} (in the halo prior {kh:.3f}, {len(r['keep in halo'])} seqs); "
            f"hm {3 / (1 / g + 1 / o + 1 / k):.3f}",
            flush=True,
        )
