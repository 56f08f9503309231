"""python experiments/ghosts/ghost_check.py WEIGHTS FOLDER...: what a de-flarer drops of the
simulated ghosts (issue 13).

Each FOLDER holds ``test/*.h5`` of ``eflare-night-sparse`` (ghosts sensed at their own
rate; keep-only targets), e.g. ``edeflare simulate N640 --recipe eflare-night-sparse
--sequences 8 --test-sequences 8 --sensor-size 640x480 --seed 4242``. The events to drop
(input minus ``gt``) are split into those inside a ghost's disc
(:func:`edeflare.sim.sensing.in_ghosts`, the script's ghosts and the source's centre per
10 ms from its ``light`` events) and the rest; printed: the share of each dropped and of
the events to keep kept, pooled and as the mean over sequences.
"""

import json
import sys

import h5py
import numpy as np

from edeflare.deflare import deflare
from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track


def measure(weights, folders):
    for folder in folders:
        n = {"ghost": [0, 0], "other": [0, 0], "keep": [0, 0]}
        per = {k: [] for k in n}
        for seq in list_sequences(folder + "/test"):
            inp, size = read_dsec(seq, "input")
            gt, _ = read_dsec(seq, "gt")
            light, _ = read_dsec(seq, "light")
            with h5py.File(seq) as f:
                script = json.loads(f.attrs["script"])
            ghosts = [GhostSpec(**g) for g in script["ghosts"]]
            out = deflare(inp, size, "model", weights=weights)
            k_in = event_keys(inp, size)
            keep = np.isin(k_in, event_keys(gt, size))
            kept = np.isin(k_in, event_keys(out, size))
            ghost = in_ghosts(inp, source_track(light), ghosts, size)
            kinds = (("ghost", ~keep & ghost, ~kept), ("other", ~keep & ~ghost, ~kept),
                     ("keep", keep, kept))  # fmt: skip
            for name, sel, hit in kinds:
                n[name][0] += int(sel.sum())
                n[name][1] += int((sel & hit).sum())
                if sel.sum() >= 100:
                    per[name].append((sel & hit).sum() / sel.sum())
        # pooled (one sequence with a huge light can hold most events) and the mean over
        # the sequences holding at least 100 events of the kind
        parts = []
        for k, (total, hits) in n.items():
            verb = "kept" if k == "keep" else "dropped"
            mean = np.mean(per[k]) if per[k] else float("nan")
            parts.append(f"{k} {total} events, {verb} {hits / max(total, 1):.3f} "
                         f"(mean of {len(per[k])} sequences {mean:.3f})")  # fmt: skip
        print(f"{folder} {size[0]}x{size[1]}: " + "; ".join(parts), flush=True)


if __name__ == "__main__":
    measure(sys.argv[1], sys.argv[2:])
