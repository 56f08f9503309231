"""Pictures of arm 1's held-out fits: the night recording, the DAVIS lamps and the Gen3
light, each through the fit that did not see it, beside the input, `night` and `learned`.

    python experiments/real-labels/figure.py RUN FAERY_DATA experiments/real-labels

RUN: ``fit.py rows``' folder. Each fold is fitted again (as ``fit.py loo`` fits it,
about 20 s) and kept as ``RUN/fold-NAME.safetensors``. ON red, OFF blue.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1] / "benchmarks"))

from fit import fit, load_rows  # noqa: E402

from edeflare.io import read_events  # noqa: E402
from edeflare.methods import deflare  # noqa: E402
from edeflare.models.weights import save_model  # noqa: E402
from edeflare.viz import event_frame, grid, save_image  # noqa: E402

CASES = {
    # name in the rows: (file, first microseconds de-flared, windows drawn, crop rows, cols)
    "night_recording": ("evt3.raw", 400_000, ((200_000, 100_000),),
                        (slice(60, 620), slice(200, 960))),
    "davis346_flicker_lamps": ("davis346_flicker_lamps.aedat4", 130_000, ((40_000, 20_000),),
                               (slice(0, 260), slice(0, 346))),
    "prophesee_gen3_rotating_light": ("prophesee_gen3_rotating_light.raw", 50_000,
                                      ((20_000, 20_000),), (slice(0, 480), slice(0, 640))),
}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("faery", type=Path)
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    from _common import REAL

    sim, real = load_rows(args.run)
    for held, (file, span, windows, crop) in CASES.items():
        fold = args.run / f"fold-{held}.safetensors"
        if not fold.is_file():
            model, card, _, threshold, _ = fit(sim, real, [r for r in real if r != held])
            save_model(fold, model, dataclasses.replace(card, keep_threshold=threshold))
        path = (args.faery if file == "evt3.raw" else REAL) / file
        events, size = read_events(path)
        t0 = int(events["t"][0])
        events = events[events["t"] < t0 + span]
        streams = {"input": events}
        for label, weights in (("night", "night"), ("learned", "learned"),
                               ("held-out fit", str(fold))):  # fmt: skip
            streams[label] = deflare(events, size, "model", weights=weights)
        frames, captions = [], []
        for start, width in windows:
            for label, ev in streams.items():
                t = ev["t"]
                part = ev[np.searchsorted(t, t0 + start) : np.searchsorted(t, t0 + start + width)]
                frames.append(event_frame(part, size)[crop])
                kept = f", {ev.size / events.size:.0%} kept" if label != "input" else ""
                captions.append(f"{label}{kept}, [{start / 1e3:g}, {(start + width) / 1e3:g}) ms")
        out = args.out / f"held_out_{held}.png"
        save_image(out, grid(frames, ncols=len(streams), captions=captions))
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
