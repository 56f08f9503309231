"""python experiments/hybrid/outputs.py SPLIT OUTDIR METHOD [KEY=VALUE ...]: run one
de-flarer over every sequence of a simulated split and save its output streams as
``OUTDIR/<seq>.METHOD.npy`` (skipped when present, so a killed run resumes).

METHOD is ``night`` (the bundled default), ``paper`` or ``eflare`` (bundled models),
or any registered method name; KEY=VALUE pairs are passed to it.
"""

import sys
import time
from pathlib import Path

import numpy as np

from edeflare.deflare import create_method, deflare
from edeflare.io import open_events

split, outdir, name = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
params = {k: float(v) if v.replace(".", "", 1).isdigit() else v for k, v in (kv.split("=", 1) for kv in sys.argv[4:])}
outdir.mkdir(parents=True, exist_ok=True)
if name in ("night", "paper", "eflare"):
    method = create_method("model", weights=name, batch_windows=1, **params)
else:
    method = create_method(name, **params)
for path in sorted(split.glob("*.h5")):
    out = outdir / f"{path.stem}.{name}.npy"
    if out.exists():
        continue
    src = open_events(path, group="input")
    events, size = src.read(), src.sensor_size
    t0 = time.perf_counter()
    result = deflare(events, size, method, rng=0)
    tmp = out.with_suffix(".tmp.npy")
    np.save(tmp, result)
    tmp.rename(out)
    print(
        f"{path.stem} {name}: {events.size} -> {result.size} events, "
        f"{time.perf_counter() - t0:.1f} s",
        flush=True,
    )
