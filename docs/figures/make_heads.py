"""The bundled learned heads (`general`, `learned-absolute`, `learned`) beside `night` on
dense simulated flare and on the real recordings.

    python docs/figures/make_heads.py docs/figures/heads.png

Writes ``heads_forward.png`` (one 20 ms window of three ``eflare-forward`` sequences,
simulated into ``benchmarks/.data/eflare-forward`` first if absent: the input, its
ground truth, ``night``, ``general``, ``learned-absolute``, ``learned``) and
``heads_real.png`` (a 20 ms window of the DAVIS346 lamps, the Prophesee Gen3 light and a
dim Newton's cradle: the input and the four models) and ``heads_street.png`` (the whole
Gen4.1 daytime street, the same columns) beside OUT. ON red, OFF blue.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from edeflare.data.generate import generate_dataset
from edeflare.data.recipe import RECIPES
from edeflare.io import read_events
from edeflare.io.sequence import list_sequences, read_sequence
from edeflare.methods import deflare
from edeflare.viz import event_frame, grid, save_image

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT.parent / "shared" / "data" / "real"
FORWARD = ROOT / "benchmarks" / ".data" / "eflare-forward"
REAL_WINDOWS = (
    ("davis346_flicker_lamps.aedat4", 40_000),
    ("prophesee_gen3_rotating_light.raw", 20_000),
    ("davis346_lowlight_cradle.aedat4", 200_000),
)
STREET = "prophesee_gen41_street.raw"
"""1280x720, 8.8 ms: a figure of its own (one row, at its own scale)."""
MODELS = ("night", "general", "learned-absolute", "learned")
WINDOW_US = 20_000


def _window(ev, a):  # type: ignore[no-untyped-def]
    return ev[(ev["t"] >= a) & (ev["t"] < a + WINDOW_US)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("out", type=Path)
    args = parser.parse_args()
    if not (FORWARD / "manifest.json").is_file():
        generate_dataset(RECIPES["eflare-forward"], FORWARD, workers=2)
    cells, rows = [], []
    for path in list_sequences(FORWARD / "test")[:3]:
        inp, gt, size, start, _ = read_sequence(path)
        a = start + 2 * WINDOW_US
        outs = [inp, gt] + [deflare(inp, size, "model", weights=w) for w in MODELS]
        cells += [event_frame(_window(e, a), size) for e in outs]
        rows.append(path.stem)
    labels = ["input", "ground truth", "night (default)", *MODELS[1:]]
    path = args.out.with_name(f"{args.out.stem}_forward.png")
    save_image(path, grid(cells, labels=labels, row_labels=rows, ncols=len(labels)))
    print("wrote", path)
    labels = ["input", "night (default)", *MODELS[1:]]
    for suffix, windows in (("real", REAL_WINDOWS), ("street", ((STREET, 0),))):
        cells, rows = [], []
        for name, offset in windows:
            rec = read_events(REAL / name)
            ev, size = rec.events, rec.sensor_size
            a = int(ev["t"][0]) + offset
            outs = [ev] + [deflare(ev, size, "model", weights=w) for w in MODELS]
            cells += [event_frame(_window(e, a), size) for e in outs]
            rows.append(Path(name).stem)
        path = args.out.with_name(f"{args.out.stem}_{suffix}.png")
        save_image(path, grid(cells, labels=labels, row_labels=rows, ncols=len(labels)))
        print("wrote", path)


if __name__ == "__main__":
    main()
