"""Reconstructions of the real flare recordings before and after de-flaring (issue 17, part 4).

Run from the repository root, with ``../shared/data/real/`` present::

    python docs/figures/make_recon_real.py --data ../shared/data/real --out docs/figures

For each recording with a bright light (the Gen3 rotating light, the DAVIS346
lamps), the events are de-flared by each method in memory, and each stream is
reconstructed by the bundled reconstructor (``edeflare.recon``) over its
aligned 20 ms windows from the recording's start. The figure shows, per
recording (rows), the last complete window's events of the input and the
reconstruction of each stream at that window's end (columns), one figure
per recording (``recon_real_<recording>.png``). Qualitative, as in the
paper: real recordings have no flare-free image to score against.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from edeflare import read_events
from edeflare.deflare import create_method
from edeflare.events import window_start_for
from edeflare.recon.infer import reconstruct_events
from edeflare.viz import event_frame, grid, save_image

RECORDINGS = ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")
METHODS = {
    "night model": ("model", {"weights": "night"}),
    "default model": ("model", {}),
    "dv-fastdecay": ("dv-fastdecay", {}),
}


def _gray(image: np.ndarray) -> np.ndarray:
    g = np.clip(np.round(image * 255.0), 0, 255).astype(np.uint8)
    return np.repeat(g[:, :, None], 3, axis=2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/real"))
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    for name in RECORDINGS:
        events, size = read_events(args.data / name)
        start = window_start_for(int(events["t"][0]), 20_000)
        streams = {"input": events}
        for label, (method, params) in METHODS.items():
            try:
                streams[label] = create_method(method, **params)(events, size, rng=0)
            except Exception as exc:  # an optional method that is not installed
                print(f"skip {label}: {exc}")
        # the last window that the recording covers completely
        end = start + 20_000 * max(1, (int(events["t"][-1]) + 1 - start) // 20_000)
        last = (events["t"] >= end - 20_000) & (events["t"] < end)
        row = [event_frame(events[last], size)]
        for label, stream in streams.items():
            _, images = reconstruct_events(stream, size, start_us=start, end_us=end)
            row.append(_gray(images[-1]))
            print(f"{name} {label}: {stream.size} events, image mean {images[-1].mean():.3f}")
        columns = ["input events (last 20 ms)", *(f"reconstruction: {s}" for s in streams)]
        out = args.out / f"recon_real_{name.split('.')[0]}.png"
        save_image(out, grid(row, labels=columns, ncols=len(columns)))
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
