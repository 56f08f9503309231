"""python experiments/ghosts/shift_sweep.py B...: the default with --ghost-shift B on the ghost
benchmark's set (benchmarks/.data/eflare-night-sparse-640x480, made by
benchmarks/ghost_removal.py): ghost events dropped, other flare dropped, scene kept (means
over the sequences holding at least 100 events of a kind), harmonic mean."""
import json, sys
import h5py, numpy as np
from edeflare.deflare import create_method
from edeflare.events import event_keys
from edeflare.io.dsec import read_dsec
from edeflare.io.sequence import list_sequences
from edeflare.sim.flare import GhostSpec
from edeflare.sim.sensing import in_ghosts, source_track
shifts = [float(v) for v in sys.argv[1:]]
methods = {s: create_method("model", ghost_shift=s) for s in shifts}
sh = {s: {"ghost": [], "other": [], "keep": []} for s in shifts}
for seq in list_sequences("benchmarks/.data/eflare-night-sparse-640x480/test"):
    inp, size = read_dsec(seq, "input"); gt, _ = read_dsec(seq, "gt"); light, _ = read_dsec(seq, "light")
    with h5py.File(seq) as f:
        ghosts = [GhostSpec(**g) for g in json.loads(f.attrs["script"])["ghosts"]]
    keys = event_keys(inp, size); keep = np.isin(keys, event_keys(gt, size))
    ghost = in_ghosts(inp, source_track(light), ghosts, size)
    kinds = {"ghost": ~keep & ghost, "other": ~keep & ~ghost, "keep": keep}
    for s, m in methods.items():
        kept = np.isin(keys, event_keys(m(inp, size, rng=0), size))
        for k, sel in kinds.items():
            if sel.sum() >= 100:
                sh[s][k].append(float((kept[sel] if k == "keep" else ~kept[sel]).mean()))
for s in shifts:
    g, o, k = (np.mean(sh[s][x]) for x in ("ghost", "other", "keep"))
    print(f"shift {s}: ghost {g:.3f} other {o:.3f} kept {k:.3f} hm {3/(1/g+1/o+1/k):.3f}", flush=True)
