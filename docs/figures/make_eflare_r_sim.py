"""Figure: eflare-r-sim pairs (observation through the filter, ground truth through the clean
lens) as event frames, ON red, OFF blue.

Run from the repository root (see docs/figures/README.md for the exact command)::

    python docs/figures/make_eflare_r_sim.py --recipe eflare-r-sim --index 24 \
        --start-ms 40 --window-ms 20 -o docs/figures/eflare_r_sim_pair.png

Each ``--index`` is one sequence of the recipe (regenerated in memory, exactly as
``edeflare simulate OUT --recipe eflare-r-sim`` writes it) and one row of the figure.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from edeflare.data.generate import RECIPES, generate_sequence
from edeflare.events import slice_time
from edeflare.viz import event_frame, grid, save_image


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recipe", default="eflare-r-sim", help="an optics recipe")
    parser.add_argument("--index", type=int, nargs="+", default=[24], help="sequence(s)")
    parser.add_argument("--seed", type=int, help="dataset seed [the recipe's]")
    parser.add_argument("--start-ms", type=float, default=40.0, help="window start (ms)")
    parser.add_argument("--window-ms", type=float, default=20.0, help="window length (ms)")
    parser.add_argument(
        "-o", "--output", type=Path, default=Path("docs/figures/eflare_r_sim_pair.png")
    )
    args = parser.parse_args(argv)
    recipe = RECIPES[args.recipe]
    if args.seed is not None:
        recipe = dataclasses.replace(recipe, seed=args.seed)
    start = round(args.start_ms * 1000)
    end = start + round(args.window_ms * 1000)
    images, rows = [], []
    for index in args.index:
        data = generate_sequence(recipe, index)
        scene = data.script
        for name in ("input", "gt"):
            events = slice_time(data.streams[name], start, end)
            images.append(event_frame(events, data.sensor_size))
        kinds = ", ".join(s.kind for s in scene.sources)
        rows.append(f"#{index}: {scene.filter} filter; {kinds}")
        print(
            f"sequence {index}: {rows[-1]}; input {data.streams['input'].size:,} events, "
            f"gt {data.streams['gt'].size:,} (100 ms)"
        )
    width, height = recipe.sensor_size
    labels = [
        f"observation E_ob (filter), {args.window_ms:g} ms",
        "ground truth E_gt (clean lens)",
    ]
    captions = [r for r in rows for _ in range(2)]
    save_image(args.output, grid(images, labels=labels, captions=captions, ncols=2))
    print(
        f"wrote {args.output} ({recipe.name}, seed {recipe.seed}, {width}x{height}, "
        f"window [{start / 1000:g}, {end / 1000:g}) ms)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
