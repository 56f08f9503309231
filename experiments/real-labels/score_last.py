"""Every method on a recording's last 30 %, the part a within-recording fit did not see
(README.md, "Within one recording"): the night recording, or ``--recording`` with
``--lights``.

Run::

    edeflare tune-head learned TRAIN/*/ --validate-last 0.3 --out RUN \
        --real FAERY_DATA/evt3.raw:benchmarks/night_recording_lights.json
    python experiments/real-labels/score_last.py RUN/model.safetensors FAERY_DATA/evt3.raw \
        experiments/real-labels/results/within_last30.json
    # the DAVIS lamps (their run RUN2 tuned on ../shared/data/real/davis346_flicker_lamps.aedat4)
    python experiments/real-labels/score_last.py RUN2/model.safetensors \
        ../shared/data/real/davis346_flicker_lamps.aedat4 \
        experiments/real-labels/results/within_last30_lamps.json \
        --lights src/edeflare/assets/lights/davis346_flicker_lamps.json
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from edeflare import read_events
from edeflare.eval.score import score_recording
from edeflare.io import write_events
from edeflare.models.head_tuning import time_split, validation_gap_us

LIGHTS = Path(__file__).resolve().parents[2] / "benchmarks" / "night_recording_lights.json"
TERMS = ("halo_removed", "ghost_removed", "flare_removed", "light_kept", "background_kept",
         "combined")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tuned", help="the tune-head run's model.safetensors")
    p.add_argument("recording", type=Path, help="faery 0.7.1's tests/data/evt3.raw, or another")
    p.add_argument("out", type=Path)
    p.add_argument("--lights", type=Path, default=LIGHTS, help="its annotation")
    args = p.parse_args()
    r = read_events(args.recording)
    _, last = time_split(r.events["t"], 0.3, validation_gap_us(20_000))  # tune-head's split
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        crop = Path(tmp) / "last30.h5"
        write_events(crop, r.events[last], r.sensor_size)
        for label, method, params in [
            ("raw", "raw", {}),
            ("dv-fastdecay", "dv-fastdecay", {}),
            ("night", "model", {}),
            ("learned", "model", {"weights": "learned"}),
            ("tuned on its first 70 %", "model", {"weights": args.tuned}),
        ]:
            report = score_recording(crop, [method], lights=args.lights, phases=4,
                                     method_params={method: params})  # fmt: skip
            rows[label] = {k: getattr(report.rows[0], k) for k in TERMS}
            print(label, {k: round(v, 3) for k, v in rows[label].items()}, flush=True)
    args.out.write_text(json.dumps({"events": int(last.sum()), "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
