"""experiments/near-objects/score.py on the six small recordings only (no faery file, no
unseen scene): the Gen3 light, the DAVIS lamps, the reference window, the DAVIS street,
the cradle, the Gen4.1 street; for the single members (question 3).

Run: python experiments/seed-spread/score_small.py WEIGHTS OUT.json
"""

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "experiments" / "real-labels"))
from _held_out import TermsRecording  # noqa: E402
from fit import real_recordings  # noqa: E402

from edeflare.models.infer import ModelDeflarer, bundled_weights  # noqa: E402

w = sys.argv[1]
path = bundled_weights(w) if not w.endswith(".safetensors") else w
d = ModelDeflarer(path, runtime="torch")
thr = d.card.keep_threshold
out = {"weights": w, "threshold": thr}
for name, ev, size, lights in real_recordings(None):
    rec = TermsRecording(name, d, ev, size, lights)
    out[name] = [round(float(v), 4) for v in rec.measure({}, [thr])[0]]
    print(name, out[name], flush=True)
json.dump(out, open(sys.argv[2], "w"), indent=1)
