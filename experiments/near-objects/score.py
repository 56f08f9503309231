"""Score a mask model as the real-labels study scored `learned`: the nine real recordings at
four window phases (TermsRecording at the card's threshold, no rule knobs), and the two
unseen scenes (one windowing, as benchmarks/unseen_scenes.py).

Run: python experiments/near-objects/score.py WEIGHTS OUT.json [FAERY_DATA [UNSEEN_DIR]]
(FAERY_DATA: faery-0.7.1/tests/data; UNSEEN_DIR: unseen_scenes.py's --folder; without them,
the six recordings of ../shared/data/real and the reference window only; without
UNSEEN_DIR, no unseen scene)
"""

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "experiments" / "real-labels"))
from _held_out import TermsRecording  # noqa: E402
from fit import real_recordings  # noqa: E402
from unseen_scenes import SCENES, load_scene, shares  # noqa: E402

from edeflare import deflare  # noqa: E402
from edeflare.models.infer import ModelDeflarer, bundled_weights  # noqa: E402

w = sys.argv[1]
path = bundled_weights(w) if not w.endswith(".safetensors") else w
d = ModelDeflarer(path, runtime="torch")
thr = d.card.keep_threshold
out = {"weights": w, "threshold": thr}
faery = Path(sys.argv[3]) if len(sys.argv) > 3 else None
for name, ev, size, lights in real_recordings(faery):
    rec = TermsRecording(name, d, ev, size, lights)
    row = rec.measure({}, [thr])[0]
    out[name] = [round(float(v), 4) for v in row]
    print(name, out[name], flush=True)
for name in SCENES if len(sys.argv) > 4 else ():
    ev, size = load_scene(Path(sys.argv[4]), name)
    out[name] = shares(ev, deflare(ev, size, "model", weights=w, rng=0))
    print(name, out[name], flush=True)
json.dump(out, open(sys.argv[2], "w"), indent=1)
