"""The default model on the real recordings, beside an older model and the dv filters.

    python docs/figures/make_night_real.py docs/figures/night_real.png [--model W]

One picture per recording, ``night_real_<recording>.png`` beside OUT: three 10 ms
windows of the Prophesee Gen3 rotating light, three 20 ms windows of the DAVIS346
lamps, the 8.8 ms Gen4.1 daytime street (no bright light: what a de-flarer should
leave alone), one row each. Columns: the input, the default model (or
``--model W``), the older ``eflare``, dv-processing's FastDecay and
BackgroundActivity filters (the ``dv`` extra). ON red, OFF blue.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from edeflare.io import read_events
from edeflare.methods import deflare
from edeflare.viz import event_frame, grid, save_image

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
RECORDINGS = (
    ("prophesee_gen3_rotating_light.raw", 10_000, 3),
    ("davis346_flicker_lamps.aedat4", 20_000, 3),
    ("prophesee_gen41_street.raw", 10_000, 1),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out", type=Path)
    parser.add_argument("--model", default=None, help="weights of the default column")
    args = parser.parse_args()
    columns = {
        "input": None,
        "default (night)": ("model", {"weights": args.model}),
        "eflare (older model)": ("model", {"weights": "eflare"}),
        "dv-fastdecay": ("dv-fastdecay", {}),
        "dv-bafilter": ("dv-bafilter", {}),
    }
    for name, window, count in RECORDINGS:
        rec = read_events(REAL / name)
        ev, size = rec.events, rec.sensor_size
        outs = {
            label: ev if spec is None else deflare(ev, size, spec[0], **spec[1])
            for label, spec in columns.items()
        }
        t0 = int(ev["t"][0])
        cells, rows = [], []
        for k in range(count):
            a, b = t0 + k * window, t0 + (k + 1) * window
            cells += [event_frame(e[(e["t"] >= a) & (e["t"] < b)], size) for e in outs.values()]
            rows.append(f"{k * window // 1000}-{(k + 1) * window // 1000} ms")
        path = args.out.with_name(f"{args.out.stem}_{Path(name).stem}.png")
        save_image(path, grid(cells, labels=list(columns), row_labels=rows, ncols=len(columns)))
        print("wrote", path)


if __name__ == "__main__":
    main()
