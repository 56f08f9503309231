"""Reconstructions of the real flare recordings before and after de-flaring (issue 17, part 4).

Run from the repository root, with ``../shared/data/real/`` present::

    python docs/figures/make_recon_real.py --data ../shared/data/real --out docs/figures

For each recording with a bright light (the Gen3 rotating light, the DAVIS346
lamps), :func:`edeflare.eval.downstream.reconstruct_recording` de-flares the
events by each method in memory and reconstructs every stream with the bundled
reconstructor over aligned 20 ms windows from the recording's start: the last
complete window's input events, then each stream's image at its end
(``recon_real_<recording>.png``). The HTML report shows the same figures with
``edeflare benchmark SPLIT --html DIR --real FILE ...``. Qualitative, as in the
paper: real recordings have no flare-free image to score against.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from edeflare.eval.downstream import reconstruct_recording
from edeflare.methods import create_method
from edeflare.viz import save_image

RECORDINGS = ("prophesee_gen3_rotating_light.raw", "davis346_flicker_lamps.aedat4")
METHODS = {"default model": ("model", {}), "dv-fastdecay": ("dv-fastdecay", {})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/real"))
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = parser.parse_args()
    methods = {}
    for label, (method, params) in METHODS.items():
        try:
            methods[label] = create_method(method, **params)
        except Exception as exc:  # an optional method that is not installed
            print(f"skip {label}: {exc}")
    for name in RECORDINGS:
        r = reconstruct_recording(args.data / name, methods)
        out = args.out / f"recon_real_{name.split('.')[0]}.png"
        save_image(out, r.image)
        print(f"wrote {out}: events per stream {r.events}")


if __name__ == "__main__":
    main()
